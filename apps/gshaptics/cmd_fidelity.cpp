// `gshaptics synth SHAPE OUT.ply` (a ground-truth 3DGS scene) and `gshaptics fidelity` (the
// haptic fidelity benchmark on such scenes): thin CLIs over gshaptics/fidelity.

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <filesystem>
#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/fidelity/fidelity_run.h"

namespace gshaptics::cli {

void register_synth(CLI::App& app) {
  struct Options {
    std::string shape, out;
    SynthParams params;
  };
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "synth",
      "Write a ground-truth 3DGS scene: Gaussians on an analytic surface (metres) the way 3DGS "
      "optimisation leaves them (flat discs tangent to the surface, log-normal sizes around the "
      "spacing, jittered along the normal and in tilt, a share below the 0.2 opacity filter, a few "
      "floaters). INRIA PLY with every parameter in its header comments, plus OUT.json with the "
      "exact surface. Shapes: plane, sphere, cube, plate-2mm, plate-5mm, cylinder, corner-90, "
      "v-groove-60.");
  cmd->add_option("shape", o->shape, "Shape name")->required();
  cmd->add_option("out", o->out, "Output .ply (and OUT.ply.json)")->required();
  SynthParams& p = o->params;
  cmd->add_option("--spacing", p.spacing, "Gaussian spacing on the surface, m")->capture_default_str()
      ->check(check::range(5e-4, 0.05));
  cmd->add_option("--seed", p.seed, "Random seed")->capture_default_str();
  cmd->add_option("--normal-jitter", p.normal_jitter, "Std of the position along the normal, m")
      ->capture_default_str()->check(check::range(0.0, 0.05));
  cmd->add_option("--tilt", p.tilt_deg, "Std of the disc tilt, degrees")->capture_default_str()->check(check::range(0.0, 45.0));
  cmd->add_option("--low-opacity-share", p.low_opacity_share, "Share with opacity below 0.2")
      ->capture_default_str()->check(check::range(0.0, 1.0));
  cmd->add_option("--floater-share", p.floater_share, "Floaters per surface Gaussian")
      ->capture_default_str()->check(check::range(0.0, 1.0));
  cmd->callback([o] {
    const ShapeKind kind = parse_shape(o->shape, "synth");
    if (std::filesystem::path(o->out).extension() != ".ply")
      throw InputError("synth: " + o->out + ": the output must be a .ply file");
    const SyntheticScene s = make_synthetic_scene(AnalyticShape(kind), o->params);
    write_synthetic_scene(o->out, s);
    fmt::print("wrote      {} ({} Gaussians on the surface, {} floaters, spacing {:g} mm, seed {})\n"
               "surface    {}.json\n",
               o->out, s.surface_count, s.floater_count, o->params.spacing * 1e3, o->params.seed, o->out);
  });
}

void register_fidelity(CLI::App& app) {
  struct Options {
    bool quick = false, no_plot = false;
    std::string out = "bench/FIDELITY.md";
    std::string data_dir;
    std::string scene_dir = "runs/fidelity/scenes";
    std::uint64_t seed = 1;
    std::vector<std::string> shapes;
    std::vector<double> spacings_mm;
    int wrench_sites = -1;
    std::string stylus = "stylus:0.12,0.005", disc = "disc:0.02,0.004";
    ForceModelOptions force;
    ExecutionOptions exec;
    PassivityParams passivity;
    SynthParams synth;
  };
  auto o = std::make_shared<Options>();
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
  cmd->add_option("--data-dir", o->data_dir, "Curves (CSV) and figures (default: beside --out, in fidelity/)");
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
  cmd->add_option("--floater-share", o->synth.floater_share, "Floaters per surface Gaussian in the scenes")
      ->capture_default_str()->check(check::range(0.0, 1.0));
  add_force_options(*cmd, o->force);
  add_execution_options(*cmd, o->exec, /*simulated=*/true);
  add_passivity_option(*cmd, o->passivity);
  cmd->callback([o] {
    FidelityOptions fo = o->quick ? quick_fidelity_options() : FidelityOptions{};
    fo.renderer = o->force.spec();
    fo.play.safety.f_max = o->force.f_max;
    fo.play.safety.passivity = o->passivity;
    fo.seed = o->seed;
    fo.synth = o->synth;
    if (!o->shapes.empty()) {
      fo.shapes.clear();
      for (const std::string& name : o->shapes) fo.shapes.push_back(parse_shape(name, "--shape"));
    }
    if (!o->spacings_mm.empty()) {
      fo.spacings.clear();
      for (double mm : o->spacings_mm) fo.spacings.push_back(mm * 1e-3);
    }
    if (o->wrench_sites == 0) fo.wrench = false;
    if (o->wrench_sites > 0) fo.wrench_sites = o->wrench_sites;
    fo.wrench_tools.stylus = parse_tool_spec(o->stylus);
    fo.wrench_tools.disc = parse_tool_spec(o->disc);
    fo.play.inline_query = o->exec.inline_query;
    fo.play.latency_ticks = o->exec.latency_ticks;
    const std::filesystem::path out(o->out);
    if (out.extension() != ".md") throw InputError("fidelity: --out " + o->out + ": expected a .md file");
    const std::string data_dir =
        o->data_dir.empty() ? (out.parent_path().empty() ? std::filesystem::path("fidelity") : out.parent_path() / "fidelity").string()
                            : o->data_dir;
    fo.scene_dir = o->scene_dir;
    if (!out.parent_path().empty()) std::filesystem::create_directories(out.parent_path());
    const FidelityReport rep = run_fidelity(fo, [](const std::string& line) {
      fmt::print(stderr, "fidelity   {}\n", line);
    });
    write_fidelity_data(rep, data_dir);
    std::string command = "gshaptics fidelity --force-model " + std::string(renderer_name(o->force.model)) + (o->quick ? " --quick" : "") +
                          (o->exec.inline_query != RuntimeConfig{}.inline_query
                               ? std::string(o->exec.inline_query ? " --inline" : " --decoupled")
                               : std::string()) +
                          (o->exec.latency_ticks != 1 ? fmt::format(" --latency {}", o->exec.latency_ticks) : std::string()) +
                          (o->shapes.empty() ? std::string() : " --shape " + fmt::format("{}", fmt::join(o->shapes, ","))) +
                          (o->spacings_mm.empty() ? std::string() : fmt::format(" --spacing {}", fmt::join(o->spacings_mm, ","))) +
                          (o->wrench_sites >= 0 ? fmt::format(" --wrench-sites {}", o->wrench_sites) : std::string()) +
                          (o->synth.floater_share != SynthParams{}.floater_share
                               ? fmt::format(" --floater-share {:g}", o->synth.floater_share)
                               : std::string());
    std::string prefix;
    if (!o->no_plot) {
      const std::string script = find_tool_script("plot_fidelity.py");
      const std::filesystem::path rel = std::filesystem::relative(data_dir, out.parent_path().empty() ? "." : out.parent_path());
      if (run_python(script, {data_dir, data_dir, std::string(renderer_name(o->force.model))}, "fidelity")) prefix = rel.string() + "/fidelity_";
    }
    write_fidelity_markdown(rep, o->out, command, prefix);
    fmt::print("fidelity   {} ticks in {:.0f} s; report {}; curves in {}\n", rep.ticks, rep.seconds, o->out, data_dir);
  });
}

}  // namespace gshaptics::cli
