#pragma once
/// @file
/// The simulated admittance device of the core pipeline (paper Sec. IV-V: a HapticGiant-like
/// virtual mass-damper) driven by a simulated user hand that follows a probe trajectory, running
/// in real time behind the HapticDevice interface.

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
};

/// Simulated device + user. Time zero of the trajectory is the `now` given to start().
class SimulatedDevice final : public HapticDevice {
 public:
  SimulatedDevice(ProbeTrajectory trajectory, const SimulatedDeviceParams& params = {});
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos now) override;
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  void stop(Nanos now) noexcept override;
  [[nodiscard]] const ProbeTrajectory& trajectory() const noexcept { return trajectory_; }
  /// Force last commanded (for tests): zero after stop().
  [[nodiscard]] const Wrench& last_wrench() const noexcept { return wrench_; }

 private:
  void integrate_to(Nanos now) noexcept;
  ProbeTrajectory trajectory_;
  SimulatedDeviceParams params_;
  DeviceInfo info_;
  AdmittanceDevice device_;
  Wrench wrench_;
  Eigen::Vector3d user_force_ = Eigen::Vector3d::Zero();
  Nanos t0_ = 0, t_ = 0;
  std::uint64_t sequence_ = 0;
  double period_s_ = 0;  // trajectory duration + 0.5 s of rest
};

}  // namespace gshaptics
