#include "gshaptics/sim/probe_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "gshaptics/error.h"
#include "gshaptics/percentile.h"
#include "gshaptics/servo/simulated_runtime.h"
#include "gshaptics/sim/simulated_device.h"

namespace gshaptics {

ProbeRunResult run_probe(const CollisionWorld& world, const ProbeTrajectory& trajectory,
                         const ProbeRunParams& params, const RunProgressFn& progress) {
  if (!(params.rate_hz > 0)) throw InputError("probe run: rate must be > 0 Hz");
  SimulatedDeviceParams dp;
  dp.device = params.device;
  dp.user = params.user;
  dp.loop = false;  // one pass, then rest
  dp.max_step = 1.0 / params.rate_hz;
  SimulatedDevice device(trajectory, dp);
  RuntimeConfig c;
  c.rate_hz = params.rate_hz;
  c.duration = trajectory.duration() + 0.5;
  c.inline_query = params.inline_query;
  c.latency_ticks = params.latency_ticks;
  c.tool.semi_axes = Eigen::Vector3d::Constant(trajectory.tool_radius());
  c.renderer = params.renderer;
  c.query = params.query;
  c.safety = params.safety;
  SimulatedRuntime rt(world, device, c);
  rt.run(progress);

  ProbeRunResult out;
  out.ticks = rt.log().records();
  out.episodes = find_episodes(out.ticks);
  out.query_time = query_time_stats(out.ticks);
  return out;
}

std::vector<ContactEpisode> find_episodes(const std::vector<TickRecord>& ticks, double merge_gap_s) {
  std::vector<ContactEpisode> episodes;
  bool open = false;
  double last_contact_t = -1e300;
  for (const auto& r : ticks) {
    if (r.counts.contacts == 0) continue;
    if (!open || r.time - last_contact_t > merge_gap_s) {
      episodes.push_back({r.time, r.time, 0, 0, Eigen::Vector3d::Zero()});
      open = true;
    }
    ContactEpisode& e = episodes.back();
    e.t_end = r.time;
    e.peak_contacts = std::max(e.peak_contacts, r.counts.contacts);
    const double fm = r.force.norm();
    if (fm > e.peak_force) {
      e.peak_force = fm;
      e.peak_direction = r.force / fm;
    }
    last_contact_t = r.time;
  }
  return episodes;
}

QueryTimeStats query_time_stats(const std::vector<TickRecord>& ticks) {
  QueryTimeStats s;
  if (ticks.empty()) return s;
  std::vector<double> us;
  us.reserve(ticks.size());
  for (const auto& r : ticks) {
    us.push_back(r.query_us);
    s.over_1ms += r.query_us > 1000.0 ? 1 : 0;
  }
  s.p50_us = percentile(us, 50);
  s.p99_us = percentile(us, 99);
  s.max_us = *std::max_element(us.begin(), us.end());
  return s;
}

}  // namespace gshaptics
