// `gshaptics fidelity`: the haptic fidelity benchmark on ground-truth scenes (a thin CLI over
// session/report_session.h).

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <filesystem>
#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/fidelity/fidelity_run.h"
#include "gshaptics/session/report_session.h"

namespace gshaptics::cli {

void register_fidelity(CLI::App& app) {
  auto o = std::make_shared<FidelityCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "fidelity",
      "Measure the rendered force against analytic ground truth: ground-truth scenes of eight "
      "shapes at 2, 4 and 8 mm Gaussian spacing, presses at 20 sites (cube edges and corners "
      "included), slides and push-throughs with 5 and 10 mm sphere tools, played by an ideal "
      "position-controlled device at 1 kHz through the runtime's servo step (safety layer and "
      "execution mode included; every press also in the other mode for its energy W). Writes a Markdown report with one table per scenario "
      "(onset, direction error, stiffness and its ratio across densities, hold-through, energy, "
      "tick cost) and figures. --quick runs a small subset (CI).");
  cmd->add_flag("--quick", o->quick, "One density, one tool, 4 sites, 4 shapes");
  cmd->add_option("--out", o->out, "Markdown report")->capture_default_str();
  cmd->add_option("--data-dir", o->data_dir, "Curves (CSV) and figures (default: beside --out, in a folder named after it: fidelity/ for FIDELITY.md)");
  cmd->add_option("--scene-dir", o->scene_dir, "Where the generated scenes are written and reused")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of the scenes and sites")->capture_default_str();
  cmd->add_flag("--no-plot", o->no_plot, "Skip the figures (matplotlib)");
  cmd->add_option("--shape", o->shapes,
                  "Only these shapes (repeat or comma-separate): plane, sphere, cube, plate-2mm, plate-5mm, cylinder, "
                  "corner-90, v-groove-60")
      ->delimiter(',');
  cmd->add_option("--spacing", o->spacings_mm, "Only these Gaussian spacings, mm (repeat or comma-separate)")
      ->delimiter(',')
      ->check(check::range(0.5, 50.0));
  cmd->add_option("--wrench-sites", o->wrench_sites,
                  "6-DoF cases (compound tools, torque; on the plane and the cube): sites per case, 0 to skip "
                  "(default 3, --quick 1)")
      ->check(check::range(0, 100));
  cmd->add_option("--stylus", o->stylus, "6-DoF cases: the stylus (a --tool spec)")->capture_default_str();
  cmd->add_option("--disc", o->disc, "6-DoF cases: the disc (a --tool spec)")->capture_default_str();
  cmd->add_option("--defect", o->defects,
                  "Capture defect patches on the plane, KIND[:RADIUS_MM] (faint-patch, hole, large-flat, "
                  "interior-clutter; repeat or comma-separate; 'none' to skip). Default: one of each")
      ->delimiter(',');
  cmd->add_option("--defect-sites", o->defect_sites, "Capture defects: press sites per patch (default 5, --quick 2)")
      ->check(check::range(1, 100));
  cmd->add_option("--floater-share", o->synth.floater_share, "Floaters per surface Gaussian in the scenes")
      ->capture_default_str()->check(check::range(0.0, 1.0));
  cmd->add_option("--edge-sigmas", o->synth.edge_sigmas,
                  fmt::format("Scenes with crisp convex edges: discs near the cube's edges narrowed to this many "
                              "standard deviations within them (gshaptics synth --edge-sigmas; {} suggested); 0: sized "
                              "alike, as the reports",
                              SynthParams::kCrispEdgeSigmas))
      ->capture_default_str()->check(check::range(0.0, SynthParams::kMaxEdgeSigmas));
  add_force_options(*cmd, o->force);
  add_execution_options(*cmd, o->exec, /*simulated=*/true);
  add_passivity_option(*cmd, o->passivity);
  cmd->callback([o] { run_fidelity_command(*o); });
}

}  // namespace gshaptics::cli
