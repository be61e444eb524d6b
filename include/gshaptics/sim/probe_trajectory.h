#pragma once
/// @file
/// A seeded probe trajectory over a scene: contact sites on the object's outer surface, each
/// approached along its outward normal, pressed in and released (paper Sec. V-A, Fig. 4).

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/device/hand_trajectory.h"

namespace gshaptics {

/// Parameters of the generator. Lengths in world units (metres for a registered scene), speeds
/// in world units per second, times in seconds.
struct ProbeParams {
  int sites = 7;                 ///< contact sites (paper: seven)
  std::uint64_t seed = 1;
  double tool_radius = 0.05;     ///< spherical tool radius
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  ///< world up (travel happens above the object)
  double press_depth = 1.0;      ///< target goes this many tool radii past first contact
  double approach_distance = 4;  ///< approach starts this many tool radii off the surface
  double travel_speed = 1.0;     ///< world units / s between sites (above the object)
  double approach_speed = 0.15;  ///< world units / s toward the surface
  double press_time = 0.4, hold_time = 0.5, release_time = 0.3;
  /// Where the force model's surface first holds the tool: for the sphere's centre moving from
  /// `start` along the unit `dir`, the distance moved at first contact, or NaN when none within
  /// `reach` (world units). Each site's touch point is there, so the press goes press_depth
  /// past the surface the proxy rests on. Empty: the first overlap with the world's ellipsoids,
  /// stepped at tool_radius / 8 (the ellipsoid proxy's and the paper model's surface).
  std::function<double(const Eigen::Vector3d& start, const Eigen::Vector3d& dir, double reach)> first_touch;
  /// For a tool with a shape (a compound tool, held at the world's orientation, its TCP where
  /// the sphere's centre is): how far the TCP moves from `start` along the unit `dir` before any
  /// of its parts meets the force model's surface, or NaN when none does within `reach` (world
  /// units). A site is kept only where the tool comes down from above to the approach's start
  /// touching nothing and meets the surface no earlier along the approach than the sphere does
  /// (by tool_radius / 4): a long tool's body does not meet the object before its tip reaches
  /// the site (a stylus held upright, pressed on a side under an overhang), and meets it within
  /// tool_radius past the site's centre; the site's touch point is then where the tool meets it
  /// (a stylus's tip, narrower than the sphere, reaches further). Empty: the sphere alone decides.
  std::function<double(const Eigen::Vector3d& start, const Eigen::Vector3d& dir, double reach)> tool_touch;
};

/// The default spherical tool radius for a world: 1 % of its robust extent (the 1-99 percentile
/// box of the kept Gaussians' centres; robust_extent()), world units. The one place that
/// default lives: the CLI, Python and the benchmarks use it.
[[nodiscard]] double default_tool_radius(const CollisionWorld& world);

/// The probe parameters of the main job for a tool of `tool_radius` (> 0): the world's own up,
/// approach at 2 tool radii per second and travel at 8, the press `press_depth_m` past first
/// contact (world units; <= 0: one tool radius), the rest ProbeParams' defaults.
[[nodiscard]] ProbeParams default_probe_params(const CollisionWorld& world, double tool_radius, int sites = ProbeParams{}.sites,
                                               std::uint64_t seed = ProbeParams{}.seed, double press_depth_m = 0);

/// How far past first contact (m) the simulated hand's target must go for the hand to push with
/// `force` (N) at rest through a coupling of `coupling_stiffness` (N/m): the hand (a spring of
/// `hand_stiffness`, N/m; UserHandParams) and the coupling in series, d = F (1/k_c + 1/k_h).
/// The probe run presses to half the force limit with it, so its peaks sit in the middle of the
/// device's range whatever the scene's size. Throws InputError for non-positive arguments.
[[nodiscard]] double press_depth_for_force(double force, double coupling_stiffness, double hand_stiffness);

/// Finds `params.sites` sites on the outer surface of the object at the middle of the scene and
/// links them into a path: above the object -> down to the approach point -> along -normal to
/// first contact and `press_depth` beyond -> hold -> back out -> up. Sites are checked with the
/// collision query itself: the approach column and path must be free until first contact.
/// Throws InputError when no site can be found (an empty or degenerate scene).
[[nodiscard]] ProbeTrajectory generate_probe_trajectory(const CollisionWorld& world,
                                                        const ProbeParams& params);

}  // namespace gshaptics
