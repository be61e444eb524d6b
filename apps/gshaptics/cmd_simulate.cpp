// `gshaptics simulate [SCENE]`: the main job. A simulated user probes the scene through a
// simulated admittance device at 1 kHz; writes the per-tick log, a summary and the figure of
// the paper's Fig. 5.

#include <fmt/format.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "common.h"
#include "gshaptics/io/error.h"
#include "gshaptics/scene/scene_stats.h"
#include "gshaptics/sim/probe_run.h"

namespace gshaptics::cli {

namespace {

struct SimulateOptions {
  SceneOptions scene;
  std::string out_dir;
  int sites = 7;
  std::uint64_t seed = 1;
  double tool_radius = 0;  // 0: 1% of the scene's robust extent
  double rate = 1000;
  ForceParams force;
  bool no_plot = false;
  bool quiet = false;
};

std::string find_plot_script() {
  if (const char* env = std::getenv("GSHAPTICS_PLOT_SCRIPT")) return env;
  for (const std::string& p : {std::string(GSHAPTICS_SOURCE_DIR) + "/tools/plot_probe_run.py",
                              std::string(GSHAPTICS_INSTALL_DATADIR) + "/plot_probe_run.py"})
    if (std::filesystem::exists(p)) return p;
  return "";
}

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

void register_simulate(CLI::App& app) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Simulated probe run (the main job): a seeded trajectory touches N sites on the object's "
      "outer surface; a simulated hand drives a simulated admittance device; every 1 kHz tick "
      "runs the collision query and force model inline. Writes probe_log.csv, summary.json and "
      "probe_run.png (the paper's Fig. 5) to --out. Without SCENE, runs the bundled Truck.");
  cmd->add_option("scene", o->scene.scene, "Scene file (default: bundled data/truck.splat, registered z-up in metres)");
  cmd->add_option("--out", o->out_dir, "Output folder (default: runs/<scene name>)");
  cmd->add_option("--sites", o->sites, "Contact sites to probe")->capture_default_str()
      ->check(CLI::Range(1, 100));
  cmd->add_option("--seed", o->seed, "Seed of the site choice")->capture_default_str();
  cmd->add_option("--tool-radius", o->tool_radius,
                  "Spherical tool radius, world units (default: 1% of the scene's 1-99 pct extent)");
  cmd->add_option("--rate", o->rate, "Servo rate of the simulation, Hz")->capture_default_str()
      ->check(CLI::Range(100.0, 20000.0));
  cmd->add_option("--k-base", o->force.k_base, "Base stiffness k_base, N per contact (eq. 9)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd->add_option("--damping", o->force.damping, "Damping D, N s/m (eq. 10)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd->add_option("--f-max", o->force.f_max, "Force clamp F_max, N (eq. 11)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd->add_option("--tau-normal", o->force.tau_normal, "Time constant of the normal EMA, s")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd->add_option("--tau-opacity", o->force.tau_opacity, "Time constant of the opacity EMA, s")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-plot", o->no_plot, "Do not draw probe_run.png (needs /usr/bin/python3 with matplotlib)");
  cmd->add_flag("--quiet", o->quiet, "No progress bars");
  add_world_options(*cmd, o->scene);

  cmd->callback([o] {
    SceneOptions so = o->scene;
    if (so.scene.empty()) {
      so.scene = bundled_scene();
      if (so.scene.empty()) throw InputError("simulate: bundled scene data/truck.splat not found; give SCENE");
      if (so.registration_file.empty()) so.registration_file = bundled_registration();
    }
    const bool registered = !so.registration_file.empty() || !so.reg_rotation.empty() ||
                            !so.reg_scale.empty() || !so.reg_translation.empty() || so.up != "none";
    const LoadedScene s = load_with_progress(so.scene, o->quiet);
    const WorldConfig cfg = world_config_from(so, s.report.frame);
    WorldBuildReport br;
    const CollisionWorld world = CollisionWorld::build(s.scene, cfg, &br);
    fmt::print("scene      {} ({}, {} Gaussians, {} skipped)\n", so.scene, to_string(s.report.format),
               s.report.loaded, s.report.skipped());
    fmt::print("filter     opacity > {:.2f}: kept {} ({:.1f}%)\n", cfg.min_opacity, br.filter.after,
               100 * br.filter.kept_fraction());
    fmt::print("world      {} Gaussians, BVH built in {:.0f} ms, {:.1f} MB{}\n", world.size(),
               br.build_seconds * 1e3, double(br.memory_bytes) / 1e6,
               so.registration_file.empty() ? "" : ", registration " + so.registration_file);

    ProbeParams pp;
    pp.sites = o->sites;
    pp.seed = o->seed;
    // A registered (or --up turned) world is z-up; otherwise the probe goes along the file's own
    // up axis (-y for PLY/.splat, +y for SPZ).
    pp.up = registered ? Eigen::Vector3d(0, 0, 1) : up_axis_from("auto", s.report.frame);
    if (o->tool_radius > 0) {
      pp.tool_radius = o->tool_radius;
    } else {
      std::vector<double> ax[3];
      for (const auto& g : world.gaussians())
        for (int k = 0; k < 3; ++k) ax[k].push_back(g.center[k]);
      double extent = 0;
      for (int k = 0; k < 3; ++k) extent = std::max(extent, percentile(ax[k], 99) - percentile(ax[k], 1));
      pp.tool_radius = 0.01 * extent;
    }
    // Speeds scale with the tool so that any scene unit gives a similar run.
    pp.approach_speed = 2.0 * pp.tool_radius;
    pp.travel_speed = 8.0 * pp.tool_radius;
    const ProbeTrajectory traj = generate_probe_trajectory(world, pp);
    fmt::print("probe      {} sites, tool radius {:.4g}, up [{:.2f}, {:.2f}, {:.2f}], {:.1f} s at {:.0f} Hz\n",
               traj.sites().size(), pp.tool_radius, pp.up.x(), pp.up.y(), pp.up.z(),
               traj.duration(), o->rate);
    if (int(traj.sites().size()) < o->sites)
      fmt::print(stderr, "warning: only {} of {} sites are reachable on this scene\n",
                 traj.sites().size(), o->sites);

    std::fflush(stdout);  // the progress bar goes to stderr: keep the lines above first
    ProbeRunParams rp;
    rp.rate_hz = o->rate;
    rp.force = o->force;
    Progress bar("simulating", !o->quiet);
    const ProbeRunResult run = run_probe(world, traj, rp, [&](double f) { bar(f); });
    bar.done();

    std::string out_dir = o->out_dir;
    if (out_dir.empty()) out_dir = "runs/" + std::filesystem::path(so.scene).stem().string();
    std::filesystem::create_directories(out_dir);
    const std::string csv = out_dir + "/probe_log.csv";
    const std::string summary_path = out_dir + "/summary.json";
    const std::string png = out_dir + "/probe_run.png";
    write_tick_log_csv(csv, run.ticks);

    nlohmann::json sj;
    sj["scene"] = so.scene;
    sj["registration"] = so.registration_file;
    sj["gaussians_loaded"] = s.report.loaded;
    sj["gaussians_kept"] = world.size();
    sj["min_opacity"] = cfg.min_opacity;
    sj["tool_radius"] = pp.tool_radius;
    sj["rate_hz"] = o->rate;
    sj["ticks"] = run.ticks.size();
    sj["query_us"] = {{"p50", run.query_time.p50_us}, {"p99", run.query_time.p99_us},
                      {"max", run.query_time.max_us}, {"ticks_over_1ms", run.query_time.over_1ms}};
    nlohmann::json eps = nlohmann::json::array();
    fmt::print("\n{:>3} {:>9} {:>9} {:>13} {:>11}  {}\n", "#", "start s", "end s", "peak contacts",
               "peak force N", "direction at peak");
    for (std::size_t i = 0; i < run.episodes.size(); ++i) {
      const auto& e = run.episodes[i];
      fmt::print("{:>3} {:>9.3f} {:>9.3f} {:>13} {:>11.2f}  [{:+.2f}, {:+.2f}, {:+.2f}]\n", i + 1,
                 e.t_start, e.t_end, e.peak_contacts, e.peak_force, e.peak_direction.x(),
                 e.peak_direction.y(), e.peak_direction.z());
      eps.push_back({{"t_start", e.t_start}, {"t_end", e.t_end}, {"peak_contacts", e.peak_contacts},
                     {"peak_force", e.peak_force},
                     {"peak_direction", {e.peak_direction.x(), e.peak_direction.y(), e.peak_direction.z()}}});
    }
    sj["episodes"] = eps;
    nlohmann::json sites = nlohmann::json::array();
    for (const auto& st : traj.sites())
      sites.push_back({{"gaussian_index", st.gaussian_index}, {"t_touch", st.t_touch},
                       {"surface_point", {st.surface_point.x(), st.surface_point.y(), st.surface_point.z()}},
                       {"normal", {st.normal.x(), st.normal.y(), st.normal.z()}}});
    sj["sites"] = sites;
    write_file_atomically(summary_path, sj.dump(2) + "\n");

    fmt::print("\nquery time p50 {:.1f} us, p99 {:.1f} us, max {:.1f} us; {} of {} ticks over 1 ms\n",
               run.query_time.p50_us, run.query_time.p99_us, run.query_time.max_us,
               run.query_time.over_1ms, run.ticks.size());
    fmt::print("log        {}\nsummary    {}\n", csv, summary_path);
    if (run.episodes.empty()) {
      fmt::print(stderr, "error: the probe run made no contact\n");
      set_exit_code(1);
    }
    if (o->no_plot) return;
    const std::string script = find_plot_script();
    if (script.empty()) throw InputError("simulate: tools/plot_probe_run.py not found (use --no-plot)");
    const char* py = std::getenv("GSHAPTICS_PYTHON");
    const std::string cmdline = fmt::format("{} {} {} {} {}", shell_quote(py ? py : "/usr/bin/python3"),
                                            shell_quote(script), shell_quote(csv),
                                            shell_quote(summary_path), shell_quote(png));
    const int rc = std::system(cmdline.c_str());
    if (rc != 0) {
      fmt::print(stderr, "error: plotting failed ({}); the log and summary are written. Install "
                         "python3-matplotlib or pass --no-plot\n", cmdline);
      set_exit_code(1);
      return;
    }
    fmt::print("figure     {}\n", png);
  });
}

}  // namespace gshaptics::cli
