// `gshaptics seen-felt`: seen against felt on real scenes (a thin CLI over
// session/report_session.h and fidelity/seen_felt.h).

#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/session/report_session.h"

namespace gshaptics::cli {

void register_seen_felt(CLI::App& app) {
  auto o = std::make_shared<SeenFeltCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "seen-felt",
      "Measure where the force starts and where the proxy rests against the surface the splats render, on real "
      "scenes: tools (spheres by default) of 0.5, 1 and 2 % of the scene's extent pressed vertically (the file's +y) and from "
      "around along rays onto the seen surface (the 3DGS median depth over every Gaussian), 4 tool radii past it, "
      "through the runtime's servo step. Writes a Markdown report (rays through, rays without force, felt - seen "
      "p90, onset p10 per configuration), the rays as CSV and a figure. Without scenes: the shared scenes.");
  cmd->add_option("scenes", o->scenes, "Scene files (default: the shared real scenes)")->check(CLI::ExistingFile);
  cmd->add_flag("--quick", o->quick, "3 rays per configuration, the 1 % tool only (CI)");
  cmd->add_option("--out", o->out, "Markdown report")->capture_default_str();
  cmd->add_option("--data-dir", o->data_dir, "Rays (CSV) and figure (default: beside --out, in a folder named after it: seen_felt/ for SEEN_FELT.md)");
  cmd->add_option("--rays", o->rays, "Rays kept per configuration (default 20, --quick 3)")->check(check::range(1, 1000));
  cmd->add_option("--tool-percent", o->tools_percent, "Tool radii, % of the scene's extent (comma-separated)")
      ->delimiter(',')
      ->check(check::range(0.05, 20.0));
  cmd->add_option("--direction", o->directions, "Press directions: vertical, around (comma-separated)")
      ->delimiter(',')
      ->check(CLI::IsMember({"vertical", "around"}));
  cmd->add_option("--tool-shape", o->tool,
                  "Tool pressed along the rays, sized by the tool radius R: sphere (radius R), stylus (length 24 R, "
                  "radius R, tip first) or disc (radius 4 R, thickness 2 R)")
      ->capture_default_str()
      ->check(CLI::IsMember({"sphere", "stylus", "disc"}));
  cmd->add_option("--tool-tilt", o->tilt_deg,
                  "Stylus and disc: the tool's axis against the ray, deg (its azimuth turns from ray to ray)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 89.0));
  cmd->add_option("--seed", o->seed, "Seed of the rays")->capture_default_str();
  cmd->add_flag("--no-plot", o->no_plot, "Skip the figure (matplotlib)");
  add_object_option(*cmd, o->objects);
  add_force_options(*cmd, o->force);
  add_execution_options(*cmd, o->exec, /*simulated=*/true);
  cmd->callback([o] { run_seen_felt_command(*o); });
}

}  // namespace gshaptics::cli
