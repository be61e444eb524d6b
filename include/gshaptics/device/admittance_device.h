#pragma once
/// @file
/// A simulated admittance-type haptic device (like the paper's HapticGiant, Sec. IV-V) and a
/// simulated user hand that drives it.

#include <Eigen/Core>

namespace gshaptics {

/// Virtual mass-damper the admittance controller renders: m a = F_user + F_render - b v.
struct AdmittanceParams {
  double mass = 3.0;     ///< virtual mass, kg
  double damping = 20.0; ///< virtual damping, N s/m
};

/// Translational state of the device's tool centre point (world frame).
struct DeviceState {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< m
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< m/s
};

/// Admittance device integrated with semi-implicit Euler (stable for the default parameters at
/// servo periods up to several ms).
class AdmittanceDevice {
 public:
  explicit AdmittanceDevice(const AdmittanceParams& params = {}, const DeviceState& initial = {})
      : params_(params), state_(initial) {}
  /// Advances by dt seconds under the sum of external forces (N, world frame).
  void step(const Eigen::Vector3d& external_force, double dt) noexcept;
  [[nodiscard]] const DeviceState& state() const noexcept { return state_; }
  void set_state(const DeviceState& s) noexcept { state_ = s; }

 private:
  AdmittanceParams params_;
  DeviceState state_;
};

/// The user's hand as a spring-damper pulling the device toward a target pose, with a force
/// limit (a person pushes with tens of newtons, not more).
struct UserHandParams {
  double stiffness = 600.0;  ///< N/m
  double damping = 40.0;     ///< N s/m
  double max_force = 60.0;   ///< N
};

/// Force the hand applies to the device (N, world frame).
[[nodiscard]] Eigen::Vector3d user_hand_force(const UserHandParams& params,
                                              const DeviceState& device,
                                              const Eigen::Vector3d& target_position,
                                              const Eigen::Vector3d& target_velocity) noexcept;

}  // namespace gshaptics
