#include "gshaptics/sim/probe_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "gshaptics/error.h"
#include "gshaptics/percentile.h"

namespace gshaptics {

ProbeRunResult run_probe(const CollisionWorld& world, const ProbeTrajectory& trajectory,
                         const ProbeRunParams& params, const RunProgressFn& progress) {
  if (!(params.rate_hz > 0)) throw InputError("probe run: rate must be > 0 Hz");
  const double dt = 1.0 / params.rate_hz;
  const double duration = trajectory.duration() + 0.5;
  const auto n_ticks = std::size_t(std::ceil(duration / dt));

  ProbeRunResult out;
  out.ticks.resize(n_ticks);  // all memory up front: the loop below does not allocate
  const std::unique_ptr<ForceRenderer> renderer =
      make_force_renderer(params.force_model, world, params.force, params.query, params.proxy);
  DeviceState start;
  Eigen::Vector3d target_v;
  trajectory.sample(0.0, start.position, target_v);
  AdmittanceDevice device(params.device, start);
  Eigen::Vector3d rendered = Eigen::Vector3d::Zero();
  const std::size_t report_every = std::max<std::size_t>(1, n_ticks / 100);

  for (std::size_t k = 0; k < n_ticks; ++k) {
    const double t = double(k) * dt;
    const DeviceState& s = device.state();
    // Servo tick: pose in -> collision queries + force model -> wrench out (paper Sec. IV).
    const auto q0 = std::chrono::steady_clock::now();
    const RenderOutput f = renderer->render(ToolEllipsoid::sphere(s.position, trajectory.tool_radius()), s.velocity, dt);
    const auto q1 = std::chrono::steady_clock::now();
    rendered = f.force;

    Eigen::Vector3d target_p;
    trajectory.sample(t, target_p, target_v);
    const Eigen::Vector3d user = user_hand_force(params.user, s, target_p, target_v);

    TickRecord& rec = out.ticks[k];
    rec.time = t;
    rec.position = s.position;
    rec.velocity = s.velocity;
    rec.counts = f.counts;
    rec.proxy = f.proxy;
    rec.constraints = f.constraints;
    rec.desired = rendered;
    rec.force = rendered;
    rec.user_force = user;
    rec.query_us = float(std::chrono::duration<double, std::micro>(q1 - q0).count());

    device.step(user + rendered, dt);
    if (progress && k % report_every == 0) progress(double(k) / double(n_ticks));
  }
  if (progress) progress(1.0);
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
