#include "gshaptics/force/shaded_normal.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/broadphase/bvh.h"

namespace gshaptics {

namespace {

// A disc whose own normal (its shortest axis, turned toward c) lies more than acos(kAgree) ~ 73
// deg from the outward estimate, and beyond whose rim c lies, turns (fully at 90 deg) to the
// direction from its nearest rim point to c, as far as that direction agrees better with the
// estimate (over kGain of cosine): across a convex edge the other face's discs then point out,
// while in a concave groove, where the rim direction would point into the floor, they keep their
// normal. Such a disc also loses weight with its distance past the rim, in units of kRimFalloff
// kernel widths: it is not the surface nearest to c.
constexpr double kAgree = 0.3;
constexpr double kGain = 0.2;
constexpr double kRimFalloff = 0.5;

// The weighted sum of the Gaussians' directions at c (see the header). `outward`: a first
// estimate of the unit normal, or zero for the first pass, in which every disc seen from beyond
// its rim takes the rim direction.
Eigen::Vector3d direction_sum(const CollisionWorld& world, const Eigen::Vector3d& c, double radius, double s,
                              const Eigen::Vector3d& outward) noexcept {
  const double s2 = s * s;
  const double half = radius + 3.0 * s;
  float lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = round_down_to_float(c[k] - half);
    hi[k] = round_up_to_float(c[k] + half);
  }
  const bool first_pass = outward.isZero(0);
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
      const int ju = (jmin + 1) % 3, jv = (jmin + 2) % 3;
      const double a_min = g.semi_axes[jmin];
      const double a_mid = std::min(g.semi_axes[ju], g.semi_axes[jv]);
      const double flat = a_mid > 0 ? 1.0 - a_min / a_mid : 0.0;
      Eigen::Vector3d axis = R.col(jmin) * (dl[jmin] >= 0 ? 1.0 : -1.0);
      double weight = double(g.opacity) * std::exp(-0.5 * q);
      const double agree = first_pass ? -1.0 : axis.dot(outward);
      const double eu = dl[ju] / g.semi_axes[ju], ev = dl[jv] / g.semi_axes[jv];
      const double rho = std::sqrt(eu * eu + ev * ev);  // > 1: c is beyond the disc's rim
      if (flat > 0 && agree < kAgree && rho > 1.0) {
        Eigen::Vector3d off;  // from the rim point on the ray toward c's projection, to c
        off[jmin] = dl[jmin];
        off[ju] = dl[ju] * (1.0 - 1.0 / rho);
        off[jv] = dl[jv] * (1.0 - 1.0 / rho);
        const Eigen::Vector3d rim = (R * off).normalized();
        double t = std::min(1.0, (kAgree - agree) / kAgree);
        if (!first_pass) t *= std::clamp((rim.dot(outward) - agree) / kGain, 0.0, 1.0);
        const Eigen::Vector3d blend = (1.0 - t) * axis + t * rim;
        const double bn = blend.norm();
        if (bn > 1e-9) axis = blend / bn;  // (off is never zero: c is past the rim)
        const double past = std::hypot(off[ju], off[jv]) / (kRimFalloff * s);
        weight *= std::exp(-0.5 * t * past * past);
      }
      const Eigen::Vector3d dir = flat * axis + (1.0 - flat) * (R * ad) / an;
      sum += weight * dir;
    }
  });
  return sum;
}

}  // namespace

Eigen::Vector3d shaded_normal(const CollisionWorld& world, const Eigen::Vector3d& c, double radius,
                              double kernel) noexcept {
  const double s = kernel * radius;
  const Eigen::Vector3d first = direction_sum(world, c, radius, s, Eigen::Vector3d::Zero());
  const double n1 = first.norm();
  if (!(n1 > 0) || !std::isfinite(n1)) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d sum = direction_sum(world, c, radius, s, first / n1);
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
