#pragma once
/// @file
/// The haptic fidelity benchmark: ground-truth scenes (AnalyticShape + make_synthetic_scene) at
/// several Gaussian densities, scripted presses, slides and push-throughs with sphere tools,
/// and the force a chosen renderer gives, judged against the analytic surface (interaction.h).
/// `gshaptics fidelity` is a thin CLI over run_fidelity() and the writers below.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "gshaptics/fidelity/interaction.h"
#include "gshaptics/fidelity/material_fidelity.h"
#include "gshaptics/fidelity/texture_fidelity.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/fidelity/wrench_fidelity.h"
#include "gshaptics/force/renderer_spec.h"

namespace gshaptics {

/// The runtime's default execution mode and safety layer (RuntimeConfig{}), as PlayOptions.
[[nodiscard]] PlayOptions default_play_options();
/// "inline" or "decoupled, N tick(s) latency".
[[nodiscard]] std::string describe_mode(const PlayOptions& play);

/// The matrix to run. Lengths in metres.
struct FidelityOptions {
  RendererSpec renderer;               ///< the force renderer and its parameters (default: the proxy)
  std::vector<ShapeKind> shapes = all_shapes();
  std::vector<double> spacings = {0.002, 0.004, 0.008};  ///< Gaussian spacings (densities)
  std::vector<double> tool_radii = {0.005, 0.010};
  int press_sites = 20;       ///< per shape
  int push_sites = 5;         ///< per plate / cube
  double press_depth = 0.010;
  double push_depth = 0.030;
  std::uint64_t seed = 1;     ///< scenes and sites
  SynthParams synth;          ///< how the scenes are drawn (spacing and seed are set per scene)
  double rate_hz = kDefaultServoRateHz;
  std::string scene_dir;      ///< where the generated scenes are written (and reused); required
  /// How the servo step runs (SimulatedRuntime, as a real-time run): the mode every metric is
  /// measured in. Default: the runtime's default mode.
  PlayOptions play = default_play_options();
  /// Also play every press in the other execution mode and report its energy W (the decoupled
  /// worker's force age shows there).
  bool compare_modes = true;
  /// The 6-DoF cases (wrench_fidelity.h) on the plane and the cube, when those shapes are in
  /// `shapes`: compound tools pressed `wrench_depth` deep at `wrench_sites` sites per case.
  bool wrench = true;
  int wrench_sites = 3;
  double wrench_depth = 0.005;
  WrenchTools wrench_tools;
  /// Capture defects (capture_defect.h, issue 71 item 5): each patch on the plane at every
  /// spacing, pressed `press_depth` deep with every tool radius at its centre and at
  /// `defect_sites - 1` points half its radius out. Empty: none.
  std::vector<CaptureDefect> defects = default_capture_defects();
  int defect_sites = 5;
  /// Materials (material_fidelity.h, issue 74): the plane with two materials side by side at every
  /// spacing and tool radius, `material_presses` presses per side and a slide across the border,
  /// when the plane is in `shapes` and the renderer is the proxy on the ellipsoids (the only one
  /// that reads materials yet).
  bool materials = true;
  int material_presses = 4;
  /// Texture (texture_fidelity.h, issue 74): every grating of `grating_wavelengths` x
  /// `grating_amplitudes` and the plane without relief, dragged at each of `drag_speeds` with every
  /// tool radius, when the plane is in `shapes` and the renderer reads materials. Empty: none.
  std::vector<double> grating_wavelengths = {0.001, 0.002, 0.004};  ///< m
  std::vector<double> grating_amplitudes = {0.00005, 0.0001, 0.0002};  ///< m
  std::vector<double> drag_speeds = {0.02, 0.05, 0.1};  ///< m/s
};

/// The CI subset: 4 mm spacing, 5 mm tool, 4 press sites, 2 push sites, 1 site per 6-DoF case;
/// plane, sphere, cube, 2 mm plate; 2 sites per defect.
[[nodiscard]] FidelityOptions quick_fidelity_options();

/// One row of a table: a shape (and feature) at one density and tool radius.
struct FidelityRow {
  std::string shape, feature;  ///< feature: face / edge / corner / concave (presses), path (slides)
  double spacing = 0, tool_radius = 0;  ///< m
  int runs = 0;                         ///< sites or slides
  // presses and push-throughs
  double onset_mm_median = NAN, onset_mm_max = NAN;
  double stiffness_median = NAN;       ///< N/mm
  double hold_through_min_mm = NAN;
  int never_lost = 0;                  ///< runs that held to the deepest point
  double energy_min_j = NAN;
  int active_cycles = 0;               ///< runs with W < 0
  double energy_other_min_j = NAN;     ///< the same presses in the other execution mode
  int active_cycles_other = 0;
  // slides
  double force_rsd = NAN, tangential_over_normal = NAN, mean_force = NAN;
  double lost_share_max = NAN;  ///< slides: the largest SlideMetrics::lost_share of the runs
  double step_max = NAN;        ///< slides: the largest SlideMetrics::largest_step of the runs, N
  // all
  double dir_p50 = NAN, dir_p95 = NAN, dir_max = NAN;  ///< degrees, ticks with |F| >= 0.1 N
  double shallow_dir_p95 = NAN;  ///< presses: p95 over ticks with |F| >= 0.1 N and delta <= 2 mm
  double tick_p50_us = NAN, tick_p99_us = NAN;
};

/// One row of the 6-DoF table: a case at one density.
struct WrenchRow {
  std::string name, shape;
  double spacing = 0;  ///< m
  int runs = 0, never_lost = 0, active_cycles = 0;
  double stiffness_median = NAN;  ///< N/mm
  double energy_min_j = NAN;
  double force_dir_p95 = NAN;     ///< deg, against the analytic contact normal
  double torque_dir_p50 = NAN, torque_dir_p95 = NAN;  ///< deg
  double torque_ratio_p5 = NAN, torque_ratio_p50 = NAN, torque_ratio_p95 = NAN;  ///< |tau| / |tau*|
  double analytic_lever_mm = NAN;  ///< median |tau*| / |F|
  double zero_lever_p95_mm = NAN;  ///< cases whose analytic torque is zero: |tau| / |F|, p95
  double deepest_part_mm = NAN;    ///< the proxy's deepest part past the true surface (max; NaN: no proxy)
  double tick_p99_us = NAN;
};

/// A curve for the figures: x (delta or path, mm) against force components (N).
struct FidelityCurve {
  std::string scenario, shape;
  double spacing = 0, tool_radius = 0;
  std::vector<double> x_mm, force, f_normal;
};

struct FidelityReport {
  FidelityOptions options;
  std::vector<FidelityRow> press, push, slide;
  /// The capture defect rows: shape "plane", feature "none" (the plane without a defect at the same
  /// sites, per spacing and tool) or the patch ("hole, 4 mm").
  std::vector<FidelityRow> defect;
  std::vector<WrenchRow> wrench;
  std::vector<MaterialRow> material;  ///< the two-material plane's sides
  std::vector<TextureRow> texture;    ///< the gratings' drags
  std::vector<FidelityCurve> curves;
  /// Pooled press direction errors per shape (degrees), for the histogram.
  std::vector<std::pair<std::string, std::vector<double>>> press_directions;
  double seconds = 0;  ///< wall time of the whole run
  std::size_t ticks = 0;
};

/// Progress: a line of what is running now. May be empty.
using FidelityProgressFn = std::function<void(const std::string&)>;

/// Generates (or reuses, when the sidecar matches) every scene, loads it through load_scene,
/// builds its world with the default WorldConfig, and plays every script through a fresh
/// renderer. Throws InputError for bad options or an unknown force model.
[[nodiscard]] FidelityReport run_fidelity(const FidelityOptions& options, const FidelityProgressFn& progress = {});

/// Writes the report as Markdown (one table per scenario, the stiffness ratio across densities,
/// the command that made it) to `path`, atomically.
void write_fidelity_markdown(const FidelityReport& report, const std::string& path, const std::string& command,
                             const std::string& figures_prefix);

/// Writes the curves and direction-error histograms (1-degree bins) as CSV files into `dir`
/// (press_curves.csv, slide_curves.csv, push_curves.csv, press_directions.csv), for
/// tools/plot_fidelity.py.
void write_fidelity_data(const FidelityReport& report, const std::string& dir);

}  // namespace gshaptics
