#pragma once
/// @file
/// The contact normal of a tool ellipsoid resting on a clean convex edge of the Gaussians (issue
/// 36, item 5). At an edge the shaded field (shaded_normal.h) blends the two faces' normals, while
/// a smooth tool resting on a sharp edge is pushed along its own normal there (a stylus crossing an
/// edge: perpendicular to both its axis and the edge). EdgeNormal looks at the tool's patch, the
/// Gaussians whose bounding sphere comes within `band` of it and whose box meets its box grown by
/// `band`, and:
/// - tells a clean edge from a face, a corner or a messy patch by the spread of the patch's thin
///   axes (each weighted by opacity and flatness 1 - a_min / a_mid): a clean edge has two principal
///   directions and almost nothing out of their plane;
/// - tells a convex edge from a groove: split into its two faces, each face lies behind the
///   other's plane at a convex edge (a groove keeps the shaded normal: its hull spans the
///   opening, and the support normal would be the bisector whichever wall the tool touches);
/// - at a clean convex edge, takes the patch's support normal (support_normal.h), keeps only its part
///   across the edge (its tilt along the edge is the rims' jitter), and leaves out Gaussians whose
///   centre is inside the tool (floaters it passed) and floaters among those that hold the answer.
/// blend() then hands the force from the shaded normal to it over 3-6 degrees of disagreement.
///
/// Threading: one thread per EdgeNormal; read() and blend() allocate, lock, log and throw nothing.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/sweep_query.h"
#include "gshaptics/collision/tool_ellipsoid.h"
#include "gshaptics/force/support_normal.h"

namespace gshaptics {

/// What EdgeNormal::read() found for one tool ellipsoid.
struct EdgeNormalAnswer {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< unit when `edge`, world frame
  bool edge = false;                                 ///< the patch is a clean convex edge
};

/// One tool ellipsoid's last answer and the pose it was found at.
struct EdgeNormalCache {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  EdgeNormalAnswer answer;
  bool valid = false;
  void reset() noexcept { valid = false; }
};

class EdgeNormal {
 public:
  explicit EdgeNormal(const CollisionWorld& world);

  /// The answer for `tool` (world frame, m), starting the support normal's search at `start`
  /// (unit, e.g. the shaded normal). `band` (m, > 0): the patch's reach beyond the tool. The
  /// cached answer while the tool is within `reuse` m (and turned by less than that at its
  /// largest semi-axis) of where it was found. `floaters`: the proxy's floater rule (empty: every
  /// Gaussian is surface).
  EdgeNormalAnswer read(const ToolEllipsoid& tool, const Eigen::Vector3d& start, double band, double reuse,
                        BlockFilter floaters, EdgeNormalCache& cache) noexcept;

  /// `shaded` (unit) turned toward the answer's normal: not at all while they are within
  /// kBlendFrom, fully past kBlendTo, linearly between. Unchanged when the answer is no edge or
  /// its normal faces away from `contact` (a contact normal the result must agree with).
  [[nodiscard]] static Eigen::Vector3d blend(const Eigen::Vector3d& shaded, const EdgeNormalAnswer& answer,
                                             const Eigen::Vector3d& contact) noexcept;

  /// The soft minimum's width, in the tool's smallest semi-axis: about the Gaussians' jitter on
  /// a 5 mm tool (0.5 mm).
  static constexpr double kSupportTau = 0.1;
  /// A clean edge: the thin axes' second principal value at least kFeatureShare of the first (a
  /// second face holds about 5 % of the patch's weight; a face's 3 deg tilts give 0.3 %) and the
  /// third under kEdgeShare of the second (the fidelity cube's edges pass; no patch of the Truck
  /// or burger stylus probe runs does, 19 % of halo's).
  static constexpr double kFeatureShare = 0.05;
  static constexpr double kEdgeShare = 0.05;
  /// blend(): 3 and 6 degrees, rad.
  static constexpr double kBlendFrom = 3.0 * 3.14159265358979323846 / 180;
  static constexpr double kBlendTo = 6.0 * 3.14159265358979323846 / 180;
  static constexpr std::size_t kMaxPatch = kSupportPatchOnePass;

 private:
  const CollisionWorld* world_;
  std::array<PatchGaussian, kMaxPatch> patch_{};
  std::array<std::uint32_t, kMaxPatch> slot_{};
  std::array<Eigen::Vector3d, kMaxPatch> axis_{};  // thin axis x opacity x flatness
};

}  // namespace gshaptics
