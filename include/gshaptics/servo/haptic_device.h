#pragma once
/// @file
/// The device layer: one interface for every haptic device the runtime drives (pose, velocity and
/// buttons in; wrench out), whatever it is: a simulated admittance device, a replayed log, a
/// mouse in a browser or a robot across a network.
///
/// Threading contract: the servo thread owns the device between HapticRuntime start and stop;
/// read() and write() are called from that thread only, once per tick each, and must not block,
/// allocate, lock, log or throw. info() is const and may be called from any thread.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>

#include "gshaptics/servo/clock.h"

namespace gshaptics {

/// What the device reports at one tick. World frame (the frame the scene is registered into),
/// metres, seconds.
struct DeviceSample {
  /// Increments every time the device delivers new data. The runtime's watchdog trips when it
  /// stops changing (a stalled driver, a dead network link). 0: no data yet (the runtime
  /// neither uses the pose nor renders a force).
  std::uint64_t sequence = 0;
  Nanos stamp = 0;  ///< when the data was measured, ns on the runtime's clock
  Eigen::Vector3d position = Eigen::Vector3d::Zero();                  ///< tool centre point, m
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();     ///< tool frame -> world
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();                  ///< m/s
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();          ///< rad/s, world frame
  /// Force the user applies, N, world frame, when the device measures or simulates it (zero
  /// otherwise). Logged only; the force model does not use it.
  Eigen::Vector3d user_force = Eigen::Vector3d::Zero();
  std::uint32_t buttons = 0;  ///< bit i set: button i pressed
};

/// The wrench the runtime commands, world frame, at the tool centre point.
struct Wrench {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   ///< N
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();  ///< N m (zero: the paper renders force only)
};

/// Static facts about a device.
struct DeviceInfo {
  std::string name;
  double max_rate_hz = 10000;  ///< highest servo rate the device accepts
  /// Where the tool centre may be, world frame, m. Outside it the runtime commands zero force.
  Eigen::AlignedBox3d workspace{Eigen::Vector3d::Constant(-1e300), Eigen::Vector3d::Constant(1e300)};
};

/// A haptic device as the runtime sees it.
class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  [[nodiscard]] virtual const DeviceInfo& info() const noexcept = 0;
  /// Called once on the servo thread before the first tick (time `now`). May throw InputError
  /// (a device that cannot start); the runtime then does not start.
  virtual void start(Nanos now) = 0;
  /// The newest data at time `now`. A device with nothing new returns its previous sample
  /// (same sequence). Never blocks.
  [[nodiscard]] virtual DeviceSample read(Nanos now) noexcept = 0;
  /// Commands a wrench, applied until the next write.
  virtual void write(const Wrench& wrench, Nanos now) noexcept = 0;
  /// Called once on the servo thread after the last tick, after a zero wrench was written.
  virtual void stop(Nanos now) noexcept = 0;
  /// True when the device has nothing more to give (a replay at its end); the runtime then stops.
  [[nodiscard]] virtual bool finished() const noexcept { return false; }
};

}  // namespace gshaptics
