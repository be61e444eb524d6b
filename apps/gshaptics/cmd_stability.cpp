// `gshaptics stability`: the largest coupling stiffness a simulated device holds without
// oscillating, swept over control scheme, servo rate, round-trip delay and passivity (a thin CLI
// over fidelity/stability.h).

#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/session/report_session.h"

namespace gshaptics::cli {

void register_stability(CLI::App& app) {
  auto o = std::make_shared<StabilityCommandOptions>();
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
  cmd->add_option("--data-dir", o->data_dir, "CSV and figure (default: beside --out, in a folder named after it: stability/ for STABILITY.md)");
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
  cmd->add_option("--trace-stiffness", o->sweep.trace_stiffness,
                  "Keep the trials' traces at this stiffness, N/m (added to the sweep): stability_traces.csv and "
                  "a figure of the device and setpoint heights and the force, the control schemes side by side")
      ->check(check::positive());
  cmd->add_option("--duration", o->sweep.trial.duration, "Simulated time per trial, s")
      ->capture_default_str()->check(check::range(1.2, 60.0));
  cmd->add_option("--device-mass", o->sweep.impedance_device.mass, "Impedance device's moving mass, kg")
      ->capture_default_str()->check(check::positive());
  cmd->add_option("--device-damping", o->sweep.impedance_device.damping, "Impedance device's physical damping, N s/m")
      ->capture_default_str()->check(check::non_negative());
  cmd->add_option("--passivity-max-damping", o->sweep.passivity.max_damping,
                  "Cap on the passivity controller's damping when on, N s/m")
      ->capture_default_str()->check(check::non_negative());
  cmd->callback([o] { run_stability_command(*o); });
}

}  // namespace gshaptics::cli
