#pragma once
/// @file
/// Materials by region: a scene's surfaces with their own coupling stiffness and damping, static
/// and kinetic friction and viscosity, read by the proxy under its contact. The haptics
/// frameworks labs use give every object a material (CHAI3D's cMaterial: stiffness, damping,
/// static and dynamic friction, viscosity, texture, vibration); a 3DGS capture carries no labels,
/// so a material map assigns them to regions of the scene.
///
/// A map is JSON (docs/usage.md, "Materials"):
///
///     {"frame": "scene",
///      "materials": [{"name": "wood", "stiffness": 2000, "mu_s": 0.5, "mu_k": 0.4},
///                    {"name": "cushion", "stiffness": 300, "damping": 0.5, "viscosity": 2}],
///      "regions": [{"material": "wood", "box": {"min": [-1, -1, 0], "max": [1, 1, 0.8]}},
///                  {"material": "cushion", "sphere": {"center": [0, 0, 1], "radius": 0.3}},
///                  {"material": "wood", "indices": [12, 13, 14]}]}
///
/// Units: stiffness N/m, damping and viscosity N s/m, friction coefficients dimensionless;
/// texture_gain and vibration are carried for the texture renderer (0 by default). A property a
/// material leaves out is the proxy's own (ProxyParams: --stiffness, --damping, --mu-s, --mu-k),
/// and so is every property where no region claims the surface. Regions are tested on the
/// Gaussians' centres in the scene file's frame ("frame": "scene", the default) or the
/// registered world's ("world"); indices are the Gaussians' indices in the file. A Gaussian in
/// several regions takes the last one's material.
///
/// Blending (MaterialField::at): the properties at a contact are the weighted mean over the
/// Gaussians near it, w_i = alpha_i exp(-d_i^2 / (2 R^2)) (d_i: the distance from the proxy's
/// centre to Gaussian i's centre, R the tool's bounding radius): a kernel that varies
/// continuously as the proxy slides, so a tool resting on two materials blends them by how much
/// of each is under it, and crossing a border changes the force without a step.
///
/// Threading: a MaterialField is immutable after resolve(); at() allocates, locks, logs and
/// throws nothing.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/force/proxy_params.h"

namespace gshaptics {

/// One material's properties; a property left unset is the proxy's own (ProxyParams).
struct Material {
  std::string name;
  std::optional<double> stiffness;  ///< N/m, > 0: the coupling spring k_c
  std::optional<double> damping;    ///< N s/m, >= 0: along the normal
  std::optional<double> mu_s;       ///< >= 0 (0: no friction)
  std::optional<double> mu_k;       ///< 0 <= mu_k <= mu_s
  double viscosity = 0;             ///< N s/m, >= 0: drag on the device's tangential velocity in contact
  double texture_gain = 0;          ///< >= 0, for the texture renderer (not yet rendered)
  double vibration = 0;             ///< >= 0, for vibrotactile devices (not yet rendered)
};

/// A region of the scene that a material claims.
struct MaterialRegion {
  enum class Kind { kBox, kSphere, kIndices };
  Kind kind = Kind::kBox;
  std::size_t material = 0;  ///< index into MaterialMap::materials
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();  ///< kBox: corners
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< kSphere
  double radius = 0;                                 ///< kSphere
  std::vector<std::uint32_t> indices;                ///< kIndices: Gaussians of the file
};

/// A parsed material map (the JSON above).
struct MaterialMap {
  enum class Frame { kScene, kWorld };
  Frame frame = Frame::kScene;
  std::vector<Material> materials;  ///< at most 254
  std::vector<MaterialRegion> regions;
  std::string source;  ///< the file it came from, for messages

  /// Reads and validates `path`. Throws InputError naming the file and what is wrong (unreadable,
  /// not JSON, an unknown key, a material without a name or with a property out of range, a
  /// region naming no known material, an empty box).
  static MaterialMap load(const std::string& path);
  /// Parses `j`; `source` names it in errors. Throws InputError as load().
  static MaterialMap parse(const nlohmann::json& j, const std::string& source);
};

/// The properties at a contact, blended (MaterialField::at).
struct MaterialBlend {
  double stiffness = 0, damping = 0, mu_s = 0, mu_k = 0, viscosity = 0, texture_gain = 0, vibration = 0;
  /// The material with the largest weight: 0 none (the proxy's own), m + 1 MaterialMap::materials[m].
  int dominant = 0;
};

/// A material map resolved on a world: each Gaussian's material, and the properties of each
/// material with the proxy's own filled in.
class MaterialField {
 public:
  /// Tests every Gaussian of `world` against the regions of `map` (its centre brought back into
  /// the file's frame by the inverse of scene_to_world() for "frame": "scene"; its source index
  /// for index lists); `base`: the proxy's parameters for what a material leaves unset. Throws
  /// InputError (naming map.source) for a material whose mu_k exceeds its mu_s once filled in.
  static std::shared_ptr<const MaterialField> resolve(const MaterialMap& map, const CollisionWorld& world,
                                                      const ProxyParams& base);

  /// The blended properties around the proxy's centre `center` (world, m) for a tool of bounding
  /// radius `radius` (m): the weighted mean over the Gaussians whose centres lie within 3 radius
  /// (weights as in the file comment); the proxy's own where none are near. No allocation.
  [[nodiscard]] MaterialBlend at(const CollisionWorld& world, const Eigen::Vector3d& center,
                                 double radius) const noexcept;
  /// The material of world slot `slot`: 0 the proxy's own, m + 1 the map's m-th.
  [[nodiscard]] std::uint8_t material_of(std::size_t slot) const noexcept { return slot_material_[slot]; }
  /// Name of material id `id` (0: "default").
  [[nodiscard]] std::string_view name(int id) const noexcept;
  /// How many Gaussians each material claims (index 0: none).
  [[nodiscard]] const std::vector<std::size_t>& counts() const noexcept { return counts_; }
  [[nodiscard]] std::size_t material_count() const noexcept { return props_.size(); }

 private:
  struct Props {
    double v[7];  // stiffness, damping, mu_s, mu_k, viscosity, texture_gain, vibration
  };
  std::vector<std::uint8_t> slot_material_;  // per world slot
  std::vector<Props> props_;                 // id 0: the proxy's own
  std::vector<std::string> names_;
  std::vector<std::size_t> counts_;
};

}  // namespace gshaptics
