#pragma once
/// @file
/// Scripted interactions of the fidelity benchmark, played by an ideal position-controlled
/// device (it follows the script exactly; the commanded force is recorded, not applied) through
/// the servo step of a real-time run (SimulatedRuntime: safety layer and execution mode
/// included), and the metrics that judge the commanded force against the analytic surface.
///
/// Penetration delta: how far the tool's surface is past the true surface. For a sphere tool of
/// radius r whose centre is at distance s from the surface along the site's outward normal,
/// delta = r - s (at concave sites s is the signed distance, which is what the faces see).

#include <Eigen/Core>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/fidelity/analytic_shape.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/device/haptic_device.h"
#include "gshaptics/device/scripted_device.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/servo/safety.h"

namespace gshaptics {

enum class Scenario { kPress, kSlide, kPushThrough };
[[nodiscard]] std::string_view to_string(Scenario s);

/// One tick of a script. World frame, SI units.
struct ScriptTick {
  double time = 0;                                     ///< s
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< tool centre, m
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< m/s
  /// Tool frame -> world (compound tools; the scripts here hold it fixed, angular velocity 0).
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  double delta = 0;                                    ///< penetration, m (> 0: past the surface)
  double path = 0;                                     ///< slides: distance along the surface, m
  bool measured = false;  ///< part of the scored stretch (slides: the constant-delta middle)
  bool loading = false;   ///< moving into the surface (presses)
};

/// A whole interaction: where, how, and every tick.
struct Script {
  Scenario scenario = Scenario::kPress;
  ContactSite site;           ///< press / push-through: where; slides: the start
  double tool_radius = 0.005;  ///< m, the sphere tool (when `tool` has no parts)
  CompoundTool tool;           ///< a compound tool (count > 0) instead of the sphere
  double max_delta = 0.01;     ///< deepest penetration the script reaches, m
  std::vector<ScriptTick> ticks;
};

/// Press: from 2 cm outside along the site normal at `speed` to `depth` past the surface, hold
/// `hold` s, retract the same way (a closed cycle). Push-through is the same with depth 3 cm.
[[nodiscard]] Script press_script(const AnalyticShape& shape, const ContactSite& site, double tool_radius,
                                  double depth, double rate_hz, double speed = 0.02, double hold = 0.5,
                                  double start_off = 0.02);

/// Slide: press to `delta` at 2 cm/s, slide `length` m along the surface at `speed` keeping
/// delta constant, retract. Plane: a straight line; cube: 5 cm on the top face, around the edge,
/// 5 cm down the side; sphere: a great-circle arc; corner-90: 5 cm along the floor into the wall,
/// then 5 cm up the wall. Throws InputError for other shapes.
[[nodiscard]] Script slide_script(const AnalyticShape& shape, double tool_radius, double rate_hz,
                                  double delta = 0.002, double length = 0.1, double speed = 0.05);

/// What the servo commanded on each tick of a script.
struct ScriptTrace {
  std::vector<Eigen::Vector3d> force;  ///< commanded force (after the safety layer), N
  std::vector<Eigen::Vector3d> torque; ///< commanded torque about the TCP (after the safety layer), N m
  std::vector<Eigen::Vector3d> proxy;  ///< where the renderer held the tool's TCP (the device's for the paper), m
  std::vector<float> render_us;        ///< wall time of the render the tick used, microseconds
  std::vector<std::uint32_t> contacts;
};

/// How a script is played: the servo's execution mode and safety layer (as a real-time run).
struct PlayOptions {
  bool inline_query = kDefaultInlineQuery;  ///< query inside the tick; false: the decoupled worker
  int latency_ticks = 1;     ///< decoupled mode: ticks from a pose to its result (>= 1)
  SafetyParams safety;  ///< the safety layer, F_max included
};

/// Plays `script` through `renderer` (reset first) on a ScriptedDevice in a SimulatedRuntime:
/// one servo tick per script tick. Throws InputError for an empty script.
[[nodiscard]] ScriptTrace play_script(ForceRenderer& renderer, const Script& script, double rate_hz,
                                      const PlayOptions& options = {});

/// Metrics of one press or push-through.
struct PressMetrics {
  double onset_mm = NAN;        ///< delta at which |F| first exceeds 0.1 N (NaN: never)
  double stiffness_n_per_mm = NAN;  ///< slope of |F| over delta in [1, 5] mm while loading
  double hold_through_mm = 0;   ///< largest delta the force stays outward and >= 10 % of its peak so far
  bool never_lost = false;      ///< it held to the script's deepest point (within 0.1 mm)
  double peak_force = 0;        ///< N
  double energy_j = 0;          ///< W = -sum F . v dt over the closed cycle (< 0: not passive); v dt is
                                ///< each tick's displacement, F the mean of its two ends
  std::vector<double> direction_deg;  ///< per tick with |F| >= 0.1 N: angle to the normal cone
  std::vector<double> shallow_direction_deg;  ///< the same over ticks with delta <= 2 mm
};
[[nodiscard]] PressMetrics press_metrics(const AnalyticShape& shape, const Script& script, const ScriptTrace& trace);

/// Metrics of one slide (over its measured ticks).
struct SlideMetrics {
  double mean_force = 0;        ///< N
  double force_rsd = NAN;       ///< relative standard deviation of |F|
  double tangential_over_normal = NAN;  ///< mean |F_t| / mean F_n (true normal: grad of the distance)
  /// Share of the measured ticks (0 to 1) with |F| below kOnsetForce: the tool is delta past the
  /// surface all along the scored stretch, so any of them is a tick the surface was lost (the
  /// direction error is not scored there, so it cannot show them).
  double lost_share = NAN;
  /// The largest change of the force (N) from one tick to the next over the scored stretch: at a
  /// constant delta and speed a rigid surface's force turns and grows smoothly, so a step is the
  /// renderer's (a contact handed from one face to another in one tick).
  double largest_step = NAN;
  std::vector<double> direction_deg;
};
[[nodiscard]] SlideMetrics slide_metrics(const AnalyticShape& shape, const Script& script, const ScriptTrace& trace);

/// Unit gradient of the shape's signed distance at `p` (central differences): the true contact
/// normal of a sphere tool centred at `p`.
[[nodiscard]] Eigen::Vector3d distance_gradient(const AnalyticShape& shape, const Eigen::Vector3d& p);

}  // namespace gshaptics
