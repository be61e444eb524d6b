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
  /// The points whose convex hull is the object's collision geometry for the dynamics: the six
  /// axis tips (at the world's sigma) of each Gaussian with opacity >= kHullMinOpacity (all kept
  /// ones if none is that opaque), body frame, m.
  std::vector<Eigen::Vector3d> hull_points;
};

/// Builds an object from its world-frame Gaussians (SceneCut::objects) with the filter and sigma
/// of `config` (its up and registration are not used: the Gaussians are already in the world).
/// Throws InputError (naming spec.text) when none passes the filter.
[[nodiscard]] RigidObject make_rigid_object(const GaussianScene& world_gaussians, const ObjectSpec& spec,
                                            const WorldConfig& config);

}  // namespace gshaptics
