#include "gshaptics/servo/runtime_stats.h"

namespace gshaptics {

RuntimeSummary summarize(const RuntimeStats& s, const LatencyHistogram& query, double rate_hz) {
  RuntimeSummary r;
  const auto ld = [](const std::atomic<std::uint64_t>& a) { return a.load(std::memory_order_relaxed); };
  r.ticks = ld(s.ticks);
  r.rate_hz = rate_hz;
  const double wall = double(s.last_tick_ns.load() - s.start_ns.load()) * 1e-9;
  r.duration_s = wall;
  // Ticks between the first and the last tick's scheduled instants: (ticks - 1) periods.
  r.achieved_rate_hz = wall > 0 && r.ticks > 1 ? double(r.ticks - 1) / wall : 0;
  r.jitter_p50_us = s.jitter.percentile(50) * 1e-3;
  r.jitter_p99_us = s.jitter.percentile(99) * 1e-3;
  r.jitter_max_us = double(s.jitter.max()) * 1e-3;
  r.tick_p99_us = s.tick_time.percentile(99) * 1e-3;
  r.tick_max_us = double(s.tick_time.max()) * 1e-3;
  r.queries = query.count();
  r.query_p50_us = query.percentile(50) * 1e-3;
  r.query_p99_us = query.percentile(99) * 1e-3;
  r.query_max_us = double(query.max()) * 1e-3;
  r.result_age_p50_us = s.result_age.percentile(50) * 1e-3;
  r.result_age_p99_us = s.result_age.percentile(99) * 1e-3;
  r.result_age_max_us = double(s.result_age.max()) * 1e-3;
  r.deadline_misses = ld(s.deadline_misses);
  r.skipped_periods = ld(s.skipped_periods);
  r.stale_ticks = ld(s.stale_ticks);
  r.fading_ticks = ld(s.fading_ticks);
  r.faded_ticks = ld(s.faded_ticks);
  r.fades = ld(s.fades);
  r.no_result_ticks = ld(s.no_result_ticks);
  r.watchdog_ticks = ld(s.watchdog_ticks);
  r.invalid_pose_ticks = ld(s.invalid_pose_ticks);
  r.outside_workspace_ticks = ld(s.outside_workspace_ticks);
  r.force_limited_ticks = ld(s.force_limited_ticks);
  r.rate_limited_ticks = ld(s.rate_limited_ticks);
  r.continuous_limited_ticks = ld(s.continuous_limited_ticks);
  r.passivity_ticks = ld(s.passivity_ticks);
  r.passivity_peak_damping = s.passivity_peak_damping.load(std::memory_order_relaxed);
  r.passivity_min_energy = s.passivity_min_energy.load(std::memory_order_relaxed);
  r.results_used = ld(s.results_used);
  r.force_limit = s.force_limit.load(std::memory_order_relaxed);
  r.continuous_force_limit = s.continuous_force_limit.load(std::memory_order_relaxed);
  r.force_limit_by_device = s.force_limit_by_device.load(std::memory_order_relaxed);
  r.peak_force = s.peak_force.load(std::memory_order_relaxed);
  r.peak_torque = s.peak_torque.load(std::memory_order_relaxed);
  r.torque_limited_ticks = ld(s.torque_limited_ticks);
  r.torque_dropped_ticks = ld(s.torque_dropped_ticks);
  r.torque_limit = s.torque_limit.load(std::memory_order_relaxed);
  r.passivity_damping_cap = s.passivity_damping_cap.load(std::memory_order_relaxed);
  r.setpoint_limited_ticks = ld(s.setpoint_limited_ticks);
  r.braking_ticks = ld(s.braking_ticks);
  r.sensor_saturated_ticks = ld(s.sensor_saturated_ticks);
  return r;
}

}  // namespace gshaptics
