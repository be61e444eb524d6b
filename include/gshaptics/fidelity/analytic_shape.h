#pragma once
/// @file
/// Shapes with a known surface, the ground truth of the fidelity benchmark: signed distance,
/// the outward normals at every point (a normal cone at edges and corners), surface samples to
/// place Gaussians on, and contact sites to press at. World frame, metres.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <string_view>
#include <vector>

namespace gshaptics {

/// The benchmark shapes (sizes in metres; all centred on the origin, free space above z = 0 for
/// the open ones).
enum class ShapeKind {
  kPlane,      ///< 0.4 x 0.4 square at z = 0, normal +z (one-sided)
  kSphere,     ///< radius 0.1
  kCube,       ///< side 0.2, hollow shell: faces, 12 edges, 8 corners
  kPlate2mm,   ///< 0.3 x 0.3 plate 2 mm thick (z in [-1, 1] mm), both faces covered, hollow
  kPlate5mm,   ///< same, 5 mm thick
  kCylinder,   ///< radius 0.05 around the z axis, lateral surface, z in [-0.15, 0.15]
  kCorner90,   ///< concave 90-degree corner: floor z = 0 (x >= 0) and wall x = 0 (z >= 0), 0.2 deep
  kVGroove60,  ///< concave V-groove along y, 60-degree opening, bisector +z, faces 0.15 long
};

/// Every shape, in report order.
[[nodiscard]] const std::vector<ShapeKind>& all_shapes();
[[nodiscard]] std::string_view to_string(ShapeKind kind);
/// "plane", "sphere", "cube", "plate-2mm", "plate-5mm", "cylinder", "corner-90", "v-groove-60".
/// Throws InputError naming `source` for another name.
[[nodiscard]] ShapeKind parse_shape(std::string_view name, const std::string& source);

/// A point on the surface with its outward unit normal and one unit tangent.
struct SurfaceSample {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d tangent = Eigen::Vector3d::UnitX();
};

/// Where a face ends at a convex edge of the solid, seen from a point on the face: the outward
/// in-plane unit direction toward the edge and the distance to it, m.
struct FaceBorder {
  Eigen::Vector3d outward = Eigen::Vector3d::UnitX();
  double distance = 0;
};

/// The outward normals of the surface features nearest a point: one on a face, two at an edge
/// (convex or concave), three at a corner. Every direction in their non-negative span is a
/// correct contact normal there.
struct NormalCone {
  Eigen::Vector3d generators[3];
  int count = 0;
  /// Angle (degrees) between `direction` and the nearest direction of the cone; 0 inside it,
  /// 180 for the exact opposite of a single normal. `direction` must be non-zero.
  [[nodiscard]] double angle_deg(const Eigen::Vector3d& direction) const;
  /// The cone's central direction: the normalised sum of the generators.
  [[nodiscard]] Eigen::Vector3d axis() const;
};

/// Where a press happens: a surface point, the direction it is pressed along (the outward axis of
/// its normal cone) and what feature it is on.
struct ContactSite {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  std::string feature = "face";  ///< "face", "edge", "corner" (convex) or "concave"
};

class AnalyticShape {
 public:
  explicit AnalyticShape(ShapeKind kind);
  [[nodiscard]] ShapeKind kind() const noexcept { return kind_; }
  [[nodiscard]] std::string_view name() const noexcept { return to_string(kind_); }

  /// Signed distance of `p` from the surface: > 0 in free space, < 0 inside the solid (for the
  /// hollow cube and plates the solid is the full box). Exact near the surface, m.
  [[nodiscard]] double signed_distance(const Eigen::Vector3d& p) const;
  /// The normal cone of the surface point nearest `p` (features within `tolerance` m of the
  /// nearest one count as nearest).
  [[nodiscard]] NormalCone normal_cone(const Eigen::Vector3d& p, double tolerance = 1e-6) const;
  /// The directions the faces push a rigid sphere of `radius` m centred at `center` along: on a
  /// concave shape (corner-90, v-groove-60) the normals of every face the sphere reaches (within
  /// `radius` of its plane, the centre on the face's side of the other), so that in a concave
  /// corner it is the corner's cone as soon as the sphere touches both walls, the exact
  /// god-object's constraints (Zilles & Salisbury 1995); elsewhere, and where it reaches fewer
  /// than two faces, normal_cone(center). The slides score their force against it.
  [[nodiscard]] NormalCone sphere_cone(const Eigen::Vector3d& center, double radius) const;
  /// Points covering the surface at about `spacing` m apart (cell-centred grids on flat faces,
  /// a Fibonacci lattice on the sphere), with outward normals. Deterministic.
  [[nodiscard]] std::vector<SurfaceSample> sample_surface(double spacing) const;
  /// The convex edges a face sample (sample_surface()'s) lies between: on the faces of the cube
  /// and the plates, per in-plane axis the edge on the sample's side (the nearer one), written to
  /// `out`; returns 2 there and 0 on the other shapes, whose borders are open ends (the plane,
  /// the cylinder's rims, the concave shapes' far sides) or which have none (the sphere).
  int convex_borders(const SurfaceSample& sample, std::array<FaceBorder, 2>& out) const;
  /// Whether convex_borders() finds edges on this shape's faces (the cube and the plates).
  [[nodiscard]] bool has_convex_edges() const noexcept;
  /// `count` press sites drawn with `seed`: faces, and for the cube also edges and corners (about
  /// 40 % faces, 40 % edges, 20 % corners), for the corner and groove also the concave line;
  /// kept at least `margin` m from the boundary of the covered surface.
  [[nodiscard]] std::vector<ContactSite> press_sites(int count, std::uint64_t seed, double margin) const;
  /// The exact surface, for the JSON sidecar of a generated scene.
  [[nodiscard]] nlohmann::json describe() const;

 private:
  ShapeKind kind_;
};

}  // namespace gshaptics
