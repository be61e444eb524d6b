#pragma once
/// @file
/// The session layer (see world_session.h), the benchmark reports: `gshaptics fidelity` and
/// `gshaptics stability` as library calls, and `gshaptics latency` (the machine's own gaps). Each takes the command's options as given, runs the
/// sweep (fidelity/fidelity_run.h, fidelity/stability.h), writes the data (CSV), the figure
/// (tools/plot_fidelity.py, tools/plot_stability.py) and the Markdown report that cites the
/// command line reproducing it, and prints a summary. The CLI only binds options to these structs.

#include <cstdint>
#include <string>
#include <vector>

#include "gshaptics/fidelity/fidelity_run.h"
#include "gshaptics/fidelity/seen_felt.h"
#include "gshaptics/fidelity/stability.h"
#include "gshaptics/session/probe_session.h"
#include "gshaptics/session/world_session.h"

namespace gshaptics::session {

/// Path of a script in tools/ (source tree) or share/gshaptics (installed), "" when absent.
std::string find_tool_script(const std::string& name);

/// Runs `script` with /usr/bin/python3 (or $GSHAPTICS_PYTHON) and `args`; false (with a message
/// naming `command`) when it fails. Throws InputError when `script` is "".
bool run_python(const std::string& script, const std::vector<std::string>& args, const std::string& command);


/// `gshaptics fidelity`: the options as on the command line.
struct FidelityCommandOptions {
  bool quick = false;     ///< quick_fidelity_options() (CI)
  bool no_plot = false;   ///< no figures
  std::string out = "bench/FIDELITY.md";         ///< the Markdown report (.md)
  std::string data_dir;                          ///< curves and figures; "": beside `out`, in a folder named after it (FIDELITY.md: fidelity/)
  std::string scene_dir = "runs/fidelity/scenes";  ///< where the generated scenes are written and reused
  std::uint64_t seed = FidelityOptions{}.seed;
  std::vector<std::string> shapes;     ///< shape names (parse_shape); empty: the run's default
  std::vector<double> spacings_mm;     ///< Gaussian spacings, mm; empty: the run's default
  int wrench_sites = -1;               ///< 6-DoF sites per case; 0: none; < 0: the run's default
  /// Capture defect patches (parse_capture_defect specs); empty: one of each kind; "none": no
  /// defect cases.
  std::vector<std::string> defects;
  int defect_sites = -1;               ///< press sites per patch; < 0: the run's default
  std::string stylus = "stylus:0.12,0.005", disc = "disc:0.02,0.004";  ///< the 6-DoF tools (--tool specs)
  ForceModelOptions force;
  ExecutionOptions exec;
  PassivityParams passivity;
  SynthParams synth;                   ///< the scenes' floater share (the rest is set per scene)
};

/// The sweep `o` asks for (shapes, spacings, tools, mode, passivity). Throws InputError for an
/// unknown shape or a bad tool spec.
[[nodiscard]] FidelityOptions fidelity_options_from(const FidelityCommandOptions& o);
/// The command line that reproduces `o`'s report (cited in it).
[[nodiscard]] std::string fidelity_command_line(const FidelityCommandOptions& o);
/// Runs the fidelity benchmark and writes its report, curves and figures (a figure that fails is
/// reported on stderr and left out of the report). Throws InputError for bad options (`out` not a
/// .md file, ...).
void run_fidelity_command(const FidelityCommandOptions& o);

/// `gshaptics seen-felt`: the options as on the command line.
struct SeenFeltCommandOptions {
  std::vector<std::string> scenes;  ///< scene files; empty: every shared scene found (seen_felt_default_scenes())
  bool quick = false;               ///< quick_seen_felt_options() (CI)
  bool no_plot = false;
  std::string out = "bench/SEEN_FELT.md";  ///< the Markdown report (.md)
  std::string data_dir;                    ///< rays (CSV) and figure; "": beside `out`, in a folder named
                                           ///< after it in lower case (SEEN_FELT.md: seen_felt/)
  int rays = 0;                            ///< per configuration; 0: the run's default
  std::vector<double> tools_percent;       ///< tool radii, % of the extent; empty: the run's default
  std::vector<std::string> directions;     ///< vertical, around; empty: both
  std::string tool = "sphere";             ///< --tool-shape: sphere, stylus, disc (parse_seen_felt_tool)
  double tilt_deg = SeenFeltOptions{}.tilt_deg;  ///< --tool-tilt, deg (stylus, disc)
  std::uint64_t seed = SeenFeltOptions{}.seed;
  ForceModelOptions force;
  ExecutionOptions exec;
  /// --object and --support: rigid objects of the one scene given (SceneOptions::objects and
  /// supports; the rest unused). With objects, the rays are aimed at their boxes, the force
  /// renderer is the objects' (ObjectRenderer over the static part and MuJoCo), and the seen
  /// truth is the file as captured: does an object at rest feel where it shows?
  SceneOptions objects;
};

/// The shared real scenes the benchmark runs on by default: the ten object and room captures of
/// ../shared/data/scenes (the aerial crop left out: its tool would be metres wide), those found
/// beside the project or under $GSHAPTICS_SCENES.
[[nodiscard]] std::vector<std::string> seen_felt_default_scenes();
/// The measurement `o` asks for. Throws InputError for an unknown direction or tool.
[[nodiscard]] SeenFeltOptions seen_felt_options_from(const SeenFeltCommandOptions& o);
/// Runs the benchmark and writes its report, rays (CSV) and figure. Throws InputError for bad
/// options or a scene that does not load.
void run_seen_felt_command(const SeenFeltCommandOptions& o);

/// `gshaptics stability`: the options as on the command line.
struct StabilityCommandOptions {
  bool quick = false, no_plot = false;
  std::string out = "bench/STABILITY.md";  ///< the Markdown report (.md)
  std::string data_dir;                    ///< CSV and figure; "": beside `out`, in a folder named after it (STABILITY.md: stability/)
  std::string control = "both";            ///< impedance, admittance or both
  std::vector<std::string> shapes;         ///< empty: the sweep's default
  std::vector<double> stiffnesses, delays_ms, rates;  ///< N/m, ms, Hz; empty: the sweep's default
  StabilityOptions sweep;  ///< push, trial duration, device mass and damping, passivity cap as given
};

/// The sweep `o` asks for. Throws InputError for an unknown shape.
[[nodiscard]] StabilityOptions stability_options_from(const StabilityCommandOptions& o);
/// Runs the stability sweep and writes its report, trials (CSV) and figure (a figure that fails is
/// reported on stderr and left out of the report). Throws InputError for bad options.
void run_stability_command(const StabilityCommandOptions& o);

/// `gshaptics latency`: the options as on the command line.
struct LatencyCommandOptions {
  double seconds = 2.0;        ///< how long to spin, s
  int cpu = -1;                ///< -1: the last CPU (where `run` pins the servo thread)
  int priority = 0;            ///< SCHED_FIFO priority (0: normal scheduling)
  double threshold_us = 5.0;   ///< shortest gap counted, us
  bool json = false;           ///< one JSON object instead of the text
};
/// Spins on the clock on one CPU (measure_interruptions, servo/interruptions.h) and prints the
/// gaps' profile and what it means for a 1 kHz tick. Throws InputError for a CPU the machine
/// does not have; a refused pinning or priority is warned about and measured anyway.
void run_latency_command(const LatencyCommandOptions& o);

}  // namespace gshaptics::session
