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

namespace gshaptics {

inline constexpr double kDefaultObjectMass = 0.5;      ///< kg, when --object gives none
inline constexpr double kDefaultObjectFriction = 0.5;  ///< Coulomb mu against the support, when none is given
/// Gaussians at least this opaque span an object's collision hull (its "opaque Gaussians").
inline constexpr float kHullMinOpacity = 0.5f;
/// At most this many objects in one scene (fixed-size per-tick buffers).
inline constexpr std::size_t kMaxObjects = 8;

/// Which Gaussians make one object, and its physical properties.
struct ObjectSpec {
  enum class Cut { kBox, kIndices };
  Cut cut = Cut::kBox;
  /// kBox: the Gaussians whose world-frame centre lies in [box_lo, box_hi] (m).
  Eigen::Vector3d box_lo = Eigen::Vector3d::Zero(), box_hi = Eigen::Vector3d::Zero();
  /// kIndices: the file's Gaussian indices (GaussianScene::source_index).
  std::vector<std::uint32_t> indices;
  double mass = kDefaultObjectMass;          ///< kg, > 0
  double friction = kDefaultObjectFriction;  ///< mu >= 0, against the support
  std::string text;                          ///< as given, for messages
};

/// Parses one --object value:
///   box:X0,Y0,Z0,X1,Y1,Z1[:mass=KG][:friction=MU]   (world frame, m)
///   indices:I,J,K,...[:mass=KG][:friction=MU]       (the file's Gaussian indices)
/// Throws InputError naming `source` (the option or the JSON field) and what is wrong.
[[nodiscard]] ObjectSpec parse_object_spec(std::string_view text, const std::string& source = "--object");

/// A scene split into its static part and its objects' Gaussians.
struct SceneCut {
  GaussianScene rest;  ///< the static part, in the file's frame (built as the scene was)
  /// Each object's Gaussians, in the WORLD frame (registered: means, scales and rotations), in
  /// the order of the specs.
  std::vector<GaussianScene> objects;
};

/// Splits `scene` by `specs`: a Gaussian goes to the first object that claims it and to no
/// other; the rest stay static. `scene_to_world` is the world's whole registration (scene
/// file -> world, CollisionWorld::scene_to_world()). Throws InputError naming the spec when an
/// object gets no Gaussian above `min_opacity`, and for more than kMaxObjects specs.
[[nodiscard]] SceneCut cut_objects(const GaussianScene& scene, const SimilarityTransform& scene_to_world,
                                   std::span<const ObjectSpec> specs, float min_opacity);

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

/// The six faces of the box center +- half (world frame, m) tiled with thin discs every
/// `spacing` m, each 1.4 cells wide so that neighbours overlap as a capture's do (discs that only
/// touch are floaters to the proxy), thin axis 5 % of `spacing`, opacity `opacity`; source
/// indices from `first_index`. A box object or a floor slab for tests, benchmarks and demos.
[[nodiscard]] GaussianScene box_surface_gaussians(const Eigen::Vector3d& center, const Eigen::Vector3d& half,
                                                  double spacing, float opacity = 0.9f, std::uint32_t first_index = 0);

/// A rigid pose of a body frame in the world: x_world = rotation * x_body + position.
struct BodyPose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< m
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();   ///< of the body origin, m/s, world
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  ///< rad/s, world
  /// The world velocity of the body-fixed point now at `p` (world), m/s.
  [[nodiscard]] Eigen::Vector3d velocity_at(const Eigen::Vector3d& p) const noexcept {
    return linear_velocity + angular_velocity.cross(p - position);
  }
};

/// The live poses of a scene's objects, as one value the servo thread publishes through a
/// TripleBuffer and the viewer, ROS and logs read.
struct ObjectPoses {
  double time = 0;  ///< simulated time, s
  std::uint32_t count = 0;
  std::array<BodyPose, kMaxObjects> poses{};
};

}  // namespace gshaptics
