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
/// Safety for a robot that moves on its own (issue 73, item 4): an admittance-type device goes
/// where the software says, so the setpoint is limited before it is written: its acceleration
/// (and braking) to `max_acceleration`, its speed to `max_speed`, its position to the device's
/// workspace box (toward a wall no faster than braking at the limit stops at it, sqrt(2 a d)). When the device's data go stale the
/// servo step brakes the virtual tool to rest at `max_acceleration`, forces ignored, and keeps
/// writing setpoints; a stop does the same, so every run ends with the robot at rest. The force
/// sensor is tared at start (the mean over `tare_time` while the virtual tool holds still) and read
/// through a dead band; a reading at the sensor's range (DeviceInfo::force_sensor_range) is a
/// saturated sensor and stops the run (ForceSensorFilter). The defaults suit a room-scale device
/// like the paper's HapticGiant (the bundled Truck's probe run needs 1.2 m/s and 4.3 m/s^2); an
/// arm guided by hand under ISO 10218-1's reduced speed wants 0.25 m/s (--robot-max-speed).
///
/// Threading: one servo thread; allocation-free and noexcept.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>

#include "gshaptics/device/clock.h"

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

/// The limits on an admittance-type device's setpoint and its force sensor. SI units.
struct RobotSafetyParams {
  double max_speed = 1.5;          ///< setpoint speed limit, m/s (> 0)
  double max_acceleration = 10.0;  ///< setpoint acceleration and braking limit, m/s^2 (> 0)
  double max_angular_speed = 3.0;         ///< setpoint angular speed limit, rad/s (> 0)
  double max_angular_acceleration = 30.0; ///< its acceleration and braking limit, rad/s^2 (> 0)
  double tare_time = 0.1;         ///< the sensor's tare at start, s (>= 0; the virtual tool holds still)
  /// Sensor readings (after the tare) at or below this magnitude are zero, N (>= 0): the noise of
  /// a handle sensor at rest (ATI Mini40-class: about 0.1 N) does not drift the virtual tool.
  double dead_band = 0.3;
  double torque_dead_band = 0.02;  ///< the same for the sensor's torque, N m (>= 0)
};

/// The servo step's control scheme and, for admittance, the virtual tool and the robot's limits.
struct ControlParams {
  ControlMode mode = ControlMode::kImpedance;
  /// The virtual tool: mass (kg, > 0) and damping (N s/m, >= 0). Defaults: 3 kg, 20 N s/m.
  AdmittanceParams admittance;
  RobotSafetyParams robot;
};

/// The force sensor of an admittance-type device, as the servo step reads it: tared at start,
/// through a dead band, saturation detected.
class ForceSensorFilter {
 public:
  explicit ForceSensorFilter(const RobotSafetyParams& params = {}) noexcept : params_(params) {}
  /// Re-arms the tare, which starts with the first reading apply() gets (a networked sensor may
  /// come after the run starts); `range`: the sensor's range, N (+inf: none known).
  void reset(Nanos now, double range) noexcept;
  /// The user's force from a raw reading at `now` (N): zero while taring (the reading is
  /// averaged), then the reading less the tare, zero within the dead band. A non-finite reading
  /// gives zero; one at or above 99 % of the range sets saturated(). The sensor's torque (N m) is
  /// tared and dead-banded alongside (torque_dead_band) into `torque`.
  [[nodiscard]] Eigen::Vector3d apply(const Eigen::Vector3d& raw, const Eigen::Vector3d& raw_torque, Nanos now,
                                      Eigen::Vector3d& torque) noexcept;
  [[nodiscard]] bool taring() const noexcept { return taring_; }
  [[nodiscard]] bool saturated() const noexcept { return saturated_; }
  [[nodiscard]] const Eigen::Vector3d& tare() const noexcept { return tare_; }

 private:
  RobotSafetyParams params_;
  double range_ = std::numeric_limits<double>::infinity();
  Nanos tare_end_ = -1;  // -1: the tare has not started
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero(), tare_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_sum_ = Eigen::Vector3d::Zero(), torque_tare_ = Eigen::Vector3d::Zero();
  long count_ = 0;
  bool taring_ = false, saturated_ = false;
};

class AdmittanceController {
 public:
  explicit AdmittanceController(const AdmittanceParams& params = {}, const RobotSafetyParams& limits = {}) noexcept
      : params_(params), limits_(limits) {}
  /// The box the setpoint stays in, world frame, m (the device's workspace; default: unbounded).
  void set_workspace(const Eigen::AlignedBox3d& box) noexcept { workspace_ = box; }
  /// Puts the virtual tool at rest at `position` (m) and `orientation`: at start, where the
  /// device is.
  void reset(const Eigen::Vector3d& position,
             const Eigen::Quaterniond& orientation = Eigen::Quaterniond::Identity()) noexcept {
    setpoint_.position = position;
    setpoint_.velocity.setZero();
    setpoint_.orientation = orientation.normalized();
    setpoint_.angular_velocity.setZero();
  }
  /// One tick of dt s under the user's force and the environment's force (N, world frame);
  /// returns the new setpoint, within the robot's limits (limited() says whether one acted).
  /// Non-finite forces are treated as zero.
  const Setpoint& step(const Eigen::Vector3d& user_force, const Eigen::Vector3d& environment_force,
                       double dt) noexcept;
  /// The same for a 6-DoF handle: the user's and the environment's torques (N m, world frame,
  /// about the TCP) turn the virtual tool, I dw/dt = tau_user + tau_env - b_r w, within the
  /// angular speed and acceleration limits (integrated as a rotation of |w| dt about w).
  const Setpoint& step(const Eigen::Vector3d& user_force, const Eigen::Vector3d& user_torque,
                       const Eigen::Vector3d& environment_force, const Eigen::Vector3d& environment_torque,
                       double dt) noexcept;
  /// One tick of braking: the velocity falls toward zero by at most max_acceleration * dt, forces
  /// ignored (a stale device, a stop). Returns the new setpoint.
  const Setpoint& brake(double dt) noexcept;
  [[nodiscard]] bool at_rest() const noexcept {
    return setpoint_.velocity.isZero(0) && setpoint_.angular_velocity.isZero(0);
  }
  /// A limit (acceleration, speed, workspace) changed the last step's setpoint.
  [[nodiscard]] bool limited() const noexcept { return limited_; }
  [[nodiscard]] const Setpoint& setpoint() const noexcept { return setpoint_; }
  [[nodiscard]] const AdmittanceParams& params() const noexcept { return params_; }

 private:
  // Acceleration, speed and workspace limits on a step from velocity `v0`.
  void limit(const Eigen::Vector3d& v0, double dt) noexcept;
  // The rotation's step: angular velocity within its limits, then the orientation turned.
  void turn(const Eigen::Vector3d& torque, double dt) noexcept;
  // The orientation turned by the angular velocity over dt.
  void rotate(double dt) noexcept;
  AdmittanceParams params_;
  RobotSafetyParams limits_;
  Eigen::AlignedBox3d workspace_{Eigen::Vector3d::Constant(-1e300), Eigen::Vector3d::Constant(1e300)};
  Setpoint setpoint_;
  bool limited_ = false;
};

}  // namespace gshaptics
