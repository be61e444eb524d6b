#include "gshaptics/device/admittance_device.h"

namespace gshaptics {

void AdmittanceDevice::step(const Eigen::Vector3d& external_force, double dt) noexcept {
  const Eigen::Vector3d accel = (external_force - params_.damping * state_.velocity) / params_.mass;
  state_.velocity += dt * accel;
  state_.position += dt * state_.velocity;
}

Eigen::Vector3d user_hand_force(const UserHandParams& params, const DeviceState& device,
                                const Eigen::Vector3d& target_position,
                                const Eigen::Vector3d& target_velocity) noexcept {
  Eigen::Vector3d f = params.stiffness * (target_position - device.position) +
                      params.damping * (target_velocity - device.velocity);
  const double n = f.norm();
  if (n > params.max_force) f *= params.max_force / n;
  return f;
}

}  // namespace gshaptics
