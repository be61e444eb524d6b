// `gshaptics simulate [SCENE]`: the main job. A simulated user probes the scene through a
// simulated admittance device at 1 kHz; writes the per-tick log, a summary and the figure of
// the paper's Fig. 5.

#include <map>
#include <memory>

#include "commands.h"
#include "options.h"

namespace gshaptics::cli {

void register_simulate(CLI::App& app) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Simulated probe run (the main job): a seeded trajectory touches N sites on the object's "
      "outer surface; a simulated hand drives a simulated admittance device; every 1 kHz tick of "
      "simulated time runs the servo step of a real-time run (safety layer included) in the "
      "runtime's execution mode. Writes probe_log.csv, summary.json and probe_run.png (the "
      "paper's Fig. 5) to --out. Without SCENE, runs the bundled Truck.");
  const std::map<std::string, SimulateScenario> scenarios{{"probe", SimulateScenario::kProbe},
                                                          {"push", SimulateScenario::kPush}};
  cmd->add_option("--scenario", o->scenario,
                  "probe (default): the paper's probe run of SCENE; push: the simulated hand pushes a 10 x 8 x 6 cm "
                  "box of Gaussians across a floor of Gaussians, the box's dynamics on MuJoCo (writes push_log.csv, "
                  "summary.json and push_run.png: the box's path, the contact force, the friction against mu m g)")
      ->transform(CLI::CheckedTransformer(scenarios));
  cmd->add_option_function<double>("--object-mass", [o](double v) { o->object_mass = v; },
                                   "push: the box's mass, kg (default 0.4)")
      ->check(check::positive());
  cmd->add_option_function<double>("--object-friction", [o](double v) { o->object_friction = v; },
                                   "push: the box's Coulomb friction against the floor (default 0.3)")
      ->check(check::non_negative());
  cmd->add_option("scene", o->scene.scene, "Scene file (default: bundled data/truck.splat, registered z-up in metres)");
  cmd->add_option("--out", o->out_dir, "Output folder (default: runs/<name>-<extension>, e.g. runs/truck-splat)");
  cmd->add_option("--sites", o->sites, "Contact sites to probe")->capture_default_str()
      ->check(CLI::Range(1, 100));
  cmd->add_option("--seed", o->seed, "Seed of the site choice")->capture_default_str();
  cmd->add_option("--tool-radius", o->tool_radius,
                  "Spherical tool radius, world units (default: 1% of the scene's 1-99 pct extent)")
      ->check(check::positive());
  add_tool_option(*cmd, o->tool,
                  "A tool with a shape, world units, as for `run --tool` (sphere:R, ellipsoid:A,B,C, "
                  "stylus:LENGTH,RADIUS along +z from the TCP, disc:RADIUS,THICKNESS, or FILE.json), held at the "
                  "world's orientation (a stylus probes tip first). The simulated device renders force only: the "
                  "summary counts the ticks whose torque was dropped. "
                  "--tool-radius then defaults to its largest semi-axis (the trajectory's scale)");
  cmd->add_option("--rate", o->rate, "Servo rate of the simulation, Hz")->capture_default_str()
      ->check(check::range(100.0, 20000.0));
  add_force_options(*cmd, o->force, &o->tool);
  add_execution_options(*cmd, o->exec, /*simulated=*/true);
  add_passivity_option(*cmd, o->safety.passivity);
  add_control_options(*cmd, o->control);
  cmd->add_flag("--no-plot", o->no_plot, "Do not draw probe_run.png (needs /usr/bin/python3 with matplotlib)");
  cmd->add_flag("--quiet", o->quiet, "No progress bars");
  add_world_options(*cmd, o->scene);
  add_object_option(*cmd, o->scene);
  add_world_cache_option(*cmd, o->scene);

  cmd->callback([o] {
    if (const int rc = run_simulate(*o)) set_exit_code(rc);
  });
}

}  // namespace gshaptics::cli
