#pragma once
/// @file
/// The simulated device of the core pipeline, driven by a simulated user hand that follows a probe
/// trajectory, behind the HapticDevice interface, with either causality:
///  - impedance (the default): an ideal mass-damper (paper Sec. IV-V) moved by the hand and the
///    commanded force;
///  - admittance (the paper's HapticGiant class, Sec. IV; issue 73): a robot's handle of mass m
///    under a stiff position servo, F_servo = k_p (x_sp - x) + k_d (v_sp - v), tracking the
///    setpoint the runtime writes (HapticDevice::write_setpoint), with a force/torque sensor
///    between the hand and the handle: DeviceSample::user_force is the sensor's reading (the
///    hand's force on the handle). Commanded wrenches are not applied (position-controlled).
///    The same servo law and defaults as DeviceModel's admittance causality (device_model.h).

#include "gshaptics/device/haptic_device.h"
#include "gshaptics/device/device_model.h"
#include "gshaptics/device/hand_trajectory.h"

namespace gshaptics {

struct SimulatedDeviceParams {
  AdmittanceParams device;
  UserHandParams user;
  /// Integration step, s: read() integrates from the previous call to `now` in steps no longer
  /// than this, with the last commanded wrench held (zero-order hold, like a real amplifier).
  double max_step = 0.001;
  bool loop = true;  ///< restart the trajectory at its end (for runs longer than one pass)
  /// Margin around the trajectory's bounding box that forms the workspace, m.
  double workspace_margin = 0.5;
  /// kAdmittance: the robot under a position servo with a force sensor (see the file comment).
  Causality causality = Causality::kImpedance;
  /// Admittance causality: the handle's moving mass (kg) and the position servo's gains (N/m,
  /// N s/m); the defaults are DeviceModel's. The servo is integrated in substeps of at most
  /// `servo_substep` s.
  double robot_mass = DeviceModelParams{}.mass;
  double position_gain = DeviceModelParams{}.position_gain;
  double velocity_gain = DeviceModelParams{}.velocity_gain;
  double servo_substep = 1e-4;
  /// Admittance causality: the force sensor's range, N per axis (DeviceInfo::force_sensor_range);
  /// a reading is clipped to it, as a saturated sensor's is.
  double sensor_range = 200;
};

/// Simulated device + user. Time zero of the trajectory is the `now` given to start().
class SimulatedDevice final : public HapticDevice {
 public:
  SimulatedDevice(ProbeTrajectory trajectory, const SimulatedDeviceParams& params = {});
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos now) override;
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  /// Admittance causality: the position servo's new target (held until the next call).
  void write_setpoint(const Setpoint& setpoint, Nanos now) noexcept override;
  void stop(Nanos now) noexcept override;
  [[nodiscard]] const ProbeTrajectory& trajectory() const noexcept { return trajectory_; }
  /// Force last commanded (for tests): zero after stop().
  [[nodiscard]] const Wrench& last_wrench() const noexcept { return wrench_; }
  /// Admittance causality: the setpoint last written (the device's position until the first).
  [[nodiscard]] const Setpoint& last_setpoint() const noexcept { return setpoint_; }

 private:
  void integrate_to(Nanos now) noexcept;
  // One step of h s of the robot under its position servo and the hand (admittance causality).
  void servo_step(double h) noexcept;
  ProbeTrajectory trajectory_;
  SimulatedDeviceParams params_;
  DeviceInfo info_;
  AdmittanceDevice device_;
  Wrench wrench_;
  Setpoint setpoint_;
  Eigen::Vector3d user_force_ = Eigen::Vector3d::Zero();
  Nanos t0_ = 0, t_ = 0;
  std::uint64_t sequence_ = 0;
  double period_s_ = 0;  // trajectory duration + 0.5 s of rest
};

}  // namespace gshaptics
