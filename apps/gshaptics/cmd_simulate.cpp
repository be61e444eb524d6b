// `gshaptics simulate [SCENE]`: the main job. A simulated user probes the scene through a
// simulated admittance device at 1 kHz; writes the per-tick log, a summary and the figure of
// the paper's Fig. 5.

#include <fmt/format.h>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "options.h"
#include "gshaptics/error.h"
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
  ForceModelOptions force;
  ExecutionOptions exec;
  SafetyParams safety;
  bool no_plot = false;
  bool quiet = false;
};

}  // namespace

void register_simulate(CLI::App& app) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Simulated probe run (the main job): a seeded trajectory touches N sites on the object's "
      "outer surface; a simulated hand drives a simulated admittance device; every 1 kHz tick of "
      "simulated time runs the servo step of a real-time run (safety layer included) in the "
      "runtime's execution mode. Writes probe_log.csv, summary.json and probe_run.png (the "
      "paper's Fig. 5) to --out. Without SCENE, runs the bundled Truck.");
  cmd->add_option("scene", o->scene.scene, "Scene file (default: bundled data/truck.splat, registered z-up in metres)");
  cmd->add_option("--out", o->out_dir, "Output folder (default: runs/<name>-<extension>, e.g. runs/truck-splat)");
  cmd->add_option("--sites", o->sites, "Contact sites to probe")->capture_default_str()
      ->check(CLI::Range(1, 100));
  cmd->add_option("--seed", o->seed, "Seed of the site choice")->capture_default_str();
  cmd->add_option("--tool-radius", o->tool_radius,
                  "Spherical tool radius, world units (default: 1% of the scene's 1-99 pct extent)")
      ->check(check::positive());
  cmd->add_option("--rate", o->rate, "Servo rate of the simulation, Hz")->capture_default_str()
      ->check(check::range(100.0, 20000.0));
  add_force_options(*cmd, o->force);
  add_execution_options(*cmd, o->exec, /*simulated=*/true);
  cmd->add_flag("--no-plot", o->no_plot, "Do not draw probe_run.png (needs /usr/bin/python3 with matplotlib)");
  cmd->add_flag("--quiet", o->quiet, "No progress bars");
  add_world_options(*cmd, o->scene);
  add_world_cache_option(*cmd, o->scene);

  cmd->callback([o] {
    const SceneOptions so = with_bundled_defaults(o->scene, "simulate");
    const std::string out_dir =
        prepare_out_dir(o->out_dir, so.scene, {"probe_log.csv", "summary.json", "probe_run.png"});
    const PreparedWorld pw = prepare_world(so, o->quiet);
    warn_if_outside_profile(pw, o->force);
    const CollisionWorld& world = pw.world;
    const WorldConfig& cfg = pw.config;
    const LoadedScene& s = pw.scene;
    const ProbeTrajectory traj = make_probe_trajectory(pw, is_registered(so), o->sites, o->seed, o->tool_radius);
    fmt::print("rate       {:.0f} Hz of simulated time (as fast as the CPU allows), {}\n", o->rate,
               describe_execution(o->exec, true));

    std::fflush(stdout);  // the progress bar goes to stderr: keep the lines above first
    ProbeRunParams rp;
    rp.rate_hz = o->rate;
    rp.renderer = o->force.spec();
    rp.inline_query = o->exec.inline_query;
    rp.latency_ticks = o->exec.latency_ticks;
    rp.safety = o->safety;
    rp.safety.f_max = o->force.f_max;
    Progress bar("simulating", !o->quiet);
    const ProbeRunResult run = run_probe(world, traj, rp, [&](double f) { bar(f); });
    bar.done();

    OutputStage stage(out_dir, {"probe_log.csv", "summary.json", "probe_run.png"});
    const std::string csv = stage.path("probe_log.csv");
    const std::string summary_path = stage.path("summary.json");
    const std::string png = stage.path("probe_run.png");
    std::vector<std::string> write_errors;  // the run is done: report a lost output, keep going
    try {
      write_tick_log_csv(csv, run.ticks, kProbeLogColumns);
    } catch (const std::exception& e) {
      write_errors.push_back(e.what());
    }

    nlohmann::json sj;
    sj["scene"] = so.scene;
    sj["registration"] = so.registration_file;
    sj["gaussians_loaded"] = s.report.loaded;
    sj["gaussians_kept"] = world.size();
    sj["min_opacity"] = cfg.min_opacity;
    sj["tool_radius"] = traj.tool_radius();
    sj["rate_hz"] = o->rate;
    sj["mode"] = describe_execution(o->exec, true);
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
    try {
      write_file_atomically(summary_path, sj.dump(2) + "\n");
    } catch (const std::exception& e) {
      write_errors.push_back(e.what());
    }

    fmt::print("\nquery time p50 {:.1f} us, p99 {:.1f} us, max {:.1f} us; {} of {} ticks over 1 ms\n",
               run.query_time.p50_us, run.query_time.p99_us, run.query_time.max_us,
               run.query_time.over_1ms, run.ticks.size());
    if (!write_errors.empty()) {
      for (const std::string& e : write_errors) fmt::print(stderr, "error: the run completed, but {}\n", e);
      fmt::print(stderr, "note: {} is left as it was\n", out_dir);
      set_exit_code(kExitOutputsLost);
      return;
    }
    if (run.episodes.empty()) {
      fmt::print(stderr, "error: the probe run made no contact\n");
      print_no_contact_hints(pw, so, traj.tool_radius());
      set_exit_code(1);
    }
    const bool plotted = !o->no_plot && plot_run(csv, summary_path, png, "simulate");
    if (!o->no_plot && !plotted) set_exit_code(1);
    stage.commit();
    fmt::print("log        {}\nsummary    {}\n", stage.final_path("probe_log.csv"), stage.final_path("summary.json"));
    if (plotted) fmt::print("figure     {}\n", stage.final_path("probe_run.png"));
  });
}

}  // namespace gshaptics::cli
