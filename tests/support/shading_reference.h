#pragma once
// A slow, scalar reading of the shaded normal (gshaptics/force/shaded_normal.h), written from
// the formulas in docs/design.md Sec. 7 with matrices, not from the library's lanes: q and the
// density gradient from A = R diag(a^2) R^T + s^2 I and its inverse, the two passes and the
// local linear fit summed one Gaussian after another. The candidates are the library's support:
// the Gaussians of the BVH leaves within s sqrt(q_cut) of the point; with `sampled` (the
// library's rule, kMaxKernelVisits), where they number more than kMaxKernelVisits, the slots
// that are multiples of the smallest power of two that brings them under it.

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/force/shaded_normal.h"

namespace gshaptics::test {

struct ReferenceTerm {
  Eigen::Vector3d axis, rim, grad, at;
  double weight, flat, past;
  bool beyond;
};

inline Eigen::Vector3d reference_shaded_normal(const CollisionWorld& world, const Eigen::Vector3d& c, double radius,
                                               double kernel, const FreeBall& ball = {}, double min_width = 0,
                                               double tail = kShadingTail, bool sampled = true) {
  constexpr double kAgree = 0.3, kGain = 0.2, kRimFalloff = 0.5, kFitFull = 0.95, kFitNone = 0.85, kFitRidge = 0.25;
  const double rim_scale = kernel * radius, s = std::max(rim_scale, min_width);
  const double q_cut = (1 + radius / s) * (1 + radius / s) + tail;
  const double reach = s * std::sqrt(q_cut);
  std::vector<std::uint32_t> slots;
  float lo[3], hi[3];
  for (int k = 0; k < 3; ++k) lo[k] = float(c[k] - 2 * reach), hi[k] = float(c[k] + 2 * reach);
  world.bvh().for_each_overlapping_leaf_node(lo, hi, [&](const BvhNode& leaf) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double e = std::max({double(leaf.lo[k]) - c[k], c[k] - double(leaf.hi[k]), 0.0});
      d2 += e * e;
    }
    if (d2 <= reach * reach * (1 + 1e-6))
      for (std::uint32_t k = leaf.first; k < leaf.first + leaf.count; ++k) slots.push_back(k);
    return true;
  });
  std::size_t stride = 1;
  while (sampled && slots.size() > kMaxKernelVisits * stride) stride *= 2;
  std::vector<ReferenceTerm> terms;
  for (std::uint32_t k : slots) {
    if (k % stride != 0) continue;
    const CollisionGaussian& g = world.gaussians()[k];
    const Eigen::Vector3d a(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
    const Eigen::Vector3d d = c - Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
    if (ball.radius > 0 && d.dot(ball.up) < kFloaterDepth * ball.radius &&
        d.norm() < ball.radius * (1 - 1e-3) + a.minCoeff())
      continue;  // a floater beside the resting tool
    const Eigen::Matrix3d R = rotation_matrix(g);
    const Eigen::Matrix3d A = R * a.cwiseAbs2().asDiagonal() * R.transpose() + s * s * Eigen::Matrix3d::Identity();
    const Eigen::Vector3d Ad = A.inverse() * d;
    const double q = d.dot(Ad);
    if (!(q <= q_cut) || !(Ad.norm() > 0)) continue;
    int j = 0;
    for (int m = 1; m < 3; ++m)
      if (a[m] < a[j]) j = m;
    std::array<double, 3> sorted{a[0], a[1], a[2]};
    std::sort(sorted.begin(), sorted.end());
    ReferenceTerm t;
    t.flat = sorted[1] > 0 ? 1 - sorted[0] / sorted[1] : 0;
    const Eigen::Vector3d dl = R.transpose() * d;
    t.axis = R.col(j) * (dl[j] >= 0 ? 1.0 : -1.0);
    t.weight = g.opacity * std::exp(-q / 2);
    if (ball.surface > 0 && t.flat > 0) {
      const double excess = (std::fabs(dl[j]) - ball.surface - 0.5 * rim_scale) / (0.5 * rim_scale);
      if (excess > 0) t.weight *= std::exp(-0.5 * t.flat * excess * excess);
      // A disc across the face under an overhang, centred behind that face's plane (FreeBall::face).
      if (!ball.face.isZero(0)) {
        const double margin = kOverhangMargin * ball.surface;
        const double across = std::clamp((kAgree - std::fabs(R.col(j).dot(ball.face))) / kAgree, 0.0, 1.0);
        const double behind = d.dot(ball.face) - ball.face_height;
        if (behind > margin) {
          const double e = (behind - margin) / margin;
          t.weight *= std::exp(-0.5 * t.flat * ball.face_strength * across * e * e);
        }
      }
    }
    t.grad = Ad.normalized();
    t.at = -d;
    // Beyond the rim of a disc: the in-plane offset in semi-axes over 1.
    Eigen::Vector3d in_plane = dl;
    in_plane[j] = 0;
    const double rho = in_plane.cwiseQuotient(a).norm();
    t.beyond = t.flat > 0 && rho > 1;
    t.rim = t.axis;
    t.past = 0;
    if (t.beyond) {
      Eigen::Vector3d off = in_plane * (1 - 1 / rho);
      off[j] = dl[j];
      t.rim = (R * off).normalized();
      t.past = (in_plane * (1 - 1 / rho)).norm() / (kRimFalloff * rim_scale);
    }
    terms.push_back(t);
  }
  // First pass: a disc seen from beyond its rim takes the rim direction.
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  for (const ReferenceTerm& t : terms) {
    const Eigen::Vector3d axis = t.beyond ? t.rim : t.axis;
    const double w = t.beyond ? t.weight * std::exp(-0.5 * t.past * t.past) : t.weight;
    first += w * (t.flat * axis + (1 - t.flat) * t.grad);
  }
  if (!(first.norm() > 0)) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d o = first.normalized();
  // Second pass and the local linear fit of the directions on the centres.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), fx = Eigen::Vector3d::Zero(), fn = Eigen::Vector3d::Zero();
  Eigen::Matrix3d fxx = Eigen::Matrix3d::Zero(), fxn = Eigen::Matrix3d::Zero();
  double weight = 0, fw = 0;
  for (const ReferenceTerm& t : terms) {
    const double agree = t.axis.dot(o);
    double tt = 0;
    if (t.beyond && agree < kAgree)
      tt = std::min(1.0, (kAgree - agree) / kAgree) * std::clamp((t.rim.dot(o) - agree) / kGain, 0.0, 1.0);
    const Eigen::Vector3d blend = (1 - tt) * t.axis + tt * t.rim;
    const Eigen::Vector3d axis = blend.norm() > 1e-9 ? Eigen::Vector3d(blend.normalized()) : t.axis;
    const double w = t.weight * std::exp(-0.5 * tt * t.past * t.past);
    const Eigen::Vector3d dir = t.flat * axis + (1 - t.flat) * t.grad;
    sum += w * dir;
    weight += w;
    const double fit = dir.norm() > 0 ? std::clamp((dir.dot(o) / dir.norm() - kFitNone) / (kFitFull - kFitNone), 0.0, 1.0) : 0.0;
    const double wf = fit * w;
    fw += wf;
    fx += wf * t.at;
    fn += wf * dir;
    fxx += wf * t.at * t.at.transpose();
    fxn += wf * t.at * dir.transpose();
  }
  Eigen::Vector3d out = sum;
  if (fw > 0 && weight > 0) {
    const Eigen::Vector3d m = fx / fw, nbar = fn / fw;
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - o * o.transpose();
    const double ridge = kFitRidge * s;
    const Eigen::Matrix3d C = P * (fxx / fw - m * m.transpose()) * P + ridge * ridge * Eigen::Matrix3d::Identity();
    const Eigen::Matrix3d B = fxn / fw - m * nbar.transpose();
    const double share = fw / weight;
    const Eigen::Vector3d corrected = sum - fw * share * share * (B.transpose() * C.inverse() * (P * m));
    if (corrected.allFinite()) out = corrected;
  }
  return out.norm() > 0 ? Eigen::Vector3d(out.normalized()) : Eigen::Vector3d::Zero();
}

}  // namespace gshaptics::test
