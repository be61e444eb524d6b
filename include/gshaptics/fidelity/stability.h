#pragma once
/// @file
/// Stability trials: a simulated device held against a wall through the full servo step
/// (SimulatedRuntime: the same safety layer, passivity controller and execution mode as a live
/// run), and whether the contact settles or oscillates. `gshaptics stability` sweeps them; the
/// device-model validation (tests/stability_test.cpp) bisects them for the limit stiffness.
///
/// A trial: the device starts `start_gap` above the wall (the plane z = 0 of the world, normal +z)
/// with the hand pushing it down (HandImpedance::push), and runs for `duration`. The tool's
/// height along the normal, as the runtime read it, is cut into windows of `window` seconds after
/// `settle`; the amplitude of a window is half its peak-to-peak. The contact is stable when the
/// last window's amplitude is below `decay` times the first's (the oscillation dies out), or below
/// `rest_amplitude` (it is at rest). A growing oscillation and a limit cycle (bouncing) are
/// unstable.

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gshaptics/fidelity/analytic_shape.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/device/device_model.h"

namespace gshaptics {

/// How a trial is judged. Seconds and metres.
struct WallTrialOptions {
  double duration = 3.0;        ///< simulated time, s
  double settle = 0.5;          ///< the first windows start this late, s
  double window = 0.25;         ///< s
  double decay = 0.9;           ///< stable: last amplitude < decay * first amplitude
  double rest_amplitude = 2e-6; ///< or the last amplitude below this, m (at rest)
};

/// What a trial measured. Forces in N, lengths in m, energies in J.
struct WallTrialResult {
  bool stable = false;
  double first_amplitude = 0, last_amplitude = 0;  ///< m (half peak-to-peak of the height)
  double growth = 0;          ///< last / first amplitude (0 when both are 0)
  double mean_depth = 0;      ///< mean height below the wall over the last window, m (> 0: inside)
  double min_energy = 0;      ///< the passivity observer's lowest energy, J (< 0: active)
  double peak_force = 0;      ///< N, sent
  std::uint64_t passivity_ticks = 0;
  double peak_damping = 0;    ///< N s/m
  std::vector<double> time, height, force;  ///< per tick: s, m (along +z), N (z component sent)
  /// Per tick: the setpoint's height (admittance control: the virtual tool; else the device's), m,
  /// and the user's force along z as the device measured it, N.
  std::vector<double> setpoint, user_force;
};

/// Runs one trial: `device` (started and stopped by the runtime) driven by `renderer` with
/// `config` (its duration is replaced by options.duration). Throws what SimulatedRuntime throws.
[[nodiscard]] WallTrialResult run_wall_trial(HapticDevice& device, std::unique_ptr<ForceRenderer> renderer,
                                             RuntimeConfig config, const WallTrialOptions& options = {});

/// The sweep behind `gshaptics stability`: the proxy (its coupling stiffness swept) on a
/// ground-truth Gaussian scene, pressed by a simulated device through the full servo step, for
/// each control scheme, servo rate, round-trip delay and passivity off / on. SI units.
struct StabilityOptions {
  std::vector<ShapeKind> shapes = {ShapeKind::kPlane, ShapeKind::kPlate2mm};
  double spacing = 0.004;       ///< Gaussian spacing of the scenes, m
  double tool_radius = 0.005;   ///< sphere tool, m
  std::vector<double> stiffnesses = {250, 500, 1000, 2000, 4000, 8000, 16000, 32000, 64000, 128000, 256000,
                                     512000, 1024000};  ///< N/m
  std::vector<double> delays = {0, 0.002, 0.005};  ///< round trip, s (half each way)
  std::vector<double> rates = {500, 1000};         ///< servo rates, Hz
  std::vector<ControlMode> controls = {ControlMode::kImpedance, ControlMode::kAdmittance};
  /// The impedance-type device (a desktop stylus device: 0.2 kg, 2 N s/m, 10 um encoder).
  DeviceModelParams impedance_device = default_impedance_device();
  /// The admittance-type device (a HapticGiant-class robot: 2 kg under a 200 kN/m position servo).
  DeviceModelParams admittance_device = default_admittance_device();
  AdmittanceParams virtual_tool{1.0, 20.0};  ///< admittance control's virtual tool
  double push = 2.0;            ///< N, the hand pushes the tool onto the surface with it
  /// N/m: the hand's grip, anchored where the tool is put down (keeps it from sliding off sideways
  /// on the shaded normal's tilt; it also pulls back a little as the tool sinks)
  double hand_stiffness = 100.0;
  double proxy_damping = 1.0;   ///< the coupling's damping B, N s/m (ProxyParams::damping)
  /// The controller's settings when on; the cap is the desktop default on every row (impedance and
  /// admittance alike), so the rows compare control schemes under the same controller.
  PassivityParams passivity = [] {
    PassivityParams p;
    p.max_damping = kDefaultPassivityMaxDamping;
    return p;
  }();
  WallTrialOptions trial;
  /// The trials at this stiffness keep their traces (StabilityTrial::trace), N/m; 0: none do.
  double trace_stiffness = 0;
  std::uint64_t seed = 1;

  [[nodiscard]] static DeviceModelParams default_impedance_device();
  [[nodiscard]] static DeviceModelParams default_admittance_device();
};

/// The CI subset: the plane, 1 kHz, round trips 0 and 5 ms, five stiffnesses, 1.5 s trials.
[[nodiscard]] StabilityOptions quick_stability_options();

/// One configuration's verdict over the stiffness sweep.
struct StabilityRow {
  std::string shape;
  ControlMode control = ControlMode::kImpedance;
  double rate_hz = 0, delay = 0;  ///< Hz, s (round trip)
  bool passivity = false;
  /// The largest swept stiffness below which every swept one was stable, N/m (0: none was).
  double largest_stable = 0;
  bool all_stable = false;        ///< the whole sweep was stable
  /// Impedance rows: the plain sampled wall's limit on this device, b / (T/2 + d), N/m
  /// (Colgate and Schenkel 1997 with the delay added to the hold); 0 for admittance rows.
  double predicted = 0;
  /// At the first unstable stiffness (or the stiffest one when all were stable): the energy the
  /// environment generated (minus the observer's lowest energy, J), the last window's
  /// amplitude (m) and the peak force (N).
  double energy_generated = 0, amplitude = 0, peak_force = 0;
};

/// One trial of the sweep (for the figure).
struct StabilityTrial {
  std::string shape;
  ControlMode control = ControlMode::kImpedance;
  double rate_hz = 0, delay = 0, stiffness = 0;
  bool passivity = false;
  bool stable = false;
  double growth = 0, last_amplitude = 0, min_energy = 0, peak_force = 0;
  /// Per tick when the stiffness is StabilityOptions::trace_stiffness (else empty): time (s), the
  /// device's height and the setpoint's (m, along the wall's normal), the force sent (N, z).
  std::vector<double> time, height, setpoint, force;
};

struct StabilityReport {
  StabilityOptions options;
  std::vector<StabilityRow> rows;
  std::vector<StabilityTrial> trials;
  double seconds = 0;   ///< wall time of the sweep
  std::uint64_t ticks = 0;
};

using StabilityProgressFn = std::function<void(const std::string&)>;

/// Runs the sweep. Throws InputError for empty lists or non-positive values.
[[nodiscard]] StabilityReport run_stability(const StabilityOptions& options, const StabilityProgressFn& progress = {});

/// Writes the trials as CSV (for the figure) at `path`, atomically. Throws InputError naming it.
void write_stability_csv(const StabilityReport& report, const std::string& path);
/// Writes the traced trials (StabilityOptions::trace_stiffness) as CSV at `path`, atomically: shape,
/// control, rate_hz, delay_ms, passivity, stiffness, time_s, height_mm, setpoint_mm, force_n.
void write_stability_traces_csv(const StabilityReport& report, const std::string& path);
/// Writes the Markdown report (settings, the table, the figure when `figure` is not empty, the
/// traced trials' figure when `traces_figure` is not empty).
void write_stability_markdown(const StabilityReport& report, const std::string& path, const std::string& command,
                              const std::string& figure, const std::string& traces_figure = {});

/// Judges a height trace (s, m) as run_wall_trial does; fills stable, amplitudes and growth.
void judge_wall_trace(const std::vector<double>& time, const std::vector<double>& height,
                      const WallTrialOptions& options, WallTrialResult& result);

}  // namespace gshaptics
