#pragma once
/// @file
/// HapticRuntime's twin on simulated time: the same ServoController (device read, safety layer,
/// wrench out), the same CollisionWorker and renderer and the same stop ramp, ticked on a
/// ManualClock instead of a real-time thread. Every simulated path (the probe run behind
/// `gshaptics simulate`, the fidelity matrix, `run --device replay:... --simulated-time`) goes
/// through it, so what they measure is what the hand gets from HapticRuntime in the same
/// execution mode.
///
/// Execution modes (RuntimeConfig::inline_query):
///   - inline: the query runs inside the tick; the force answers this tick's pose;
///   - decoupled: the paper's collision worker. On simulated time it is modelled exactly: the
///     result for the pose of tick k is rendered from tick k + latency_ticks on (the worker
///     thread of HapticRuntime answers within one to two ticks on a real clock).
///
/// Threading: single-threaded; run() returns when the run is over. Deterministic: the same
/// device, config and renderer give the same forces, tick by tick (render times are wall
/// time and are the only thing that varies).

#include <functional>
#include <memory>
#include <vector>

#include "gshaptics/device/clock.h"
#include "gshaptics/servo/collision_worker.h"
#include "gshaptics/device/haptic_device.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/servo/runtime_stats.h"
#include "gshaptics/servo/servo_controller.h"
#include "gshaptics/servo/tick_log.h"

namespace gshaptics {

/// Progress of a simulated run: fraction of the planned simulated time done, in [0, 1].
using SimulatedProgressFn = std::function<void(double)>;

class SimulatedRuntime {
 public:
  /// Renders with make_force_renderer(config.force_model, ...), like HapticRuntime.
  /// Throws InputError for a bad config (as HapticRuntime; latency_ticks < 1 included). A run
  /// with neither a duration nor a device that finishes ends after one simulated day.
  SimulatedRuntime(const CollisionWorld& world, HapticDevice& device, const RuntimeConfig& config);
  /// Renders with the caller's renderer (owned).
  SimulatedRuntime(HapticDevice& device, const RuntimeConfig& config, std::unique_ptr<ForceRenderer> renderer);
  SimulatedRuntime(const SimulatedRuntime&) = delete;
  SimulatedRuntime& operator=(const SimulatedRuntime&) = delete;

  /// Starts the device at simulated time 0 and ticks until config.duration, the device's end,
  /// or request_stop(); then the stop ramp and a final zero-force command, as HapticRuntime.
  /// Throws what the device's start() throws. Call once.
  void run(const SimulatedProgressFn& progress = {});
  /// Ends the run at the next tick (through the stop ramp). From the progress callback, say.
  void request_stop() noexcept { stop_requested_ = true; }

  [[nodiscard]] const TickLog& log() const noexcept { return log_; }
  [[nodiscard]] const RuntimeStats& stats() const noexcept { return stats_; }
  /// Summary as HapticRuntime's; query times are wall time, tick times and jitter are zero.
  [[nodiscard]] RuntimeSummary summary() const;
  [[nodiscard]] const CollisionWorker& worker() const noexcept { return *worker_; }
  [[nodiscard]] CollisionWorker& worker() noexcept { return *worker_; }
  [[nodiscard]] const RuntimeConfig& config() const noexcept { return config_; }

 private:

  HapticDevice& device_;
  RuntimeConfig config_;
  ManualClock clock_;
  Nanos period_ = 0;
  PoseChannel poses_;
  ResultChannel results_, staged_;
  RuntimeStats stats_;
  TickLog log_;
  std::unique_ptr<CollisionWorker> worker_;
  std::unique_ptr<ServoController> servo_;
  // Decoupled mode: results in flight, slot (k + latency) % (latency + 1) for tick k's pose;
  // pose_sequence 0 marks an empty slot.
  std::vector<CollisionResult> in_flight_;
  bool stop_requested_ = false, ran_ = false;
};

}  // namespace gshaptics
