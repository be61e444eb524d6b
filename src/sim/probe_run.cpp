#include "gshaptics/sim/probe_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <string_view>
#include <variant>

#include "gshaptics/error.h"
#include "gshaptics/percentile.h"
#include "gshaptics/servo/simulated_runtime.h"
#include "gshaptics/device/simulated_device.h"

namespace gshaptics {

ProbeRunResult run_probe(const CollisionWorld& world, const ProbeTrajectory& trajectory,
                         const ProbeRunParams& params, const RunProgressFn& progress) {
  if (!(params.rate_hz > 0)) throw InputError("probe run: rate must be > 0 Hz");
  SimulatedDeviceParams dp;
  dp.device = params.device;
  dp.user = params.user;
  dp.loop = false;  // one pass, then rest
  dp.max_step = 1.0 / params.rate_hz;
  dp.causality = params.control.mode == ControlMode::kAdmittance ? Causality::kAdmittance : Causality::kImpedance;
  SimulatedDevice device(trajectory, dp);
  RuntimeConfig c;
  c.rate_hz = params.rate_hz;
  c.duration = trajectory.duration() + 0.5;
  c.inline_query = params.inline_query;
  c.latency_ticks = params.latency_ticks;
  if (params.tool.count > 0) {
    params.tool.validate("probe run: tool");
    c.tool = tool_shape_for(params.tool);
  } else {
    c.tool.semi_axes = Eigen::Vector3d::Constant(trajectory.tool_radius());
  }
  c.renderer = params.renderer;
  c.make_renderer = params.make_renderer;
  c.query = params.query;
  c.safety = params.safety;
  c.control = params.control;
  SimulatedRuntime rt(world, device, c);
  rt.run(progress);

  ProbeRunResult out;
  out.ticks = rt.log().records();
  out.episodes = find_episodes(out.ticks, 0.1, params.control.mode == ControlMode::kAdmittance);
  out.query_time = query_time_stats(out.ticks);
  return out;
}

std::vector<ContactEpisode> find_episodes(const std::vector<TickRecord>& ticks, double merge_gap_s, bool admittance) {
  std::vector<ContactEpisode> episodes;
  bool open = false;
  double last_contact_t = -1e300;
  for (std::size_t k = 0; k < ticks.size(); ++k) {
    const TickRecord& r = ticks[k];
    if (r.counts.contacts == 0) continue;
    if (!open || r.time - last_contact_t > merge_gap_s) {
      episodes.push_back({r.time, r.time, 0, 0, Eigen::Vector3d::Zero(), 0});
      open = true;
    }
    ContactEpisode& e = episodes.back();
    e.t_end = r.time;
    // The force of tick k moves the device from x_k to x_k+1; under admittance control it moves
    // the virtual tool, whose setpoint the tick writes after the step (x_k+1 is logged at k).
    if (admittance)
      e.energy_j -= r.force.dot(r.setpoint - (k > 0 ? ticks[k - 1].setpoint : r.setpoint));
    else if (k + 1 < ticks.size())
      e.energy_j -= r.force.dot(ticks[k + 1].position - r.position);
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

std::string active_episodes_note(const std::vector<ContactEpisode>& episodes) {
  int active = 0;
  double worst = 0;
  for (const ContactEpisode& e : episodes)
    if (e.energy_j < -kEnergyTolerance) ++active, worst = std::min(worst, e.energy_j);
  if (active == 0) return {};
  char note[96];
  std::snprintf(note, sizeof note, "; %d gave energy back, the worst W = %.2f mJ", active, worst * 1e3);
  return note;
}

namespace {

// What a missed site means on `renderer`'s solid, and that renderer's options that change it.
std::string_view missed_site_advice(const RendererSpec& renderer) {
  if (const auto* proxy = std::get_if<ProxyModelSpec>(&renderer)) {
    if (proxy->params.surface == ProxySurface::kSeen)
      return "met no seen surface (the Gaussians there composite to under half opacity along the approach: "
             "faint or open content; try a larger --seen-window or --surface ellipsoids)";
    return "met no Gaussian (sparse or low-opacity content there; try --isolation-gap 1, a lower --min-opacity "
           "or --surface seen)";
  }
  return "met no Gaussian (sparse or low-opacity content there; try a lower --min-opacity)";
}

}  // namespace

std::string site_note(const SiteAccount& a, double tool_radius, const RendererSpec& renderer) {
  char head[96];
  if (a.touched) {
    if (a.episodes <= 1) return {};
    std::snprintf(head, sizeof head, "%d bounces", a.episodes - 1);
    return head;
  }
  // The tool came within a tool radius of the planned touch point yet met nothing: nothing the
  // renderer holds is there; otherwise the run or the hand never got there.
  if (a.closest_approach <= tool_radius) {
    std::snprintf(head, sizeof head, "MISSED: the tool came within %.3g of the planned touch point and ", a.closest_approach);
    return std::string(head) + std::string(missed_site_advice(renderer));
  }
  std::snprintf(head, sizeof head, "MISSED: the tool never came closer than %.3g to the planned touch point",
                a.closest_approach);
  return head;
}

std::vector<SiteAccount> account_sites(const ProbeTrajectory& trajectory, const std::vector<TickRecord>& ticks,
                                       const std::vector<ContactEpisode>& episodes) {
  const std::vector<ProbeSite>& sites = trajectory.sites();
  std::vector<SiteAccount> out(sites.size());
  const double t_end = ticks.empty() ? trajectory.duration() : std::max(ticks.back().time, trajectory.duration());
  for (std::size_t i = 0; i < sites.size(); ++i) {
    SiteAccount& a = out[i];
    a.site = int(i);
    a.t_planned = sites[i].t_touch;
    a.t_window_start = i == 0 ? -std::numeric_limits<double>::infinity() : 0.5 * (sites[i - 1].t_touch + sites[i].t_touch);
    a.t_window_end = i + 1 == sites.size() ? std::numeric_limits<double>::infinity()
                                           : 0.5 * (sites[i].t_touch + sites[i + 1].t_touch);
    a.closest_approach = std::numeric_limits<double>::infinity();
    for (const TickRecord& r : ticks) {
      if (r.time < a.t_window_start || r.time >= a.t_window_end) continue;
      a.closest_approach = std::min(a.closest_approach, (r.position - sites[i].touch_point).norm());
      a.peak_force = std::max(a.peak_force, r.force.norm());
      if (r.counts.contacts > 0 && !a.touched) {
        a.touched = true;
        a.t_first_contact = r.time;
      }
    }
    for (const ContactEpisode& e : episodes) a.episodes += e.t_start >= a.t_window_start && e.t_start < a.t_window_end;
    a.t_window_start = std::max(a.t_window_start, 0.0);
    a.t_window_end = std::min(a.t_window_end, t_end);
  }
  return out;
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
