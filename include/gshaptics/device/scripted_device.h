#pragma once
/// @file
/// An ideal position-controlled device that follows a script of poses exactly: the fidelity
/// benchmark and the seen-felt benchmark play their presses and slides on it through the servo
/// step (a shortcut: no device dynamics, no hand; results say so).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "gshaptics/device/haptic_device.h"

namespace gshaptics {

/// One pose of a script: world frame, SI units.
struct ScriptedPose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< tool centre, m
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< m/s
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< tool frame -> world
};

/// A HapticDevice that follows a script exactly (an ideal position-controlled 6-DoF device that
/// renders torque, with no limits of its own): a read at time `now` returns pose
/// round((now - start) * rate_hz), held at the last one; it finishes at the last pose. The
/// commanded wrench is ignored (recorded by the runtime's log, not applied).
class ScriptedDevice final : public HapticDevice {
 public:
  /// Throws InputError for an empty script or a rate that is not > 0.
  ScriptedDevice(std::vector<ScriptedPose> poses, double rate_hz);
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos now) override;
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  void stop(Nanos now) noexcept override;
  [[nodiscard]] bool finished() const noexcept override { return done_; }

 private:
  std::vector<ScriptedPose> poses_;
  DeviceInfo info_;
  Nanos t0_ = 0;
  double period_s_;
  std::uint64_t sequence_ = 0;
  bool done_ = false;
};

}  // namespace gshaptics
