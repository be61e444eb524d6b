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
///   centre is inside the tool (floaters it passed) and floaters among those that hold the answer;
/// - optionally tells a clean convex corner (three faces): the thin axes in three tight groups,
///   every pair of faces convex, the tool outside; there the support normal is taken whole. A
///   corner's normal cone is a solid angle that the hull's normal stays in, where the shaded field
///   of the face the tool rests on tilts out of it by the discs' jitter (seen through fewer discs
///   beside two edges than on a face) and a fin (a disc overhanging the corner) turns it further.
/// - optionally answers a clean flat face (the thin axes in one tight direction): its Gaussians'
///   mean thin axis, which face_blend() averages with the shaded normal.
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
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< unit when `feature()`, world frame
  bool edge = false;                                 ///< the patch is a clean convex edge
  bool corner = false;                               ///< the patch is a clean convex corner
  /// (corners asked for) the patch's thin axes spread so that three directions hold under half
  /// their weight: a real scene's reconstruction noise, far from any clean feature
  bool messy = false;
  /// (faces asked for) the patch is one flat face: `normal` is its Gaussians' mean thin axis,
  /// turned toward the tool's side (`start`); no feature
  bool face = false;
  /// (edge or corner) the unit outward normals of the feature's faces, world frame: two at an
  /// edge, three at a corner (each face's Gaussians' mean thin axis). They span the feature's
  /// normal cone (crest_depth()).
  std::array<Eigen::Vector3d, 3> faces{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  std::uint8_t face_count = 0;
  /// (edge) the unit direction of the edge line, world frame
  Eigen::Vector3d edge_line = Eigen::Vector3d::Zero();
  /// (edge) the point of the edge line nearest the tool's centre; (corner) its vertex: where the
  /// faces' planes meet, each through its Gaussians' weighted centre. World frame, m.
  Eigen::Vector3d apex = Eigen::Vector3d::Zero();
  [[nodiscard]] bool feature() const noexcept { return edge || corner; }
};

/// The convex features EdgeNormal::read() answers at (a bit set).
/// kFaces adds the flat face's answer (EdgeNormalAnswer::face), for face_blend(). kEdgeCones
/// answers clean convex edges by their faces alone (faces, edge_line, and the faces' mean as the
/// normal), without the support normal's search: for a caller that wants an edge's normal cone,
/// not its normal (ProxyRenderer's crest hold).
enum class ConvexFeatures : std::uint8_t {
  kEdges = 1,
  kCorners = 2,
  kEdgesAndCorners = 3,
  kFaces = 4,
  kEdgesAndFaces = 5,
  kEdgeCones = 8,
  kEdgeConesAndCorners = 10
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
  /// Gaussian is surface). `features`: which convex features get an answer (the others: none).
  /// `away` (any length; zero: none): a second direction known to point from the surface toward
  /// the tool (a god-object's spring, proxy - device), for the corner test's orientation check
  /// where `start` may be wrong (a shaded normal turned by a fin).
  EdgeNormalAnswer read(const ToolEllipsoid& tool, const Eigen::Vector3d& start, double band, double reuse,
                        BlockFilter floaters, EdgeNormalCache& cache,
                        ConvexFeatures features = ConvexFeatures::kEdges,
                        const Eigen::Vector3d& away = Eigen::Vector3d::Zero()) noexcept;

  /// `shaded` (unit) turned toward the answer's normal: not at all while they are within
  /// kBlendFrom, fully past kBlendTo, linearly between. Unchanged when the answer is no feature or
  /// its normal faces away from `contact` (a contact normal the result must agree with).
  [[nodiscard]] static Eigen::Vector3d blend(const Eigen::Vector3d& shaded, const EdgeNormalAnswer& answer,
                                             const Eigen::Vector3d& contact) noexcept;
  /// On a flat face (answer.face), `shaded` (unit) averaged with the face's normal while they
  /// are within kFaceFrom, turned back to `shaded` alone by kFaceTo (there the field sees
  /// something the patch does not), linearly between. Two estimates of the same discs' tilts
  /// (3 degrees on the fidelity scenes), weighed differently: the shaded field, the gradient of
  /// the Gaussians' density, turns with the tilts of the few discs its kernel weighs near the
  /// reading point (discs lying flat at scattered heights barely turn it); the mean thin axis
  /// averages every disc of the patch alike. On the 2 mm plane the patch holds many more discs;
  /// on the 8 mm plane about as few, and the mean of the two is quieter than either there
  /// (fidelity seeds 1-30, bench/RESULTS.md). Unchanged when the answer is no face or its normal
  /// faces away from `contact`.
  [[nodiscard]] static Eigen::Vector3d face_blend(const Eigen::Vector3d& shaded, const EdgeNormalAnswer& answer,
                                                  const Eigen::Vector3d& contact) noexcept;

  /// How deep `direction` (any length, world frame) lies inside the normal cone of the answer's
  /// feature: the smallest angle, rad, between it and the cone's bounding planes (at an edge,
  /// of its part across the edge line, between the two faces' normals; at a corner, between the
  /// planes of each pair of the three), negative outside the cone and -pi/2 when the answer is no
  /// feature or `direction` is zero. A god-object on a convex polyhedron rests on an edge or a
  /// vertex while the device lies in that feature's normal cone from it (Zilles & Salisbury 1995:
  /// two or three constraints active); ProxyRenderer's crest hold reads this.
  [[nodiscard]] static double crest_depth(const EdgeNormalAnswer& answer, const Eigen::Vector3d& direction) noexcept;

  /// `from` (unit) turned toward `to` (unit) by the share t in [0, 1]: the normalised linear mix,
  /// `from` where the mix vanishes. blend()'s and face_blend()'s hand-over, and the proxy's
  /// fading of the corner's answer where a fin blocks the tool.
  [[nodiscard]] static Eigen::Vector3d turned_toward(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                                     double t) noexcept;

  /// The soft minimum's width, in the tool's smallest semi-axis: about the Gaussians' jitter on
  /// a 5 mm tool (0.5 mm).
  static constexpr double kSupportTau = 0.1;
  /// A clean edge: the thin axes' second principal value at least kFeatureShare of the first (a
  /// second face holds about 5 % of the patch's weight; a face's 3 deg tilts give 0.3 %) and the
  /// third under kEdgeShare of the second (the fidelity cube's edges pass; no patch of the Truck
  /// or burger stylus probe runs does, 19 % of halo's).
  static constexpr double kFeatureShare = 0.05;
  /// A clean edge's faces are tight: each face's thin axes spread (rms angle about its mean) at
  /// most kFaceTightness of the angle between the faces; a relief whose discs turn continuously
  /// (a grating's ridges) is no edge.
  static constexpr double kFaceTightness = 0.25;
  static constexpr double kEdgeShare = 0.05;
  /// A clean corner: each face's thin axes within kCornerSpread of its heaviest disc's (the
  /// fidelity scenes' discs tilt 3 degrees; real scenes' patches spread in every direction) and
  /// the faces' mean directions at least kCornerApart apart; each face at least kFeatureShare of
  /// the patch's weight and at most kEdgeShare left in none of the three. Radians.
  static constexpr double kCornerSpread = 20.0 * 3.14159265358979323846 / 180;
  static constexpr double kCornerApart = 30.0 * 3.14159265358979323846 / 180;
  /// A flat face: the thin axes' second principal value under kFaceShare of the first (a face's
  /// 3-degree tilts give 0.3 %; a patch spanning 16 degrees of a curved surface, or a second
  /// face's 5 %, do not pass), over at least kFaceMinGaussians flat Gaussians (the mean of
  /// fewer 3-degree tilts is no quieter than the field).
  static constexpr double kFaceShare = 0.01;
  static constexpr std::size_t kFaceMinGaussians = 8;
  /// face_blend(): 3 and 6 degrees, rad; the face's share in the mean, kFaceShareOfMean.
  static constexpr double kFaceFrom = 3.0 * 3.14159265358979323846 / 180;
  static constexpr double kFaceTo = 6.0 * 3.14159265358979323846 / 180;
  static constexpr double kFaceShareOfMean = 0.5;
  /// blend(): 3 and 6 degrees, rad.
  static constexpr double kBlendFrom = 3.0 * 3.14159265358979323846 / 180;
  static constexpr double kBlendTo = 6.0 * 3.14159265358979323846 / 180;
  static constexpr std::size_t kMaxPatch = kSupportPatchOnePass;

 private:
  // ConvexFeatures::kEdgeCones: the clean convex edge `edge` of the first `n` patch Gaussians
  // answered by its faces (sc's answer; unchanged when the edge is not clean and convex).
  const EdgeNormalAnswer& edge_cone(const Eigen::Vector3d& edge, const Eigen::Vector3d& tool_center, std::size_t n,
                                    EdgeNormalCache& sc) const noexcept;

  const CollisionWorld* world_;
  std::array<PatchGaussian, kMaxPatch> patch_{};
  std::array<std::uint32_t, kMaxPatch> slot_{};
  std::array<Eigen::Vector3d, kMaxPatch> axis_{};  // thin axis x opacity x flatness
};

}  // namespace gshaptics
