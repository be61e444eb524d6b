#pragma once
/// @file
/// The push scenario of `gshaptics simulate --scenario push` (issue 72): a simulated hand pushes
/// a box of Gaussians across a floor of Gaussians through the servo step (SimulatedDevice,
/// SimulatedRuntime: safety layer, execution mode), with the box's dynamics on MuJoCo. Every
/// tick records the hand, the device, the box's pose and the coupling force on it, and whether
/// the tool at the box's proxy overlaps the box, so the run can be held against the analytic
/// answer: once the box slides, the push less m a is the friction mu m g.

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/servo/runtime_stats.h"

namespace gshaptics {

/// The scenario's settings. Metres, kilograms, seconds; the world is z-up, the floor's top at z = 0.
struct PushScenario {
  Eigen::Vector3d box_half = Eigen::Vector3d(0.05, 0.04, 0.03);  ///< the box's half extents
  double mass = 0.4;                                              ///< kg
  double friction = 0.3;                                          ///< mu against the floor
  double spacing = 0.01;     ///< Gaussian spacing of the box's faces and the floor
  double tool_radius = 0.01;  ///< the spherical tool
  /// The hand's path at mid-height of the box: at x = start for `hold` s, to x = end by `duration`
  /// (minimum jerk), then back by `release` m over `release_time` s, letting the box go.
  double start = -0.12, end = 0.15, hold = 0.5, duration = 3.0;
  double release = 0.1, release_time = 0.5;
  RuntimeConfig runtime;  ///< rate, renderer, execution mode, safety (duration and tool are set here)
};

/// One tick of the run (world frame).
struct PushSample {
  double t = 0;                                             ///< s
  Eigen::Vector3d hand = Eigen::Vector3d::Zero();           ///< the hand's target, m
  Eigen::Vector3d device = Eigen::Vector3d::Zero();         ///< the tool centre, m
  Eigen::Vector3d box = Eigen::Vector3d::Zero();            ///< the box's body origin, m
  Eigen::Vector3d box_velocity = Eigen::Vector3d::Zero();   ///< m/s
  double box_turn = 0;                                      ///< the box's rotation from rest, rad
  Eigen::Vector3d push = Eigen::Vector3d::Zero();           ///< coupling force on the box, N
  double k_min = 0;  ///< deepest K_min of the box's Gaussians against the tool at its proxy (0: not inside)
  /// How far the tool at the box's proxy reaches into the box (its faces' planes, where its
  /// discs' centres lie), m; 0: not inside. A check for either surface: the ellipsoid proxy rests
  /// on the discs' 1-sigma shells outside the faces, the seen proxy where the eye sees them.
  double box_depth = 0;
};

/// What the run gave.
struct PushRun {
  PushScenario scenario;
  std::vector<PushSample> samples;
  RuntimeSummary runtime;         ///< of the SimulatedRuntime (ticks, forces, safety)
  double travelled = 0;           ///< the box's displacement along x, m
  double deepest_k_min = 0;       ///< max over the ticks of PushSample::k_min
  double deepest_box_depth = 0;   ///< max over the ticks of PushSample::box_depth, m
  /// The passivity observer's energy into the environment (the static scene and the box) at its
  /// highest and its lowest, J (servo/passivity.h): negative would be energy given to the hand.
  /// (The observer forgets stored energy once nothing is held, so it reads 0 after the release.)
  double peak_energy = 0, lowest_energy = 0;
  int sliding_ticks = 0;          ///< ticks with the box sliding (v_x > 2 cm/s on two ticks in a row)
  double friction_estimate = 0;   ///< over the sliding ticks: mean push_x - m mean a_x, N
  double friction_expected = 0;   ///< mu m g, N
};

/// Runs the scenario. Throws InputError for invalid settings (non-positive sizes, mass, rate)
/// and what the runtime's constructor throws. `progress` gets the fraction done.
[[nodiscard]] PushRun run_push_scenario(const PushScenario& scenario,
                                        const std::function<void(double)>& progress = {});

}  // namespace gshaptics
