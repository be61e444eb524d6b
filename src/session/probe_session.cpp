#include "gshaptics/session/probe_session.h"
#ifdef GSHAPTICS_HAVE_OBJECTS
#include "gshaptics/session/object_session.h"
#endif
#include "gshaptics/session/report_session.h"

#include <chrono>
#include <filesystem>
#include <optional>

#include "gshaptics/collision/world_cache.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/error.h"
#include "gshaptics/servo/safety.h"
#include "gshaptics/servo/passivity.h"
#include "gshaptics/servo/tick_log.h"
#include "gshaptics/sim/probe_run.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/scene/scene_stats.h"
#include "gshaptics/device/device_profile.h"
#include "gshaptics/device/device_model.h"
#include "gshaptics/sim/pose_sampler.h"
#include "gshaptics/force/seen_solid.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/collision/ellipsoid_line.h"
#include <numbers>

namespace gshaptics::session {

std::string describe_execution(const ExecutionOptions& o, bool simulated) {
  if (o.inline_query) return "inline";
  return simulated ? fmt::format("decoupled, {} tick{} latency", o.latency_ticks, o.latency_ticks == 1 ? "" : "s")
                   : std::string("decoupled (worker thread)");
}

RendererSpec ForceModelOptions::spec() const {
  RendererSpec s = renderer_spec(model, proxy, force);
  if (auto* p = std::get_if<ProxyModelSpec>(&s)) p->materials = materials;
  return s;
}

ToolOption parse_tool_option(const std::string& spec) {
  ToolOption t;
  t.tool = parse_tool_spec(spec);
  t.spec = spec;
  return t;
}

void refuse_options_not_applying(RendererKind model, std::optional<ProxyTool> tool, ProxySurface surface,
                                 std::span<const GivenOption> given) {
  std::string refused;
  const auto refuse = [&](std::string_view option, const std::string& why) {
    refused += fmt::format("{}{} {}", refused.empty() ? "" : "; ", option, why);
  };
  for (const GivenOption& g : given) {
    if (g.model && *g.model != model) {
      refuse(g.name, fmt::format("applies to the {} model only (--force-model is {})", renderer_name(*g.model),
                                 renderer_name(model)));
      continue;
    }
    if (model != RendererKind::kProxy) continue;
    for (const ProxySurfaceField& f : surface_specific_proxy_fields())
      if (f.option == g.name && f.serves != surface)
        refuse(g.name, fmt::format("serves --surface {} only (--surface is {}): {}", proxy_surface_name(f.serves),
                                   proxy_surface_name(surface), f.why_not));
    if (!tool) continue;
    for (const ProxyToolField& f : tool_specific_proxy_fields())
      if (f.option == g.name && f.serves != *tool)
        refuse(g.name, fmt::format("serves {} only: {}",
                                   f.serves == ProxyTool::kCompound ? "a tool with a shape (--tool stylus:..., disc:...)"
                                                                    : "a one-part tool",
                                   f.why_not));
  }
  if (!refused.empty()) throw InputError("options that do not apply: " + refused);
}

void warn_if_outside_profile(const PreparedWorld& w, const ForceModelOptions& o) {
  if (o.profile.empty()) return;
  const DeviceProfile& p = device_profile(o.profile, "--device-profile");
  const double size = robust_extent(w.world);
  if (fits_workspace(p, size)) return;
  fmt::print(stderr,
             "warning: the world is {:.3g} m across, larger than a {} device's {:.0f} mm workspace; "
             "scale it with --reg-scale {:.3g} (x the current scale) to fit it in 0.12 m\n",
             size, p.name, 1000 * p.workspace.maxCoeff(), desktop_scale_advice(size).reg_scale);
}

std::function<double(const Eigen::Vector3d&, const Eigen::Vector3d&, double)> seen_first_touch(
    const CollisionWorld& world, double tool_radius) {
  // The sphere's leading point meets the seen solid, seen from where the approach starts (it
  // came there through free space); a private solid, built once for the few sites.
  auto solid = std::make_shared<const SeenSolid>(world);
  return [solid, tool_radius](const Eigen::Vector3d& start, const Eigen::Vector3d& dir, double reach) {
    SeenScratch scratch;
    const SeenHit hit = solid->first_inside(start, dir, 0, tool_radius, reach + tool_radius, scratch);
    return hit.hit && !scratch.overflow ? hit.t - tool_radius : std::numeric_limits<double>::quiet_NaN();
  };
}

namespace {

using TouchFn = std::function<double(const Eigen::Vector3d&, const Eigen::Vector3d&, double)>;

// The tool's parts posed at `tcp`, held at the world's orientation (simulate --tool).
int posed_upright(const CompoundTool& tool, const Eigen::Vector3d& tcp, std::array<ToolEllipsoid, kMaxToolParts>& parts) {
  return tool.posed(tcp, Eigen::Quaterniond::Identity(), std::span<ToolEllipsoid>(parts.data(), parts.size()));
}

// tool_first_touch on the seen solid: each part's front over its centre line and the seen
// proxies' footprint rays on every ring (seen_footprint::ray_offset), pushed as
// SeenCompoundProxy pushes a part (seen from as far behind as the line is still seen from, up to
// `window`).
TouchFn seen_tool_touch(const CollisionWorld& world, const CompoundTool& tool, double window) {
  auto solid = std::make_shared<const SeenSolid>(world);
  return [solid, tool, window](const Eigen::Vector3d& start, const Eigen::Vector3d& dir, double reach) {
    std::array<ToolEllipsoid, kMaxToolParts> parts;
    const int count = posed_upright(tool, start, parts);
    SeenScratch scratch;
    double met = std::numeric_limits<double>::infinity();
    for (int j = 0; j < count; ++j) {
      const ToolEllipsoid& part = parts[std::size_t(j)];
      const ToolShadow shadow = shadow_along(part, dir);
      for (int k = -1; k < 3 * seen_footprint::kRays; ++k) {  // (-1: the centre line)
        const Eigen::Vector3d across =
            k < 0 ? Eigen::Vector3d::Zero()
                  : seen_footprint::ray_offset(shadow, k % seen_footprint::kRays, k / seen_footprint::kRays);
        const Eigen::Vector3d p = part.center + across;
        const double front = exit_along(part, p, dir);
        if (std::isnan(front)) continue;
        double eye = 0;
        const SeenHit hit = solid->push(p, dir, front, window, reach, false, eye, scratch);
        if (hit.hit && !scratch.overflow) met = std::min(met, hit.t);
      }
    }
    return std::isfinite(met) ? met : std::numeric_limits<double>::quiet_NaN();
  };
}

// tool_first_touch on the ellipsoids: the first overlap of any part, stepped at an eighth of the
// tool's smallest semi-axis.
TouchFn ellipsoid_tool_touch(const CollisionWorld& world, const CompoundTool& tool) {
  double smallest = std::numeric_limits<double>::infinity();
  for (const ToolPart& part : tool.view()) smallest = std::min(smallest, part.semi_axes.minCoeff());
  auto query = std::make_shared<ContactQuery>(world);
  return [query, tool, step = smallest / 8](const Eigen::Vector3d& start, const Eigen::Vector3d& dir, double reach) {
    constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
    if (!(reach >= 0) || !std::isfinite(reach)) return kNone;
    std::array<ToolEllipsoid, kMaxToolParts> parts;
    for (double s = 0;; s = std::min(reach, s + step)) {
      const int count = posed_upright(tool, start + s * dir, parts);
      for (int j = 0; j < count; ++j)
        if (query->any_contact(parts[std::size_t(j)])) return s;
      if (s >= reach) return kNone;
    }
  };
}

}  // namespace

std::function<double(const Eigen::Vector3d&, const Eigen::Vector3d&, double)> tool_first_touch(
    const CollisionWorld& world, const CompoundTool& tool, bool seen, double seen_window) {
  tool.validate("probe: tool");
  return seen ? seen_tool_touch(world, tool, seen_window * tool.largest_semi_axis()) : ellipsoid_tool_touch(world, tool);
}

ProbeTrajectory make_probe_trajectory(const CollisionWorld& world, bool scaled, int sites, std::uint64_t seed,
                                      double tool_radius, const ForceModelOptions& force, std::FILE* report,
                                      const std::optional<Eigen::Vector3d>& up, const CompoundTool* tool) {
  // The world's up from the actual transform: the file's convention carried through --up and the
  // registration (a --reg-scale alone rotates nothing, so it changes nothing here).
  const double extent = robust_extent(world);
  // Press to half the force limit through the proxy's coupling in series with the simulated hand.
  // At most kMaxPressRadii tool radii deep: a deeper target drives the proxy into the holes of
  // sparse scenes (fruitdrops' 1-sigma ellipsoids leave gaps) and is no longer a press.
  constexpr double kMaxPressRadii = 3.0;
  const double radius = tool_radius > 0 ? tool_radius : default_tool_radius(world);
  const double hand_k = UserHandParams{}.stiffness;
  const double depth =
      std::min(press_depth_for_force(0.5 * force.f_max, force.proxy.stiffness, hand_k), kMaxPressRadii * radius);
  const double press_force = depth / press_depth_for_force(1.0, force.proxy.stiffness, hand_k);
  ProbeParams pp = default_probe_params(world, radius, sites, seed, depth);
  if (up) pp.up = *up;
  const bool seen = force.model == RendererKind::kProxy && force.proxy.surface == ProxySurface::kSeen;
  if (seen) pp.first_touch = seen_first_touch(world, radius);
  if (tool && tool->count > 0 && !tool->is_single_at_tcp()) pp.tool_touch = tool_first_touch(world, *tool, seen, force.proxy.seen_window);
  if (!scaled && extent > 30.0)
    fmt::print(stderr,
               "warning: the scene is not registered and spans {:.0f} units; the simulated hand and "
               "device work in metres and newtons, so they will move it like a {:.0f} m object. "
               "Register it into metres (--registration, --reg-scale, --up) for a realistic run.\n",
               extent, extent);
  ProbeTrajectory traj = generate_probe_trajectory(world, pp);
  if (report)
    fmt::print(report, "probe      {} sites, tool radius {:.4g}, up [{:.2f}, {:.2f}, {:.2f}], {:.1f} s per pass; the hand "
               "presses {:.3g} past first contact (to {:.3g} N at {:.0f} N/m)\n",
               traj.sites().size(), pp.tool_radius, for_print(pp.up).x(), for_print(pp.up).y(), for_print(pp.up).z(),
               traj.duration(), depth, press_force, force.proxy.stiffness);
  if (report && press_force < 0.3 * force.f_max) {
    std::fflush(stdout);
    fmt::print(stderr,
               "note: the hand presses at most {:.0f} tool radii deep, so it reaches {:.2g} N of the {:.3g} N "
               "range on a world this small ({:.3g} across); --reg-scale or a larger --tool-radius presses harder\n",
               kMaxPressRadii, press_force, force.f_max, extent);
  }
  if (int(traj.sites().size()) < sites)
    fmt::print(stderr,
               "warning: only {} of {} sites are reachable from above (world up [{:.2f}, {:.2f}, "
               "{:.2f}]); if the scene is upside down or on its side, the probe meets its underside: "
               "try another --up (`gshaptics info SCENE --up AXIS` previews it)\n",
               traj.sites().size(), sites, for_print(pp.up).x(), for_print(pp.up).y(), for_print(pp.up).z());
  return traj;
}

void print_no_contact_hints(const PreparedWorld& w, const SceneOptions& so, double tool_radius) {
  const double extent = robust_extent(w.world);
  const Eigen::Vector3d up = for_print(w.world.up());
  std::fflush(stdout);
  fmt::print(stderr, "likely causes, from this run's numbers:\n");
  if (!is_scaled(so) && (extent > 30.0 || extent < 0.05))
    fmt::print(stderr,
               "  units      the scene spans {:.4g} units and is not registered; the simulated hand "
               "works in metres, so register it into metres (`gshaptics info {}` suggests a "
               "--reg-scale)\n", extent, so.scene);
  fmt::print(stderr,
             "  up axis    the probe came down along -[{:.2f}, {:.2f}, {:.2f}] (--up {}); if the scene "
             "is upside down or on its side, try another --up (auto, y-up, y-down, z-up, ...)\n",
             up.x(), up.y(), up.z(), so.up);
  const double kept = w.report.filter.kept_fraction();
  if (kept < 0.5)
    fmt::print(stderr, "  opacity    the filter (opacity > {:.2f}) kept only {:.0f}% of the Gaussians; "
                       "try --min-opacity 0.1\n", w.config.min_opacity, 100 * kept);
  if (tool_radius < 0.002 * extent || tool_radius > 0.1 * extent)
    fmt::print(stderr, "  tool size  the tool radius {:.4g} is {:.2g}% of the scene's size {:.4g}; 0.5-5% "
                       "usually touches\n", tool_radius, 100 * tool_radius / extent, extent);
}

std::string describe_control(const ControlParams& c, bool simulated) {
  if (c.mode == ControlMode::kImpedance)
    return simulated ? "impedance: the simulated device is an ideal mass-damper, commanded force"
                     : "impedance: the device is commanded force";
  return fmt::format("admittance: a virtual tool of {:.3g} kg and {:.3g} N s/m under the user's measured force and the "
                     "rendered force, within {:.3g} m/s and {:.3g} m/s^2 (sensor tared over {:.3g} s, dead band {:.3g} N); "
                     "the device tracks it{}",
                     c.admittance.mass, c.admittance.damping, c.robot.max_speed, c.robot.max_acceleration,
                     c.robot.tare_time, c.robot.dead_band,
                     simulated ? " (the simulated robot: a position servo with a force sensor at the handle)" : "");
}

nlohmann::json control_json(const ControlParams& c) {
  nlohmann::json j = {{"mode", control_mode_name(c.mode)}};
  if (c.mode == ControlMode::kAdmittance) {
    j["virtual_mass_kg"] = c.admittance.mass;
    j["virtual_damping_ns_per_m"] = c.admittance.damping;
    j["max_speed_m_per_s"] = c.robot.max_speed;
    j["max_acceleration_m_per_s2"] = c.robot.max_acceleration;
    j["sensor_tare_s"] = c.robot.tare_time;
    j["sensor_dead_band_n"] = c.robot.dead_band;
  }
  return j;
}

unsigned log_columns(unsigned columns, const ControlParams& c) {
  return c.mode == ControlMode::kAdmittance ? columns | kColumnsAdmittance : columns;
}

bool plot_run(const std::string& csv, const std::string& summary, const std::string& png,
              const std::string& command) {
  return run_python(find_tool_script("plot_probe_run.py"), {csv, summary, png}, command);
}

ProbeSessionResult simulate_probe(const CollisionWorld& world, const SimulateOptions& o, bool scaled, std::FILE* report,
                                  const std::optional<Eigen::Vector3d>& up, const std::function<void(double)>& progress,
                                  const RendererFactory& make_renderer) {
  ProbeTrajectory traj =
      make_probe_trajectory(world, scaled, o.sites, o.seed, o.tool_radius, o.force, report, up, &o.tool.tool);
  ProbeRunParams rp;
  rp.rate_hz = o.rate;
  rp.renderer = o.force.spec();
  rp.make_renderer = make_renderer;
  rp.inline_query = o.exec.inline_query;
  rp.latency_ticks = o.exec.latency_ticks;
  rp.safety = o.safety;
  rp.safety.f_max = o.force.f_max;
  rp.tool = o.tool.tool;
  rp.control = o.control;
  if (report) {
    fmt::print(report, "rate       {:.0f} Hz of simulated time (as fast as the CPU allows), {}\n", o.rate,
               describe_execution(o.exec, true));
    fmt::print(report, "control    {}\n", describe_control(o.control, /*simulated=*/true));
    if (rp.tool.count > 0)
      fmt::print(report, "tool       {} ({} part{}, held at the world's orientation)\n", o.tool.spec, rp.tool.count,
                 rp.tool.count == 1 ? "" : "s");
    std::fflush(report);  // a progress bar goes to stderr: keep the lines above first
  }
  ProbeRunResult run = run_probe(world, traj, rp, progress);
  return {std::move(traj), std::move(run)};
}

namespace {

// The passivity controller over a run: ticks it acted on, its peak damping, the lowest energy.
struct PassivityTally {
  std::uint64_t ticks = 0;
  double min_energy = 0, peak_damping = 0;
  ProxyStepWork proxy_work;  // what the proxy's own steps did on the coupling
};

PassivityTally tally_passivity(const std::vector<TickRecord>& ticks) {
  PassivityTally p;
  for (const TickRecord& t : ticks) {
    if (t.flags & kFlagPassivity) ++p.ticks;
    p.min_energy = std::min(p.min_energy, t.energy);
    p.peak_damping = std::max(p.peak_damping, double(t.damping));
  }
  p.proxy_work = proxy_step_work(ticks);
  return p;
}

// summary.json's head: the scene, the world, the tool (and the torque a force-only device dropped),
// the rate, mode, renderer, ticks, passivity and query time.
nlohmann::json simulate_summary(const SimulateOptions& o, const SceneOptions& so, const PreparedWorld& pw,
                                const SceneObjects& objects, const ProbeSessionResult& probe, const PassivityTally& pc) {
  const ProbeRunResult& run = probe.run;
  nlohmann::json sj;
  sj["scene"] = so.scene;
  sj["registration"] = so.registration_file;
  sj["gaussians_loaded"] = pw.scene.report.loaded;
  sj["gaussians_kept"] = pw.world.size();
  if (!so.objects.empty()) sj["objects"] = objects_json(so, pw, &objects);
  sj["min_opacity"] = pw.config.min_opacity;
  sj["tool_radius"] = probe.trajectory.tool_radius();
  if (o.tool.tool.count > 0) {
    // The simulated device is a 3-DoF admittance device: the safety layer drops the torque a
    // compound tool asks for (as for any force-only device) and counts those ticks.
    std::size_t dropped = 0;
    for (const TickRecord& r : run.ticks) dropped += (r.flags & kFlagTorqueDropped) != 0;
    sj["tool"] = {{"spec", o.tool.spec}, {"parts", o.tool.tool.count}, {"torque_dropped_ticks", dropped}};
    fmt::print("torque     the simulated device renders force only: {} ticks had a torque it was not sent\n",
               dropped);
  }
  sj["rate_hz"] = o.rate;
  sj["mode"] = describe_execution(o.exec, true);
  sj["control"] = control_json(o.control);
  sj["renderer"] = std::string(renderer_name(o.force.model));
  sj["ticks"] = run.ticks.size();
  sj["passivity"] = {{"enabled", o.safety.passivity.enabled}, {"ticks", pc.ticks},
                     {"peak_damping", pc.peak_damping}, {"min_energy_j", pc.min_energy},
                     {"proxy_step_stored_j", pc.proxy_work.stored}, {"proxy_step_net_j", pc.proxy_work.net}};
  sj["query_us"] = {{"p50", run.query_time.p50_us}, {"p99", run.query_time.p99_us},
                    {"max", run.query_time.max_us}, {"ticks_over_1ms", run.query_time.over_1ms}};
  return sj;
}

// The episodes' table (printed) and their JSON.
nlohmann::json report_episodes(const ProbeRunResult& run, RendererKind model) {
  nlohmann::json eps = nlohmann::json::array();
  // The proxy's contacts are the Gaussians holding it (at most three), not the paper's K_min set.
  const bool proxy = model == RendererKind::kProxy;
  fmt::print("\n{:>3} {:>9} {:>9} {:>13} {:>11} {:>8}  {}\n", "#", "start s", "end s",
             proxy ? "peak holding" : "peak contacts", "peak force N", "W mJ", "direction at peak");
  for (std::size_t i = 0; i < run.episodes.size(); ++i) {
    const auto& e = run.episodes[i];
    fmt::print("{:>3} {:>9.3f} {:>9.3f} {:>13} {:>11.2f} {:>8.2f}  [{:+.2f}, {:+.2f}, {:+.2f}]\n", i + 1,
               e.t_start, e.t_end, e.peak_contacts, e.peak_force, e.energy_j * 1e3, e.peak_direction.x(),
               e.peak_direction.y(), e.peak_direction.z());
    eps.push_back({{"t_start", e.t_start}, {"t_end", e.t_end}, {"peak_contacts", e.peak_contacts},
                   {"peak_force", e.peak_force}, {"energy_j", e.energy_j},
                   {"peak_direction", {e.peak_direction.x(), e.peak_direction.y(), e.peak_direction.z()}}});
  }
  if (!run.episodes.empty()) fmt::print("W: the energy the hand put in (< 0: the scene gave back more){}\n",
                                        active_episodes_note(run.episodes));
  return eps;
}

// Why a planned site was not touched, or how often it bounced ("" for a clean touch).
// Every planned site accounted for: touched or not, when, how hard, bounces (printed, and into
// `sj`: sites, sites_touched, sites_missed).
void report_sites(const ProbeSessionResult& probe, const RendererSpec& renderer, nlohmann::json& sj) {
  const ProbeTrajectory& traj = probe.trajectory;
  const ProbeRunResult& run = probe.run;
  const std::vector<SiteAccount> accounts = account_sites(traj, run.ticks, run.episodes);
  nlohmann::json sites = nlohmann::json::array();
  fmt::print("\n{:>4} {:>9} {:>9} {:>12} {:>8}\n", "site", "planned s", "touched s", "peak force N", "episodes");
  int missed = 0;
  for (std::size_t i = 0; i < traj.sites().size(); ++i) {
    const ProbeSite& st = traj.sites()[i];
    const SiteAccount& a = accounts[i];
    nlohmann::json j = {{"gaussian_index", st.gaussian_index}, {"t_touch", st.t_touch},
                        {"surface_point", {st.surface_point.x(), st.surface_point.y(), st.surface_point.z()}},
                        {"normal", {st.normal.x(), st.normal.y(), st.normal.z()}},
                        {"touched", a.touched}, {"peak_force", a.peak_force}, {"episodes", a.episodes},
                        {"closest_approach", std::isfinite(a.closest_approach) ? a.closest_approach : -1.0}};
    if (a.touched) j["t_first_contact"] = a.t_first_contact;
    sites.push_back(j);
    if (!a.touched) ++missed;
    fmt::print("{:>4} {:>9.3f} {:>9} {:>12.2f} {:>8}  {}\n", i + 1, a.t_planned,
               a.touched ? fmt::format("{:.3f}", a.t_first_contact) : std::string("-"), a.peak_force, a.episodes,
               site_note(a, traj.tool_radius(), renderer));
  }
  sj["sites"] = sites;
  sj["sites_touched"] = int(accounts.size()) - missed;
  sj["sites_missed"] = missed;
}

}  // namespace

int run_simulate(SimulateOptions o) {
  if (o.scenario == SimulateScenario::kPush) {
#ifdef GSHAPTICS_HAVE_OBJECTS
    return run_simulate_push(o);
#else
    throw InputError("--scenario push: this build has no rigid objects (libmujoco-dev was missing when it was built)");
#endif
  }
  if (o.tool.given() && o.tool_radius <= 0) o.tool_radius = o.tool.tool.largest_semi_axis();
  const RendererSpec renderer = o.force.spec();
  const SceneOptions so = with_bundled_defaults(o.scene, "simulate", renderer);
  const std::string out_dir =
      prepare_out_dir(o.out_dir, so.scene, {"probe_log.csv", "summary.json", "probe_run.png"});
  const PreparedWorld pw = prepare_world(so, o.quiet);
  o.force.materials = with_scene_colours(o.force.materials, so.scene);
  warn_if_outside_profile(pw, o.force);
  const SceneObjects objects = scene_objects(pw, so, o.rate);
  Progress bar("simulating", !o.quiet);
  const ProbeSessionResult probe = simulate_probe(pw.world, o, is_scaled(so), stdout, std::nullopt,
                                                  [&](double f) { bar(f); }, objects.make_renderer);
  bar.done();
  const ProbeRunResult& run = probe.run;

  OutputStage stage(out_dir, {"probe_log.csv", "summary.json", "probe_run.png"});
  const std::string csv = stage.path("probe_log.csv");
  const std::string summary_path = stage.path("summary.json");
  std::vector<std::string> write_errors;  // the run is done: report a lost output, keep going
  try {
    write_tick_log_csv(csv, run.ticks, log_columns(kProbeLogColumns, o.control));
  } catch (const std::exception& e) {
    write_errors.push_back(e.what());
  }
  const PassivityTally pc = tally_passivity(run.ticks);
  nlohmann::json sj = simulate_summary(o, so, pw, objects, probe, pc);
  sj["episodes"] = report_episodes(run, o.force.model);
  report_sites(probe, renderer, sj);
  try {
    write_file_atomically(summary_path, sj.dump(2) + "\n");
  } catch (const std::exception& e) {
    write_errors.push_back(e.what());
  }

  fmt::print("\npassivity  {}: the controller added damping on {} ticks (peak {:.3g} N s/m); lowest observed energy "
             "{:.3g} mJ; the proxy's own steps stored {:.3g} mJ in the coupling (net {:.3g} mJ)\n",
             o.safety.passivity.enabled ? "on" : "off (observed only)", pc.ticks, pc.peak_damping, pc.min_energy * 1e3,
             pc.proxy_work.stored * 1e3, pc.proxy_work.net * 1e3);
  fmt::print("query time p50 {:.1f} us, p99 {:.1f} us, max {:.1f} us; {} of {} ticks over 1 ms\n",
             run.query_time.p50_us, run.query_time.p99_us, run.query_time.max_us,
             run.query_time.over_1ms, run.ticks.size());
  if (!write_errors.empty()) {
    for (const std::string& e : write_errors) fmt::print(stderr, "error: the run completed, but {}\n", e);
    fmt::print(stderr, "note: {} is left as it was\n", out_dir);
    return kExitOutputsLost;
  }
  int rc = 0;
  if (run.episodes.empty()) {
    fmt::print(stderr, "error: the probe run made no contact\n");
    print_no_contact_hints(pw, so, probe.trajectory.tool_radius());
    rc = 1;
  }
  const bool plotted = !o.no_plot && plot_run(csv, summary_path, stage.path("probe_run.png"), "simulate");
  if (!o.no_plot && !plotted) rc = 1;
  stage.commit();
  fmt::print("log        {}\nsummary    {}\n", stage.final_path("probe_log.csv"), stage.final_path("summary.json"));
  if (plotted) fmt::print("figure     {}\n", stage.final_path("probe_run.png"));
  return rc;
}

}  // namespace gshaptics::session
