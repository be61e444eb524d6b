#pragma once
/// @file
/// A scene cut into its static part and rigid objects (issue 72): which Gaussians make each object
/// (an axis-aligned world box, or a list of the file's Gaussian indices), its mass and friction,
/// and the cut itself. The objects' dynamics and rendering are gshaptics::objects
/// (objects/rigid_object.h); the cut needs neither, so every scene command can parse --object.
///
/// A cut leaves the static part without the Gaussians that were under the object: the capture
/// never saw them, so where the object stood the static scene has a hole that the support plane
/// (objects/object_dynamics.h) carries.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "gshaptics/io/gaussian_scene.h"
#include "gshaptics/scene/registration.h"

namespace gshaptics {

inline constexpr double kDefaultObjectMass = 0.5;      ///< kg, when --object gives none
inline constexpr double kDefaultObjectFriction = 0.5;  ///< Coulomb mu against the support, when none is given
/// At most this many objects in one scene (fixed-size per-tick buffers).
inline constexpr std::size_t kMaxObjects = 8;
/// At most this many convex pieces in one object's (or support's) collision geometry.
inline constexpr int kMaxObjectHulls = 16;

/// Which Gaussians make one object, and its physical properties.
struct ObjectSpec {
  enum class Cut { kBox, kIndices, kFile };
  Cut cut = Cut::kBox;
  /// kBox: the Gaussians whose world-frame centre c lies in [box_lo, box_hi] (m) in the box's
  /// frame, box_rotation^-1 c (identity: an axis-aligned box; an oriented box, `obox:`, turns it).
  Eigen::Vector3d box_lo = Eigen::Vector3d::Zero(), box_hi = Eigen::Vector3d::Zero();
  Eigen::Quaterniond box_rotation = Eigen::Quaterniond::Identity();
  /// kIndices: the file's Gaussian indices (GaussianScene::source_index).
  std::vector<std::uint32_t> indices;
  /// kFile: a splat file of its own (any format load_scene reads), placed in the world by its
  /// registration file (empty: none; the world's --up applies as it does to the scene).
  std::string file, registration_file;
  /// kFile: a registration given inline (an objects JSON); it wins over registration_file.
  std::optional<SimilarityTransform> registration;
  double mass = kDefaultObjectMass;          ///< kg, > 0
  double friction = kDefaultObjectFriction;  ///< mu >= 0, against the support
  /// Convex pieces of the collision geometry, 1..kMaxObjectHulls (rigid_object.h: the opaque
  /// Gaussians split by k-means; more than one for a concave object such as an arch or a mug).
  int hulls = 1;
  std::string text;                          ///< as given, for messages
};

/// Parses one --object value:
///   box:X0,Y0,Z0,X1,Y1,Z1[:mass=KG][:friction=MU][:hulls=N]   (world frame, m)
///   obox:CX,CY,CZ,HX,HY,HZ,QW,QX,QY,QZ[:...]          (an oriented box: centre, half extents
///                                                     along its own axes, its rotation w first)
///   indices:I,J,K,...[:mass=KG][:friction=MU][:hulls=N]   (the file's Gaussian indices)
///   file:PATH[:registration=FILE.json][:mass=KG][:friction=MU]   (a splat file of its own;
///   PATH may not contain ':')
/// `hulls=N` splits the collision geometry into N convex pieces (ObjectSpec::hulls).
/// Throws InputError naming `source` (the option or the JSON field) and what is wrong.
[[nodiscard]] ObjectSpec parse_object_spec(std::string_view text, const std::string& source = "--object");

/// What an objects JSON lists: the rigid objects and the static supports they stand on.
struct ObjectSpecList {
  std::vector<ObjectSpec> objects;
  std::vector<ObjectSpec> supports;  ///< as --support (box, obox or indices)
};

/// Parses an objects JSON (`--objects FILE.json`):
///   {"objects": [{"box": [X0, Y0, Z0, X1, Y1, Z1]} | {"obox": {"center", "half", "rotation"}} |
///                {"indices": [I, J, ...]} |
///                {"file": "cup.ply", "registration": "cup.json" or {"scale", "rotation", "translation"}},
///                each with optional "mass" (kg), "friction" and "hulls"],
///    "supports": [{"box": ...} | {"obox": ...} | {"indices": ...}]   (optional)}
/// Relative file paths resolve against `base_dir`. Throws InputError naming `source` and the entry
/// (objects[I], supports[I]) and what is wrong; at most kMaxObjects objects.
[[nodiscard]] ObjectSpecList parse_object_specs_json(const std::string& text, const std::string& source,
                                                     const std::string& base_dir);
/// Reads an objects JSON file (parse_object_specs_json, paths relative to its folder). Throws
/// InputError naming the file.
[[nodiscard]] ObjectSpecList load_object_specs(const std::string& path);

/// A scene split into its static part and its objects' Gaussians.
struct SceneCut {
  GaussianScene rest;  ///< the static part, in the file's frame (built as the scene was)
  /// Each object's Gaussians, in the WORLD frame (registered: means, scales and rotations), in
  /// the order of the specs; their band-0 colour when the scene has one (the higher SH bands,
  /// which would turn with the registration, are not kept).
  std::vector<GaussianScene> objects;
};

/// Splits `scene` by `specs`: a Gaussian goes to the first object that claims it and to no
/// other; the rest stay static. A file object (Cut::kFile) claims nothing: its entry in
/// SceneCut::objects is filled by object_from_file(). `scene_to_world` is the world's whole registration (scene
/// file -> world, CollisionWorld::scene_to_world()). Throws InputError naming the spec when an
/// object gets no Gaussian above `min_opacity`, and for more than kMaxObjects specs.
[[nodiscard]] SceneCut cut_objects(const GaussianScene& scene, const SimilarityTransform& scene_to_world,
                                   std::span<const ObjectSpec> specs, float min_opacity);

/// Static supports (`--support`, a table top): the Gaussians each spec claims, copied in the world
/// frame (registered) without leaving the scene, so the hand still feels them and MuJoCo gets
/// their hull as a static body. A Gaussian may go to several supports. Throws InputError naming
/// the spec for a file spec (a support is a part of the scene) and for one that claims no Gaussian
/// above `min_opacity`.
[[nodiscard]] std::vector<GaussianScene> select_supports(const GaussianScene& scene, const SimilarityTransform& scene_to_world,
                                                         std::span<const ObjectSpec> specs, float min_opacity);

/// A file object's Gaussians in the world frame (as SceneCut::objects holds them, band-0 colour
/// kept): spec.file loaded, placed by with_up_axis(its registration, `up`, the file's frame).
/// Throws InputError naming the file for a file that cannot be read, and naming the spec when
/// no Gaussian is above `min_opacity`.
[[nodiscard]] GaussianScene object_from_file(const ObjectSpec& spec, UpAxis up, float min_opacity);

/// Fills each file object's entry of `cut` (object_from_file), so that cut.objects holds every
/// object of `specs`. Throws as object_from_file().
void load_file_objects(SceneCut& cut, std::span<const ObjectSpec> specs, UpAxis up, float min_opacity);

/// The six faces of the box center +- half (world frame, m) tiled with thin discs every
/// `spacing` m, each 1.4 cells wide so that neighbours overlap as a capture's do (discs that only
/// touch are floaters to the proxy), thin axis 5 % of `spacing`, opacity `opacity`; source
/// indices from `first_index`. A box object or a floor slab for tests, benchmarks and demos.
[[nodiscard]] GaussianScene box_surface_gaussians(const Eigen::Vector3d& center, const Eigen::Vector3d& half,
                                                  double spacing, float opacity = 0.9f, std::uint32_t first_index = 0);

/// A box of Gaussians standing on a floor slab of Gaussians, z up, metres: the box's faces
/// (box_surface_gaussians, orange) from z = 0 to 2 box_half.z about the z axis, the slab's
/// (grey) top face spacing / 20 under it, floor_half wide. `object_spec` is the --object text
/// that cuts the box and nothing of the floor. For demos and the viewer's browser test
/// (`gshaptics synth box-on-floor`).
struct BoxOnFloor {
  GaussianScene scene;  ///< the box's Gaussians first, then the floor's; band-0 colour set
  std::string object_spec;
};
[[nodiscard]] BoxOnFloor box_on_floor(const Eigen::Vector3d& box_half, const Eigen::Vector2d& floor_half, double spacing);

}  // namespace gshaptics
