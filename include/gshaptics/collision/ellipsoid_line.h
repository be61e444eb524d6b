#pragma once
/// @file
/// Where a line leaves a tool ellipsoid, and where lines parallel to a push pass through its
/// shadow: the part's front over such a line, which the seen compound proxy's footprints
/// (force/seen_compound_proxy.h) and the seen-felt measure of a shaped tool (fidelity/seen_felt.h)
/// both read.

#include <Eigen/Core>

#include "gshaptics/collision/tool_ellipsoid.h"

namespace gshaptics {

/// The t at which the line p + t u (u unit; world frame, m) leaves `part` going along u: the
/// larger root of |diag(1/a) R^T (p + t u - c)|^2 = 1. NaN when the line misses the part.
/// Never allocates, locks, logs or throws.
[[nodiscard]] double exit_along(const ToolEllipsoid& part, const Eigen::Vector3d& p, const Eigen::Vector3d& u) noexcept;

/// exit_along() for many lines along one u through one posed part: the part's rotation and u in
/// its frame computed once (a footprint reads some hundred lines a tick). The same arithmetic as
/// exit_along(), so the same answers. Never allocates, locks, logs or throws.
class ExitAlong {
 public:
  ExitAlong(const ToolEllipsoid& part, const Eigen::Vector3d& u) noexcept;
  /// exit_along(part, p, u).
  [[nodiscard]] double operator()(const Eigen::Vector3d& p) const noexcept;

 private:
  Eigen::Matrix3d rt_;  // R^T
  Eigen::Vector3d center_, semi_axes_, wu_;  // wu = diag(1/a) R^T u
  double a_ = 0;                             // |wu|^2
};

/// A tool part's shadow along a push u (unit; world frame): the ellipse {L y : |y| <= 1} on the
/// plane across u (basis e1 = u.unitOrthogonal(), e2 = u x e1), L L^T the part's covariance
/// R diag(a^2) R^T projected on that plane (m^2). Points are offsets across u from the part's
/// centre (m). Never allocates, locks, logs or throws.
struct ToolShadow {
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX(), e2 = Eigen::Vector3d::UnitY();
  Eigen::Matrix2d l = Eigen::Matrix2d::Zero();  ///< lower-triangular Cholesky factor

  /// The point the unit disc's point `disc` (|disc| <= 1) maps to: the map is affine, so points
  /// uniform on the disc are uniform on the shadow.
  [[nodiscard]] Eigen::Vector3d at(const Eigen::Vector2d& disc) const noexcept;
  /// The shadow's boundary point in the direction cos(angle) e1 + sin(angle) e2 (rad).
  [[nodiscard]] Eigen::Vector3d boundary(double angle) const noexcept;
};

/// `part`'s shadow along u (unit). Never allocates, locks, logs or throws.
[[nodiscard]] ToolShadow shadow_along(const ToolEllipsoid& part, const Eigen::Vector3d& u) noexcept;

}  // namespace gshaptics
