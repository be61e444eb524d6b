#include "gshaptics/servo/admittance.h"

namespace gshaptics {

const char* control_mode_name(ControlMode mode) noexcept {
  return mode == ControlMode::kAdmittance ? "admittance" : "impedance";
}

const Setpoint& AdmittanceController::step(const Eigen::Vector3d& user_force,
                                           const Eigen::Vector3d& environment_force, double dt) noexcept {
  if (!(dt > 0)) return setpoint_;
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  if (user_force.allFinite()) f += user_force;
  if (environment_force.allFinite()) f += environment_force;
  Eigen::Vector3d& v = setpoint_.velocity;
  v += (dt / params_.mass) * (f - params_.damping * v);
  setpoint_.position += dt * v;
  return setpoint_;
}

}  // namespace gshaptics
