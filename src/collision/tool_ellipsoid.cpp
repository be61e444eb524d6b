#include "gshaptics/collision/tool_ellipsoid.h"
#include "gshaptics/collision/ellipsoid_line.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

namespace gshaptics {

ToolEllipsoid ToolEllipsoid::sphere(const Eigen::Vector3d& center, double radius) {
  ToolEllipsoid t;
  t.center = center;
  t.semi_axes = Eigen::Vector3d::Constant(radius);
  return t;
}

bool ToolEllipsoid::valid() const noexcept {
  return center.allFinite() && semi_axes.allFinite() && rotation.coeffs().allFinite() &&
         semi_axes.minCoeff() > 0 && rotation.norm() > 1e-9;
}

Eigen::Vector3d ToolEllipsoid::aabb_half_extent() const noexcept {
  const Eigen::Matrix3d R = rotation.normalized().toRotationMatrix();
  const Eigen::Vector3d a2 = semi_axes.cwiseAbs2();
  return (R.cwiseAbs2() * a2).cwiseSqrt();
}

Eigen::Vector3d ToolEllipsoid::surface_point(const Eigen::Vector3d& n) const noexcept {
  const Eigen::Vector3d local = rotation.conjugate() * n;
  const Eigen::Vector3d scaled = local.cwiseProduct(semi_axes.cwiseProduct(semi_axes));
  const double s = std::sqrt(local.dot(scaled));
  return s > 0 ? Eigen::Vector3d(center + rotation * scaled / s) : center;
}

double ToolEllipsoid::inner_clearance(const Eigen::Vector3d& p) const noexcept {
  const Eigen::Vector3d local = rotation.conjugate() * (p - center);
  const double rho = local.cwiseQuotient(semi_axes).norm();
  return rho < 1.0 ? (1.0 - rho) * semi_axes.minCoeff() : 0.0;
}

ExitAlong::ExitAlong(const ToolEllipsoid& part, const Eigen::Vector3d& u) noexcept
    : rt_(part.rotation.toRotationMatrix().transpose()), center_(part.center), semi_axes_(part.semi_axes) {
  wu_ = (rt_ * u).cwiseQuotient(semi_axes_);
  a_ = wu_.squaredNorm();
}

double ExitAlong::operator()(const Eigen::Vector3d& p) const noexcept {
  const Eigen::Vector3d wo = (rt_ * (p - center_)).cwiseQuotient(semi_axes_);
  const double b = wo.dot(wu_), c = wo.squaredNorm() - 1;
  const double disc = b * b - a_ * c;
  if (!(disc >= 0)) return std::numeric_limits<double>::quiet_NaN();
  return (-b + std::sqrt(disc)) / a_;
}

double exit_along(const ToolEllipsoid& part, const Eigen::Vector3d& p, const Eigen::Vector3d& u) noexcept {
  return ExitAlong(part, u)(p);
}

ToolShadow shadow_along(const ToolEllipsoid& part, const Eigen::Vector3d& u) noexcept {
  ToolShadow sh;
  sh.e1 = u.unitOrthogonal();
  sh.e2 = u.cross(sh.e1);
  const Eigen::Matrix3d r = part.rotation.toRotationMatrix();
  const Eigen::Matrix3d sigma = r * part.semi_axes.cwiseAbs2().asDiagonal() * r.transpose();
  Eigen::Matrix2d s;
  s << sh.e1.dot(sigma * sh.e1), sh.e1.dot(sigma * sh.e2), sh.e2.dot(sigma * sh.e1), sh.e2.dot(sigma * sh.e2);
  sh.l = s.llt().matrixL();
  return sh;
}

Eigen::Vector3d ToolShadow::at(const Eigen::Vector2d& disc) const noexcept {
  const Eigen::Vector2d y = l * disc;
  return y.x() * e1 + y.y() * e2;
}

Eigen::Vector3d ToolShadow::boundary(double angle) const noexcept {
  // Along d, the boundary is L y with y = L^-1 d / |L^-1 d|.
  const Eigen::Vector2d d(std::cos(angle), std::sin(angle));
  const Eigen::Vector2d y = l.triangularView<Eigen::Lower>().solve(d);
  return at(y / y.norm());
}

}  // namespace gshaptics
