#include "gshaptics/force/shaded_normal.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/broadphase/bvh.h"

namespace gshaptics {

Eigen::Vector3d shaded_normal(const CollisionWorld& world, const Eigen::Vector3d& c, double radius,
                              double kernel) noexcept {
  const double s = kernel * radius, s2 = s * s;
  const double half = radius + 3.0 * s;
  float lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = round_down_to_float(c[k] - half);
    hi[k] = round_up_to_float(c[k] + half);
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const CollisionGaussian* gs = world.gaussians().data();
  world.bvh().for_each_overlapping_leaf(lo, hi, [&](std::uint32_t first, std::uint32_t count) {
    for (std::uint32_t k = first; k < first + count; ++k) {
      const CollisionGaussian& g = gs[k];
      const Eigen::Vector3d d = c - Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
      // In the Gaussian's frame A = diag(a^2 + s^2): q = sum dl^2 / A, A^-1 d = R (dl / A).
      const Eigen::Matrix3d R = rotation_matrix(g);
      const Eigen::Vector3d dl = R.transpose() * d;
      Eigen::Vector3d ad;
      double q = 0;
      for (int j = 0; j < 3; ++j) {
        const double inv = 1.0 / (double(g.semi_axes[j]) * g.semi_axes[j] + s2);
        ad[j] = dl[j] * inv;
        q += dl[j] * ad[j];
      }
      if (q > 40) continue;
      const double an = ad.norm();
      if (!(an > 0)) continue;
      int jmin = 0;
      for (int j = 1; j < 3; ++j)
        if (g.semi_axes[j] < g.semi_axes[jmin]) jmin = j;
      const double a_min = g.semi_axes[jmin];
      const double a_mid = std::min(g.semi_axes[(jmin + 1) % 3], g.semi_axes[(jmin + 2) % 3]);
      const double flat = a_mid > 0 ? 1.0 - a_min / a_mid : 0.0;
      const Eigen::Vector3d axis = R.col(jmin) * (dl[jmin] >= 0 ? 1.0 : -1.0);
      const Eigen::Vector3d dir = flat * axis + (1.0 - flat) * (R * ad) / an;
      sum += (double(g.opacity) * std::exp(-0.5 * q)) * dir;
    }
  });
  const double n = sum.norm();
  return n > 0 && std::isfinite(n) ? Eigen::Vector3d(sum / n) : Eigen::Vector3d::Zero();
}

double shading_scale(const CollisionWorld& world, std::span<const Contact> blockers, double radius) noexcept {
  double scale = radius;
  for (const Contact& b : blockers) {
    const float* a = world.gaussians()[b.slot].semi_axes;
    scale = std::max(scale, double(std::max({std::min(a[0], a[1]), std::min(a[1], a[2]), std::min(a[0], a[2])})));
  }
  return scale;
}

}  // namespace gshaptics
