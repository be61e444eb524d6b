#pragma once
/// @file
/// Rigid objects in a scene (issue 72): a scene is a static part plus zero or more rigid objects,
/// each cut from the scene (an axis-aligned world box, or a list of the file's Gaussian indices).
/// An object keeps its Gaussians and its BVH in its own body frame, so a query transforms the tool
/// into that frame and nothing is rebuilt when the object moves; the static world stays immutable
/// and shareable.
///
/// Frames: "world" is the registered frame of the scene (CollisionWorld::scene_to_world()); an
/// object's body frame has its axes along the world's at rest and its origin at the centre of the
/// box around its hull points (RigidObject::rest_origin). Units: metres, kilograms.
///
/// A cut leaves the static part without the Gaussians that were under the object: the capture
/// never saw them, so where the object stood the static scene has a hole that the support plane
/// (object_dynamics.h) carries.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/io/gaussian_scene.h"
#include "gshaptics/servo/object_poses.h"
#include "gshaptics/scene/scene_cut.h"

namespace gshaptics {

/// Gaussians at least this opaque span an object's collision hull (its "opaque Gaussians").
inline constexpr float kHullMinOpacity = 0.5f;

/// One rigid object: its Gaussians as a collision world in its body frame, and what the
/// dynamics needs.
struct RigidObject {
  ObjectSpec spec;
  /// The object's filtered Gaussians in its body frame (immutable, shared with every renderer).
  std::shared_ptr<const CollisionWorld> body;
  /// The body frame's origin in the world at rest (m); the body's axes are the world's at rest.
  Eigen::Vector3d rest_origin = Eigen::Vector3d::Zero();
  /// The points whose convex hulls are the object's collision geometry for the dynamics: the six
  /// axis tips (at the world's sigma) of each Gaussian with opacity >= kHullMinOpacity (all kept
  /// ones if none is that opaque), body frame, m; grouped by piece (piece_ends).
  std::vector<Eigen::Vector3d> hull_points;
  /// Where each convex piece's points end in hull_points (piece k is [piece_ends[k-1],
  /// piece_ends[k]), the first from 0): one entry per piece, ObjectSpec::hulls of them at most.
  std::vector<std::size_t> piece_ends;

  /// Piece k's points (body frame, m).
  [[nodiscard]] std::span<const Eigen::Vector3d> piece(std::size_t k) const noexcept {
    const std::size_t begin = k == 0 ? 0 : piece_ends[k - 1];
    return std::span<const Eigen::Vector3d>(hull_points).subspan(begin, piece_ends[k] - begin);
  }
};

/// The pieces of a concave object (ObjectSpec::hulls > 1), from the Gaussians on its surface: a
/// convex piece lies on one side of every one of its surface discs' tangent planes, so a disc whose
/// plane has many of the piece's centres on both sides (farther than `tolerance`, m) shows a
/// concavity, and the piece is cut there. Each round cuts the piece with the most centres on the
/// minority side of one of its discs' planes, along the most even such plane (the centres within
/// `tolerance` of it join the side of their nearest centre off it), until there are `pieces`
/// pieces or no plane has kMinPieceGaussians and 2 % of a piece on its minority side (the pieces
/// are convex to within the tolerance). A cut removes volume from the hulls' union, never adds.
/// `centres` (m) and `normals` (unit: each Gaussian's thinnest axis) in any one frame; planes are
/// tried at up to 256 discs a piece and counted on up to 4096 centres (deterministic strides).
/// Returns each centre's piece, 0-based and dense.
[[nodiscard]] std::vector<int> split_into_pieces(std::span<const Eigen::Vector3d> centres,
                                                 std::span<const Eigen::Vector3d> normals, double tolerance, int pieces);
/// A piece needs this many Gaussians (a hull of fewer is too thin for MuJoCo to weigh).
inline constexpr std::size_t kMinPieceGaussians = 4;

/// Builds an object from its world-frame Gaussians (SceneCut::objects) with the filter and sigma
/// of `config` (its up and registration are not used: the Gaussians are already in the world),
/// its collision geometry in spec.hulls convex pieces (split_into_pieces).
/// Throws InputError (naming spec.text) when none passes the filter.
[[nodiscard]] RigidObject make_rigid_object(const GaussianScene& world_gaussians, const ObjectSpec& spec,
                                            const WorldConfig& config);

}  // namespace gshaptics
