#pragma once
/// @file
/// The tool (haptic interaction point) as an ellipsoid in the world frame (paper Sec. III-B2).

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace gshaptics {

/// Tool ellipsoid {x : (x - center)^T Sigma_tool^-1 (x - center) <= 1} with
/// Sigma_tool = R diag(semi_axes^2) R^T. World frame; metres for a registered scene.
struct ToolEllipsoid {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  ///< unit quaternion
  Eigen::Vector3d semi_axes = Eigen::Vector3d::Constant(0.01);   ///< all > 0

  /// A spherical tool of radius `radius` at `center`.
  [[nodiscard]] static ToolEllipsoid sphere(const Eigen::Vector3d& center, double radius);

  /// True when every value is finite, semi-axes are > 0 and the quaternion is not zero.
  [[nodiscard]] bool valid() const noexcept;
  /// Radius of the bounding sphere (largest semi-axis), as in paper eq. 4.
  [[nodiscard]] double bounding_radius() const noexcept { return semi_axes.maxCoeff(); }
  /// Half-extents of the exact axis-aligned bounding box: sqrt(Sigma_tool_jj).
  [[nodiscard]] Eigen::Vector3d aabb_half_extent() const noexcept;
  /// The surface point whose outward normal is `n` (any non-zero direction, world frame):
  /// center + Sigma n / sqrt(n^T Sigma n), Sigma = R diag(semi_axes^2) R^T. m.
  [[nodiscard]] Eigen::Vector3d surface_point(const Eigen::Vector3d& n) const noexcept;
  /// A lower bound of the distance from `p` (world frame, m) to the surface when p is inside:
  /// (1 - |diag(1/a) R^T (p - center)|) a_min, which is exact for a sphere (the ellipsoid scaled
  /// by p's normalised radius lies inside it, at least (1 - that radius) a_min from its surface);
  /// 0 when p is not inside. The radius of a ball at p that lies within the tool. m.
  [[nodiscard]] double inner_clearance(const Eigen::Vector3d& p) const noexcept;
  /// True when the three semi-axes are equal (to 1e-12 relative): a sphere.
  [[nodiscard]] bool is_sphere() const noexcept { return is_sphere(semi_axes); }
  [[nodiscard]] static bool is_sphere(const Eigen::Vector3d& semi_axes) noexcept {
    return semi_axes.maxCoeff() - semi_axes.minCoeff() <= 1e-12 * semi_axes.maxCoeff();
  }
};

}  // namespace gshaptics
