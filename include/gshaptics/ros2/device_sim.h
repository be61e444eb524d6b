#pragma once
/// @file
/// The device side of the paper's two-machine split (Sec. IV) as a library call: a haptic
/// device (the simulated admittance device and hand, or any HapticDevice) publishes its pose over
/// ROS 2 and applies the wrench a `gshaptics node --ros2` sends back, at a fixed rate, while the
/// pose -> wrench round trip is measured. `gshaptics device-sim --ros2` is a thin CLI over it.

#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

#include "gshaptics/ros2/ros2_bridge.h"
#include "gshaptics/device/haptic_device.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/servo/tick_log.h"

namespace gshaptics {

/// How the device side runs.
struct DeviceLoopParams {
  double rate_hz = kDefaultServoRateHz;    ///< device rate, Hz (> 0)
  double duration_s = 1.0;  ///< run length, s (> 0)
};

/// What the device side saw.
struct DeviceLoopResult {
  /// One record per device tick: time (s since start), position, velocity, force applied (the
  /// newest wrench received), user force, latency_us (round trip of a new wrench; -1 otherwise).
  /// Written with kDeviceLogColumns.
  std::vector<TickRecord> ticks;
  std::uint64_t poses_sent = 0;
  std::uint64_t wrenches_received = 0;
  std::uint64_t setpoints_received = 0;  ///< admittance-type device: setpoints taken from the node
  Setpoint last_setpoint;                ///< the newest of them (a node that stopped leaves it at rest)
  std::vector<double> latencies_us;  ///< every measured pose -> wrench round trip, microseconds
  double peak_force = 0;             ///< N
  bool interrupted = false;          ///< `stop` became non-zero before the end
};

/// Progress callback: seconds run so far, poses sent, wrenches received, |F| now. May be empty.
using DeviceLoopProgressFn = std::function<void(double, std::uint64_t, std::uint64_t, double)>;

/// Runs `device` for `params.duration_s` on absolute deadlines of the monotonic clock: each tick
/// reads the device, publishes its pose (stamped now), takes the newest wrench (its header stamp
/// echoes the pose it answers, giving the round trip) and writes it to the device. An
/// admittance-type device (DeviceInfo::admittance; the link made with RosBridgeOptions::admittance)
/// also publishes its force sensor's reading and takes the node's newest setpoint. Stops early
/// when `stop` (may be null) becomes non-zero; the device is stopped at the end. Call
/// `link.wait_for_node()` first. Throws InputError for bad params and what the device throws.
[[nodiscard]] DeviceLoopResult run_device_loop(HapticDevice& device, Ros2DeviceLink& link,
                                               const DeviceLoopParams& params,
                                               const std::atomic<int>* stop = nullptr,
                                               const DeviceLoopProgressFn& progress = {});

}  // namespace gshaptics
