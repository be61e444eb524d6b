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
///                  {"material": "wood", "indices": [12, 13, 14]},
///                  {"material": "cushion", "colour": {"rgb": [0.8, 0.2, 0.2], "tolerance": 0.15}},
///                  {"material": "wood", "colour": {"rgb": [0.5, 0.3, 0.1], "clusters": 6},
///                   "box": {"min": [-1, -1, 0], "max": [1, 1, 0.8]}}]}
///
/// Units: stiffness N/m, damping and viscosity N s/m, friction coefficients dimensionless;
/// texture_gain scales the relief force (force/texture.h: g k (h - h_bar); 0 by default: none),
/// and "texture" adds a procedural relief, {"grating": {"wavelength": m, "amplitude": m,
/// "direction": [x, y, z]}} or {"noise": {"amplitude": m, "wavelength_min": m,
/// "wavelength_max": m, "seed": n}}; vibration is carried for vibrotactile devices. A property a
/// material leaves out is the proxy's own (ProxyParams: --stiffness, --damping, --mu-s, --mu-k),
/// and so is every property where no region claims the surface. Regions are tested on the
/// Gaussians' centres in the scene file's frame ("frame": "scene", the default) or the
/// registered world's ("world"); indices are the Gaussians' indices in the file. A Gaussian in
/// several regions takes the last one's material.
///
/// Blending. The proxy reads the materials of the Gaussians holding it, weighted by opacity
/// (contact_shares), and follows them along its path: the shares move toward the contacts' by
/// 1 - exp(-ds / R) for a slide of ds (ProxyRenderer), so a tool resting on two materials feels
/// them mixed as its contacts are, and crossing a border blends over one tool radius of path,
/// without a step. MaterialField::at gives the same properties anywhere (a viewer, a query): the
/// weighted mean over the
/// Gaussians near it, w_i = alpha_i (1 - d_i^2 / rho^2) for d_i < rho = 2 R (d_i: the distance
/// from the proxy's centre to Gaussian i's centre, R the tool's bounding radius; the
/// Epanechnikov kernel): weights that vary continuously as the proxy slides, so a tool resting on
/// two materials blends them by how much of each is under it, and crossing a border changes the
/// force without a step. The kernel is a polynomial in the centres, so a BVH node of one material
/// wholly inside the kernel adds its weight from its opacity moments (sum alpha, sum alpha c,
/// sum alpha |c|^2, kept per node) without visiting its Gaussians: the cost grows with the
/// kernel's surface, not its volume.
///
/// Threading: a MaterialField is immutable after resolve(); at() allocates, locks, logs and
/// throws nothing.

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <limits>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/proxy_params.h"
#include "gshaptics/force/texture.h"
#include "gshaptics/io/gaussian_scene.h"

namespace gshaptics {

/// One material's properties; a property left unset is the proxy's own (ProxyParams).
struct Material {
  std::string name;
  std::optional<double> stiffness;  ///< N/m, > 0: the coupling spring k_c
  std::optional<double> damping;    ///< N s/m, >= 0: along the normal
  std::optional<double> mu_s;       ///< >= 0 (0: no friction)
  std::optional<double> mu_k;       ///< 0 <= mu_k <= mu_s
  double viscosity = 0;             ///< N s/m, >= 0: drag on the device's tangential velocity in contact
  double texture_gain = 0;          ///< >= 0: the relief force's gain on k (force/texture.h; 0: no texture)
  double vibration = 0;             ///< in [0, 1]: a vibrotactile device's level in contact (RenderOutput::vibration)
  ProceduralTexture texture;        ///< a procedural relief added to the captured one (kind none: none)
};

/// A selection of Gaussians by their base colour (the SH band-0 colour a viewer shows head-on,
/// rgb = clamp(0.5 + C0 f_dc, 0, 1), C0 = 0.2821): within `tolerance` of `rgb` (Euclidean, in
/// [0, 1]^3), or, with `clusters` K > 0, the Gaussians of the k-means cluster (K clusters of the
/// scene's colours, weighted by opacity) whose centre lies nearest `rgb`.
struct ColourSelector {
  Eigen::Vector3d rgb = Eigen::Vector3d::Zero();  ///< in [0, 1]
  double tolerance = 0.1;                         ///< > 0, used without clusters
  int clusters = 0;                               ///< 0: by tolerance; 2-64: by cluster
};

/// A region of the scene that a material claims.
struct MaterialRegion {
  /// kColour: the Gaussians a colour selects, anywhere (a box or sphere may carry a colour too:
  /// then only the Gaussians inside it that the colour selects).
  enum class Kind { kBox, kSphere, kIndices, kColour };
  Kind kind = Kind::kBox;
  std::size_t material = 0;  ///< index into MaterialMap::materials
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();  ///< kBox: corners
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< kSphere
  double radius = 0;                                 ///< kSphere
  /// kIndices: Gaussians of the file (sorted); with a colour, the ones it selected
  /// (resolve_colour_regions).
  std::vector<std::uint32_t> indices;
  std::optional<ColourSelector> colour;  ///< kColour, or a box / sphere "within" a colour
  bool colour_resolved = false;          ///< `indices` hold the colour's selection
};

/// The map's regions in the world frame of `world`, for a viewer: [{"material": name, "box":
/// {"corners": 8 points}} | {"material", "sphere": {"center", "radius"}} | {"material",
/// "indices": count}] (a scene-frame box becomes the 8 corners of its registered image).
struct MaterialMap;
[[nodiscard]] nlohmann::json regions_in_world(const MaterialMap& map, const CollisionWorld& world);

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
  /// True when a region selects by colour and has not been resolved against a scene's colours.
  [[nodiscard]] bool needs_colours() const noexcept;
};

/// What colour regions select by, per Gaussian of a scene file: its SH band-0 coefficients f_dc,
/// its opacity (the k-means weight) and its index in the file. A world keeps none of these; an
/// embedding keeps them beside it (the Python module's CollisionWorld does).
struct SceneColours {
  std::vector<Eigen::Vector3f> f_dc;
  std::vector<float> opacity;
  std::vector<std::uint32_t> source_index;
  /// Those of `scene`; empty when it has no colour (loaded without LoadOptions::keep_color).
  static SceneColours of(const GaussianScene& scene);
  [[nodiscard]] bool empty() const noexcept { return f_dc.empty(); }
};

/// `map` with its colour regions resolved on `colours`: each selects the source indices of the
/// Gaussians its ColourSelector picks (k-means: Lloyd's iterations from a farthest-point start,
/// deterministic). `selected` (optional): how many Gaussians each region's colour selected (0 for
/// regions without one). Throws InputError naming map.source when a region needs colours and
/// there are none.
[[nodiscard]] MaterialMap resolve_colour_regions(const MaterialMap& map, const SceneColours& colours,
                                                 std::vector<std::size_t>* selected = nullptr);
/// The same on the colours of `scene` (loaded with LoadOptions::keep_color).
[[nodiscard]] MaterialMap resolve_colour_regions(const MaterialMap& map, const GaussianScene& scene,
                                                 std::vector<std::size_t>* selected = nullptr);

/// The properties at a contact, blended (MaterialField::at).
struct MaterialBlend {
  double stiffness = 0, damping = 0, mu_s = 0, mu_k = 0, viscosity = 0, texture_gain = 0, vibration = 0;
  /// The material with the largest weight: 0 none (the proxy's own), m + 1 MaterialMap::materials[m].
  int dominant = 0;
  /// m: the materials' procedural reliefs at the contact point, blended by the same weights.
  double procedural = 0;
};

class VirtualCoupling;
class FrictionCone;
/// Gives a proxy's coupling and friction cone a blend's stiffness and damping (N/m, N s/m) and
/// static and kinetic friction: what every proxy does with the material under its contact.
void apply_blend(const MaterialBlend& blend, VirtualCoupling& coupling, FrictionCone& friction) noexcept;

/// A material map resolved on a world: each Gaussian's material, and the properties of each
/// material with the proxy's own filled in.
class MaterialField {
 public:
  /// Tests every Gaussian of `world` against the regions of `map` (its centre brought back into
  /// the file's frame by the inverse of scene_to_world() for "frame": "scene"; its source index
  /// for index lists; the colour's selection for colour regions); `base`: the proxy's parameters
  /// for what a material leaves unset. Throws InputError (naming map.source) for a material whose
  /// mu_k exceeds its mu_s once filled in, and for a colour region not yet resolved on the
  /// scene's colours (resolve_colour_regions).
  static std::shared_ptr<const MaterialField> resolve(const MaterialMap& map, const CollisionWorld& world,
                                                      const ProxyParams& base);

  /// The blended properties around the proxy's centre `center` (world, m) for a tool of bounding
  /// radius `radius` (m): the weighted mean over the Gaussians whose centres lie within 2 radius
  /// (weights as in the file comment); the proxy's own where none are near. No allocation.
  /// `contact`: where the procedural reliefs are read (the proxy's contact point; NaN: not read).
  [[nodiscard]] MaterialBlend at(const CollisionWorld& world, const Eigen::Vector3d& center, double radius,
                                 const Eigen::Vector3d& contact = Eigen::Vector3d::Constant(
                                     std::numeric_limits<double>::quiet_NaN())) const noexcept;
  /// Ids: 0 (the proxy's own) and at most 254 materials.
  static constexpr std::size_t kMaxIds = 255;
  /// A weight (or share) per material id.
  using Weights = std::array<double, kMaxIds>;
  /// The materials of the Gaussians holding the proxy, `contacts` (slots of the world the field
  /// was resolved on), weighted by their opacities, as shares that sum to 1 (`shares` untouched
  /// and false when there are none). No allocation.
  bool contact_shares(std::span<const Contact> contacts, Weights& shares) const noexcept;
  /// The same for any weighted Gaussians: `for_each(add)` calls add(slot, weight) for each (world
  /// slot, weight >= 0), and is called twice (the total, then the shares); the seen proxy's
  /// layers weighted T_k alpha_k (SeenSolid::visit_hit_layers). No allocation.
  template <class ForEach>
  bool weighted_shares(ForEach&& for_each, Weights& shares) const noexcept {
    double total = 0;
    for_each([&](std::uint32_t, double w) { total += w; });
    if (!(total > 0)) return false;
    for (std::size_t id = 0; id < props_.size(); ++id) shares[id] = 0;
    for_each([&](std::uint32_t slot, double w) { shares[slot_material_[slot]] += w / total; });
    return true;
  }
  /// The properties of materials mixed by `w` (any non-negative weights; the proxy's own when all
  /// are 0), their procedural reliefs read at `contact` (NaN: not read). No allocation.
  [[nodiscard]] MaterialBlend blend(const Weights& w, const Eigen::Vector3d& contact) const noexcept;
  /// The material (id) with the largest opacity among the world slots `slots` (0 when none).
  [[nodiscard]] int dominant(std::span<const std::uint32_t> slots, const CollisionWorld& world) const noexcept;
  /// True when some material has a texture (a gain above 0).
  [[nodiscard]] bool textured() const noexcept { return textured_; }
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
  struct NodeMoments {
    double alpha = 0, alpha_c[3] = {0, 0, 0}, alpha_c2 = 0;  // sum alpha, sum alpha c, sum alpha |c|^2
    int material = -1;  // the one material of its Gaussians; -1: several
  };
  void build_moments(const CollisionWorld& world);
  static constexpr double kKernel = 2.0;      // tool radii: the blend's support rho
  std::vector<std::uint8_t> slot_material_;  // per world slot
  std::vector<NodeMoments> moments_;         // per BVH node
  std::vector<Props> props_;                 // id 0: the proxy's own
  std::vector<ProceduralTexture> textures_;  // per id
  bool textured_ = false;
  std::vector<std::string> names_;
  std::vector<std::size_t> counts_;
};

/// A proxy's materials along its path (ProxyRenderer, CompoundProxy): each tick in contact the
/// shares of the Gaussians holding it (MaterialField::contact_shares) are the target, and the
/// shares move toward it by 1 - exp(-ds / R) for a tangential slide ds of the proxy, R the tool's
/// scale; the first contact takes the target as it is. Also the forces a material adds: a
/// viscous drag on the device's tangential velocity and the texture (force/texture.h).
/// Threading: one thread; update() and add_forces() allocate, lock, log and throw nothing.
class MaterialFollower {
 public:
  /// `field` must not be null; `base`: the proxy's own parameters (the blend before any contact).
  MaterialFollower(std::shared_ptr<const MaterialField> field, const ProxyParams& base);
  /// One tick in contact: the proxy at `p` (world, m) with contact normal `n` (unit), held by
  /// `blockers`; `radius` the tool's scale (m); the procedural reliefs read at `contact`.
  const MaterialBlend& update(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double radius,
                              const Eigen::Vector3d& contact, std::span<const Contact> blockers) noexcept;
  /// update() with the target shares given (`target`: per material id, summing to 1; null when
  /// nothing holds the proxy this tick): the seen solid's layers at the hit (SeenProxy).
  const MaterialBlend& follow(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double radius,
                              const Eigen::Vector3d& contact, const MaterialField::Weights* target) noexcept;
  /// The coupling force `f` (N) with the material's viscous drag on `velocity` (m/s, the
  /// device's) and its texture at `contact` added: the relief's force along `n` and the friction
  /// it modulates, mu_k times that normal force against the device's tangential velocity v_t
  /// (scaled by |v_t| / max(|v_t|, 5 mm/s): none at rest), as Coulomb's law makes a bump resist
  /// more and a groove less (the lateral texture forces of Minsky et al. 1990, here from the
  /// normal force). The normal force stays >= 0 and |F| <= f_max. `dt` (s): the tick, for the
  /// vibration envelope (texture_rms()).
  [[nodiscard]] Eigen::Vector3d add_forces(const CollisionWorld& world, Eigen::Vector3d f, const Eigen::Vector3d& contact,
                                           const Eigen::Vector3d& n, const Eigen::Vector3d& velocity, double radius,
                                           double f_max, double dt) noexcept;
  /// add_forces() with the texture tip's height `tip` (m; TextureState::force) read by
  /// the caller on its own solid; read only when the blend has a texture (needs_tip()).
  [[nodiscard]] Eigen::Vector3d add_forces_at_tip(double tip, Eigen::Vector3d f, const Eigen::Vector3d& contact,
                                                  const Eigen::Vector3d& n, const Eigen::Vector3d& velocity,
                                                  double radius, double f_max, double dt) noexcept;
  /// True when add_forces_at_tip() reads its tip: the blend under the contact has a texture.
  [[nodiscard]] bool needs_tip() const noexcept { return blend_.texture_gain > 0; }
  /// The texture force's RMS over the last kVibrationWindow (exponential window), N: what a
  /// vibrotactile device (a VR controller) plays as the texture's vibration; 0 out of contact.
  [[nodiscard]] double texture_rms() const noexcept { return std::sqrt(texture_ms_); }
  /// The window of texture_rms(), s: about one display frame at 40-60 Hz, the rate a WebXR
  /// actuator takes pulses at.
  static constexpr double kVibrationWindow = 0.02;
  /// Below this tangential speed (m/s) the texture's friction fades out.
  static constexpr double kSlideSpeed = 0.005;
  /// Out of contact: the next contact starts from its own contacts' shares.
  void release() noexcept;
  [[nodiscard]] const MaterialBlend& blend() const noexcept { return blend_; }
  [[nodiscard]] const MaterialField& field() const noexcept { return *field_; }
  [[nodiscard]] const std::shared_ptr<const MaterialField>& shared_field() const noexcept { return field_; }

 private:
  std::shared_ptr<const MaterialField> field_;
  MaterialBlend blend_;
  MaterialField::Weights shares_{};
  Eigen::Vector3d at_ = Eigen::Vector3d::Zero();
  bool started_ = false;
  TextureState texture_;
  double texture_ms_ = 0;  // the texture force's mean square, N^2 (texture_rms)
};

}  // namespace gshaptics
