#pragma once
/// @file
/// Admittance rendering (the paper's planned extension, Sec. VI; the HapticGiant's own control
/// scheme, Sec. IV): the device measures the user's force and is commanded a position. The servo
/// step keeps a virtual tool, a mass-damper
///   m a = F_user + F_env - b v,
/// integrated with semi-implicit Euler once per tick (stable for dt^2 K / m < 4 on a wall of
/// stiffness K), where F_env is the force model's force on the virtual tool (the proxy holds it
/// at the surface, the paper's penalty pushes it out). The device's position servo tracks the
/// virtual tool (HapticDevice::write_setpoint), so the wall's stiffness is limited by that servo
/// and the integration, not by the device's damping: an admittance-type device holds walls an
/// impedance device cannot (Ott, Mukherjee and Nakamura 2010, "Unified impedance and admittance
/// control", ICRA; Adams and Hannaford 1999 for the two causalities).
///
/// Threading: one servo thread; allocation-free and noexcept.

#include <Eigen/Core>
#include <cstdint>

#include "gshaptics/device/device_model.h"
#include "gshaptics/device/haptic_device.h"

namespace gshaptics {

/// How the runtime drives the device.
enum class ControlMode : std::uint8_t {
  kImpedance,   ///< read the pose, command force (every device; the paper's scheme on desktop devices)
  kAdmittance,  ///< read the user's force, command a position (DeviceInfo::admittance devices)
};

/// "impedance" or "admittance".
[[nodiscard]] const char* control_mode_name(ControlMode mode) noexcept;

/// The servo step's control scheme and, for admittance, the virtual tool.
struct ControlParams {
  ControlMode mode = ControlMode::kImpedance;
  /// The virtual tool: mass (kg, > 0) and damping (N s/m, >= 0). Defaults: 3 kg, 20 N s/m.
  AdmittanceParams admittance;
};

class AdmittanceController {
 public:
  explicit AdmittanceController(const AdmittanceParams& params = {}) noexcept : params_(params) {}
  /// Puts the virtual tool at rest at `position` (m): at start, and whenever the device gate
  /// failed (the tool follows the device again from where the device is).
  void reset(const Eigen::Vector3d& position) noexcept {
    setpoint_.position = position;
    setpoint_.velocity.setZero();
  }
  /// One tick of dt s under the user's force and the environment's force (N, world frame);
  /// returns the new setpoint. Non-finite forces are treated as zero.
  const Setpoint& step(const Eigen::Vector3d& user_force, const Eigen::Vector3d& environment_force,
                       double dt) noexcept;
  [[nodiscard]] const Setpoint& setpoint() const noexcept { return setpoint_; }
  [[nodiscard]] const AdmittanceParams& params() const noexcept { return params_; }

 private:
  AdmittanceParams params_;
  Setpoint setpoint_;
};

}  // namespace gshaptics
