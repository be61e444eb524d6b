// `gshaptics stability`: the largest coupling stiffness a simulated device holds without
// oscillating, swept over control scheme, servo rate, round-trip delay and passivity (a thin CLI
// over fidelity/stability.h).

#include <fmt/format.h>

#include <filesystem>
#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/fidelity/stability.h"

namespace gshaptics::cli {

void register_stability(CLI::App& app) {
  struct Options {
    bool quick = false, no_plot = false;
    std::string out = "bench/STABILITY.md";
    std::string data_dir;
    std::string control = "both";
    std::vector<std::string> shapes;
    std::vector<double> stiffnesses, delays_ms, rates;
    StabilityOptions sweep;
  };
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "stability",
      "Find the stiffest wall each device holds still: a simulated impedance device (0.2 kg, "
      "2 N s/m, 10 um encoder) and a simulated admittance device (2 kg under a position servo) "
      "press the proxy onto a ground-truth Gaussian plane and 2 mm plate through the full servo "
      "step, with the coupling stiffness swept over each servo rate and round-trip delay, passivity "
      "off and on. Writes a Markdown table (largest stable stiffness against the Colgate-Schenkel "
      "prediction, energy generated, oscillation amplitude), the trials as CSV and a figure. --quick "
      "runs a small subset (CI).");
  cmd->add_flag("--quick", o->quick, "The plane, 1 kHz, 0 and 5 ms, five stiffnesses, 1.5 s trials");
  cmd->add_option("--out", o->out, "Markdown report")->capture_default_str();
  cmd->add_option("--data-dir", o->data_dir, "CSV and figure (default: beside --out, in stability/)");
  cmd->add_flag("--no-plot", o->no_plot, "Skip the figure (matplotlib)");
  cmd->add_option("--control", o->control, "impedance, admittance or both")
      ->capture_default_str()->check(CLI::IsMember({"impedance", "admittance", "both"}));
  cmd->add_option("--shape", o->shapes, "Scenes: plane, plate-2mm, plate-5mm (repeatable; default plane and plate-2mm)");
  cmd->add_option("--stiffness", o->stiffnesses, "Coupling stiffnesses to sweep, N/m (repeatable)")
      ->check(check::positive());
  cmd->add_option("--delay", o->delays_ms, "Round-trip delays, ms, half each way (repeatable; default 0 2 5)")
      ->check(check::range(0.0, 500.0));
  cmd->add_option("--rate", o->rates, "Servo rates, Hz (repeatable; default 500 1000)")->check(check::range(1.0, 10000.0));
  cmd->add_option("--push", o->sweep.push, "The hand's push onto the surface, N")->capture_default_str()->check(check::positive());
  cmd->add_option("--duration", o->sweep.trial.duration, "Simulated time per trial, s")
      ->capture_default_str()->check(check::range(1.2, 60.0));
  cmd->add_option("--device-mass", o->sweep.impedance_device.mass, "Impedance device's moving mass, kg")
      ->capture_default_str()->check(check::positive());
  cmd->add_option("--device-damping", o->sweep.impedance_device.damping, "Impedance device's physical damping, N s/m")
      ->capture_default_str()->check(check::non_negative());
  cmd->add_option("--passivity-max-damping", o->sweep.passivity.max_damping,
                  "Cap on the passivity controller's damping when on, N s/m")
      ->capture_default_str()->check(check::non_negative());
  cmd->callback([o] {
    StabilityOptions so = o->quick ? quick_stability_options() : StabilityOptions{};
    const StabilityOptions& given = o->sweep;
    so.push = given.push;
    if (!o->quick || given.trial.duration != StabilityOptions{}.trial.duration) so.trial.duration = given.trial.duration;
    so.impedance_device.mass = given.impedance_device.mass;
    so.impedance_device.damping = given.impedance_device.damping;
    so.passivity.max_damping = given.passivity.max_damping;
    if (!o->shapes.empty()) {
      so.shapes.clear();
      for (const std::string& s : o->shapes) so.shapes.push_back(parse_shape(s, "stability"));
    }
    if (!o->stiffnesses.empty()) so.stiffnesses = o->stiffnesses;
    if (!o->delays_ms.empty()) {
      so.delays.clear();
      for (double d : o->delays_ms) so.delays.push_back(d * 1e-3);
    }
    if (!o->rates.empty()) so.rates = o->rates;
    if (o->control == "impedance") so.controls = {ControlMode::kImpedance};
    if (o->control == "admittance") so.controls = {ControlMode::kAdmittance};
    const std::filesystem::path out(o->out);
    if (out.extension() != ".md") throw InputError("stability: --out " + o->out + ": expected a .md file");
    const std::filesystem::path parent = out.parent_path().empty() ? std::filesystem::path(".") : out.parent_path();
    const std::string data_dir = o->data_dir.empty() ? (parent / "stability").string() : o->data_dir;
    const StabilityReport rep = run_stability(so, [](const std::string& line) { fmt::print(stderr, "stability  {}\n", line); });
    std::filesystem::create_directories(data_dir);
    const std::string csv = (std::filesystem::path(data_dir) / "stability_trials.csv").string();
    write_stability_csv(rep, csv);
    std::string figure;
    if (!o->no_plot) {
      const std::string png = (std::filesystem::path(data_dir) / "stability.png").string();
      if (run_python(find_tool_script("plot_stability.py"), {csv, png}, "stability"))
        figure = std::filesystem::relative(png, parent).string();
    }
    const std::string command = "gshaptics stability" + std::string(o->quick ? " --quick" : "") +
                                (o->control != "both" ? " --control " + o->control : std::string());
    write_stability_markdown(rep, o->out, command, figure);
    for (const StabilityRow& r : rep.rows)
      fmt::print("{:<9} {:<10} {:>5g} Hz {:>4g} ms  passivity {:<3}  largest stable {}{:g} N/m{}\n", r.shape,
                 control_mode_name(r.control), r.rate_hz, r.delay * 1e3, r.passivity ? "on" : "off",
                 r.all_stable ? ">= " : "", r.largest_stable,
                 r.predicted > 0 ? fmt::format(" (predicted {:.0f})", r.predicted) : std::string());
    fmt::print("stability  {} trials, {} ticks in {:.1f} s; report {}; trials {}\n", rep.trials.size(), rep.ticks,
               rep.seconds, o->out, csv);
  });
}

}  // namespace gshaptics::cli
