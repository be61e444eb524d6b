#pragma once
/// @file
/// Counters of a real-time run: written by the servo thread every tick, readable live from any
/// thread (relaxed atomics), and summarised at the end.

#include <atomic>
#include <cstdint>

#include "gshaptics/servo/latency_histogram.h"

namespace gshaptics {

/// Live counters. Threading: the servo thread is the only writer; readers may lag by a tick.
struct RuntimeStats {
  std::atomic<std::uint64_t> ticks{0};
  std::atomic<std::uint64_t> deadline_misses{0};  ///< ticks that ended after the next deadline
  std::atomic<std::uint64_t> skipped_periods{0};  ///< periods dropped to catch up after a miss
  std::atomic<std::uint64_t> stale_ticks{0};      ///< held a result that was not new (kFlagHeld)
  std::atomic<std::uint64_t> fading_ticks{0};     ///< kFlagFading
  std::atomic<std::uint64_t> faded_ticks{0};      ///< kFlagFaded
  std::atomic<std::uint64_t> fades{0};            ///< times a fade began
  std::atomic<std::uint64_t> no_result_ticks{0};  ///< before the first collision result
  std::atomic<std::uint64_t> watchdog_ticks{0};
  std::atomic<std::uint64_t> invalid_pose_ticks{0};
  std::atomic<std::uint64_t> outside_workspace_ticks{0};
  std::atomic<std::uint64_t> force_limited_ticks{0};
  std::atomic<std::uint64_t> rate_limited_ticks{0};
  std::atomic<std::uint64_t> continuous_limited_ticks{0};  ///< kFlagContinuousLimited
  std::atomic<std::uint64_t> passivity_ticks{0};  ///< kFlagPassivity: the controller added damping
  std::atomic<double> passivity_peak_damping{0};  ///< its largest damping, N s/m
  std::atomic<double> passivity_min_energy{0};    ///< the observer's lowest energy, J
  std::atomic<std::uint64_t> results_used{0};     ///< distinct collision results rendered
  std::atomic<double> force_limit{0};             ///< peak limit in force, N (set at start)
  std::atomic<double> continuous_force_limit{0};  ///< the device's continuous force, N (+inf: none)
  std::atomic<bool> force_limit_by_device{false}; ///< the device's limit is below the configured F_max
  std::atomic<std::uint32_t> last_contacts{0};
  std::atomic<double> last_force{0};              ///< |F| sent on the last tick, N
  std::atomic<double> peak_force{0};              ///< largest |F| sent, N
  std::atomic<double> peak_torque{0};             ///< largest |tau| after the safety layer (sent if the device renders torque), N m
  std::atomic<std::uint64_t> torque_limited_ticks{0};  ///< kFlagTorqueLimited
  /// kFlagTorqueDropped: ticks with a torque the device cannot render (force-only devices)
  std::atomic<std::uint64_t> torque_dropped_ticks{0};
  std::atomic<double> torque_limit{0};            ///< torque limit in force, N m (set at start)
  std::atomic<double> passivity_damping_cap{0};   ///< the passivity controller's cap, N s/m (set at start)
  std::atomic<std::uint64_t> setpoint_limited_ticks{0};  ///< kFlagSetpointLimited
  std::atomic<std::uint64_t> braking_ticks{0};           ///< kFlagBraking
  std::atomic<std::uint64_t> sensor_saturated_ticks{0};  ///< kFlagSensorSaturated
  std::atomic<std::int64_t> start_ns{0}, last_tick_ns{0};
  LatencyHistogram jitter;      ///< wake-up time minus scheduled time, ns
  LatencyHistogram tick_time;   ///< work inside one tick (wake to device write), ns
  LatencyHistogram result_age;  ///< age of the result rendered (now - its pose stamp), ns
};

/// Plain-value summary of a run.
struct RuntimeSummary {
  double duration_s = 0;
  std::uint64_t ticks = 0;
  double rate_hz = 0;           ///< configured
  double achieved_rate_hz = 0;  ///< ticks / wall time between first and last tick
  double jitter_p50_us = 0, jitter_p99_us = 0, jitter_max_us = 0;
  double tick_p99_us = 0, tick_max_us = 0;
  double query_p50_us = 0, query_p99_us = 0, query_max_us = 0;  ///< worker step (query + force)
  std::uint64_t queries = 0;
  double result_age_p50_us = 0, result_age_p99_us = 0, result_age_max_us = 0;
  std::uint64_t deadline_misses = 0, skipped_periods = 0, stale_ticks = 0, fading_ticks = 0,
                faded_ticks = 0, fades = 0, no_result_ticks = 0, watchdog_ticks = 0,
                invalid_pose_ticks = 0, outside_workspace_ticks = 0, force_limited_ticks = 0,
                rate_limited_ticks = 0, continuous_limited_ticks = 0, results_used = 0,
                passivity_ticks = 0;
  double passivity_peak_damping = 0;  ///< N s/m
  double passivity_min_energy = 0;    ///< J (< 0: the environment was active before the controller caught it)
  double peak_force = 0;  ///< N
  double peak_torque = 0;  ///< largest |tau| after the safety layer, N m (sent if the device renders torque)
  std::uint64_t torque_limited_ticks = 0;  ///< torque clipped to its limit or rate
  std::uint64_t torque_dropped_ticks = 0;  ///< torque not sent: the device renders force only
  double torque_limit = 0;  ///< min(SafetyParams::tau_max, the device's max_torque), N m
  double passivity_damping_cap = 0;  ///< the passivity controller's damping cap, N s/m (passivity_damping_cap)
  /// Admittance control: ticks whose setpoint a robot limit held (speed, acceleration, workspace),
  /// ticks the virtual tool braked to rest, ticks the force sensor read its range (the run stops).
  std::uint64_t setpoint_limited_ticks = 0, braking_ticks = 0, sensor_saturated_ticks = 0;
  double force_limit = 0;  ///< peak limit applied: min(configured F_max, device's peak force), N
  double continuous_force_limit = 0;  ///< the device's continuous force, N (+inf: none)
  bool force_limit_by_device = false;  ///< the device's own limit bound (it is below F_max)
};

/// Builds the summary from the counters and the worker's latency histogram.
[[nodiscard]] RuntimeSummary summarize(const RuntimeStats& stats, const LatencyHistogram& query,
                                       double rate_hz);

}  // namespace gshaptics
