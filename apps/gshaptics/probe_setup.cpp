#include "probe_setup.h"

#include <fmt/format.h>

#include <cstdlib>
#include <filesystem>

#include "gshaptics/error.h"
#include "gshaptics/sim/pose_sampler.h"

namespace gshaptics::cli {

namespace {

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

void add_force_options(CLI::App& cmd, ForceModelOptions& o) {
  cmd.add_option("--force-model", o.model,
                 std::string("Force model: proxy (god-object on the Gaussians, virtual coupling in N/m) "
                             "or paper (the paper's penalty force, eq. 7-11)"))
      ->capture_default_str()
      ->check(CLI::IsMember({"proxy", "paper"}));
  ForceParams& force = o.force;
  cmd.add_option("--k-base", force.k_base, "paper: base stiffness k_base, N per contact (eq. 9)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd.add_option("--damping", force.damping, "paper: damping D, N s/m (eq. 10)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd.add_option("--f-max", force.f_max, "Force limit F_max, N (every model; paper eq. 11)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  cmd.add_option("--tau-normal", force.tau_normal, "paper: time constant of the normal EMA, s")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd.add_option("--tau-opacity", force.tau_opacity, "paper: time constant of the opacity EMA, s")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  ProxyParams& p = o.proxy;
  cmd.add_option("--stiffness", p.stiffness, "proxy: coupling stiffness k_c, N/m")
      ->capture_default_str()->check(CLI::PositiveNumber);
  cmd.add_option("--coupling-damping", p.damping, "proxy: coupling damping b_c, N s/m (passive above k_c T / 2)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd.add_option("--mu-s", p.mu_s, "proxy: static friction coefficient (0: off)")->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd.add_option("--mu-k", p.mu_k, "proxy: kinetic friction coefficient (<= --mu-s)")->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd.add_flag("--opacity-stiffness", p.opacity_stiffness, "proxy: scale k_c by the blocking Gaussians' opacity (paper eq. 9)");
  cmd.add_option("--substeps", p.substeps, "proxy: sweeps per tick")->capture_default_str()->check(CLI::Range(1, 16));
}

SceneOptions with_bundled_defaults(SceneOptions so, const std::string& command) {
  if (so.scene.empty()) {
    so.scene = bundled_scene();
    if (so.scene.empty()) throw InputError(command + ": bundled scene data/truck.splat not found; give SCENE");
    if (so.registration_file.empty()) so.registration_file = bundled_registration();
  }
  return so;
}

bool is_registered(const SceneOptions& so) {
  return !so.registration_file.empty() || !so.reg_rotation.empty() || !so.reg_scale.empty() ||
         !so.reg_translation.empty() || so.up != "none";
}

PreparedWorld prepare_world(const SceneOptions& so, bool quiet) {
  LoadedScene s = load_with_progress(so.scene, quiet);
  const WorldConfig cfg = world_config_from(so);
  WorldBuildReport br;
  CollisionWorld world = CollisionWorld::build(s.scene, cfg, &br);
  fmt::print("scene      {} ({}, {} Gaussians, {} skipped)\n", so.scene, to_string(s.report.format),
             s.report.loaded, s.report.skipped());
  fmt::print("filter     opacity > {:.2f}: kept {} ({:.1f}%)\n", cfg.min_opacity, br.filter.after,
             100 * br.filter.kept_fraction());
  fmt::print("world      {} Gaussians, BVH built in {:.0f} ms, {:.1f} MB{}\n", world.size(),
             br.build_seconds * 1e3, double(br.memory_bytes) / 1e6,
             so.registration_file.empty() ? "" : ", registration " + so.registration_file);
  return {std::move(s), cfg, br, std::move(world)};
}

ProbeTrajectory make_probe_trajectory(const PreparedWorld& w, bool registered, int sites,
                                      std::uint64_t seed, double tool_radius) {
  ProbeParams pp;
  pp.sites = sites;
  pp.seed = seed;
  // A registered (or --up turned) world is z-up; otherwise the probe goes along the file's own
  // up axis (-y for PLY/.splat, +y for SPZ).
  pp.up = registered ? Eigen::Vector3d(0, 0, 1) : up_of(w.scene.report.frame);
  const double extent = robust_extent(w.world);
  pp.tool_radius = tool_radius > 0 ? tool_radius : 0.01 * extent;
  if (!registered && extent > 30.0)
    fmt::print(stderr,
               "warning: the scene is not registered and spans {:.0f} units; the simulated hand and "
               "device work in metres and newtons, so they will move it like a {:.0f} m object. "
               "Register it into metres (--registration, --reg-scale, --up) for a realistic run.\n",
               extent, extent);
  pp.approach_speed = 2.0 * pp.tool_radius;
  pp.travel_speed = 8.0 * pp.tool_radius;
  ProbeTrajectory traj = generate_probe_trajectory(w.world, pp);
  fmt::print("probe      {} sites, tool radius {:.4g}, up [{:.2f}, {:.2f}, {:.2f}], {:.1f} s per pass\n",
             traj.sites().size(), pp.tool_radius, pp.up.x(), pp.up.y(), pp.up.z(), traj.duration());
  if (int(traj.sites().size()) < sites)
    fmt::print(stderr, "warning: only {} of {} sites are reachable on this scene\n",
               traj.sites().size(), sites);
  return traj;
}

std::string find_tool_script(const std::string& name) {
  if (name == "plot_probe_run.py")
    if (const char* env = std::getenv("GSHAPTICS_PLOT_SCRIPT")) return env;
  for (const std::string& p : {std::string(GSHAPTICS_SOURCE_DIR) + "/tools/" + name,
                              std::string(GSHAPTICS_INSTALL_DATADIR) + "/" + name})
    if (std::filesystem::exists(p)) return p;
  return "";
}

bool run_python(const std::string& script, const std::vector<std::string>& args, const std::string& command) {
  if (script.empty()) throw InputError(command + ": the plotting script is not found in tools/ (use --no-plot)");
  const char* py = std::getenv("GSHAPTICS_PYTHON");
  std::string cmdline = shell_quote(py ? py : "/usr/bin/python3") + " " + shell_quote(script);
  for (const std::string& a : args) cmdline += " " + shell_quote(a);
  if (std::system(cmdline.c_str()) != 0) {
    fmt::print(stderr, "error: plotting failed ({}); the data files are written. Install "
                       "python3-matplotlib or pass --no-plot\n", cmdline);
    return false;
  }
  return true;
}

bool plot_run(const std::string& csv, const std::string& summary, const std::string& png,
              const std::string& command) {
  return run_python(find_tool_script("plot_probe_run.py"), {csv, summary, png}, command);
}

}  // namespace gshaptics::cli
