#include "gshaptics/force/support_normal.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>

namespace gshaptics {

namespace {

// S, its gradient and Hessian as a function on R^3 (gap_i extended homogeneously of degree 1).
struct Eval {
  double s = -INFINITY;
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
};

double support(const Eigen::Matrix3d& m, const Eigen::Vector3d& n, Eigen::Vector3d& mn) noexcept {
  mn = m * n;
  return std::sqrt(std::max(0.0, n.dot(mn)));
}

// The soft minimum alone (derivatives: `full`). The first kSupportPatchOnePass Gaussians'
// supports and gaps (EdgeNormal's whole patch) are computed once, for the minimum and then for
// the sum; any further ones twice.
Eval evaluate(const Eigen::Vector3d& cp, const Eigen::Matrix3d& mp, std::span<const PatchGaussian> patch,
              const Eigen::Vector3d& n, double tau, bool full) noexcept {
  Eval out;
  constexpr std::size_t kMax = kSupportPatchOnePass;
  std::array<double, kMax> gaps, sis;
  std::array<Eigen::Vector3d, kMax> mns;
  Eigen::Vector3d mpn, spare;
  const double sp = support(mp, n, mpn);
  double lo = INFINITY;
  for (std::size_t i = 0; i < patch.size(); ++i) {
    const PatchGaussian& q = patch[i];
    Eigen::Vector3d& mn = i < kMax ? mns[i] : spare;
    const double si = support(q.shape, n, mn), gap = n.dot(cp - q.center) - sp - si;
    if (i < kMax) sis[i] = si, gaps[i] = gap;
    lo = std::min(lo, gap);
  }
  if (!std::isfinite(lo)) return out;
  double z = 0;
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero(), gg = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d hp = Eigen::Matrix3d::Zero();
  if (full && sp > 0) hp = -(mp / sp - mpn * mpn.transpose() / (sp * sp * sp));
  for (std::size_t i = 0; i < patch.size(); ++i) {
    const PatchGaussian& q = patch[i];
    const double si = i < kMax ? sis[i] : support(q.shape, n, spare);
    const Eigen::Vector3d& mn = i < kMax ? mns[i] : spare;
    const double gap = i < kMax ? gaps[i] : n.dot(cp - q.center) - sp - si;
    const double e = q.weight * std::exp(-(gap - lo) / tau);
    z += e;
    if (!full) continue;
    Eigen::Vector3d gi = (cp - q.center) - (sp > 0 ? Eigen::Vector3d(mpn / sp) : Eigen::Vector3d::Zero());
    Eigen::Matrix3d hi = hp;
    if (si > 0) {
      gi -= mn / si;
      hi -= q.shape / si - mn * mn.transpose() / (si * si * si);
    }
    g += e * gi;
    h += e * hi;
    gg += e * gi * gi.transpose();
  }
  if (!(z > 0)) return out;
  out.s = lo - tau * std::log(z);
  if (full) {
    out.g = g / z;
    out.h = h / z - (gg / z - out.g * out.g.transpose()) / tau;
  }
  return out;
}

}  // namespace

Eigen::Matrix3d shape_matrix(const ToolEllipsoid& e) noexcept {
  const Eigen::Matrix3d r = e.rotation.normalized().toRotationMatrix();
  return r * e.semi_axes.array().square().matrix().asDiagonal() * r.transpose();
}

double support_gap(const ToolEllipsoid& part, const PatchGaussian& g, const Eigen::Vector3d& n) noexcept {
  Eigen::Vector3d mn;
  return n.dot(part.center - g.center) - support(shape_matrix(part), n, mn) - support(g.shape, n, mn);
}

SupportNormal support_normal(const ToolEllipsoid& part, std::span<const PatchGaussian> patch,
                             const Eigen::Vector3d& start, double tau) noexcept {
  SupportNormal out;
  const double len = start.norm();
  if (patch.empty() || !(len > 0) || !start.allFinite() || !(tau > 0)) return out;
  const Eigen::Vector3d cp = part.center;
  const Eigen::Matrix3d mp = shape_matrix(part);
  Eigen::Vector3d n = start / len;
  Eval cur = evaluate(cp, mp, patch, n, tau, true);
  if (!std::isfinite(cur.s)) return out;
  constexpr double kMaxStep = 0.25;   // rad
  constexpr double kConverged = 1e-6;  // rad
  constexpr int kMaxIterations = 16;
  for (int it = 0; it < kMaxIterations; ++it) {
    const Eigen::Vector3d u = n.unitOrthogonal(), v = n.cross(u);
    const Eigen::Vector2d r(u.dot(cur.g), v.dot(cur.g));
    // The Riemannian Hessian on the sphere: the tangent block minus (n . grad) I.
    Eigen::Matrix2d ht;
    ht << u.dot(cur.h * u), u.dot(cur.h * v), v.dot(cur.h * u), v.dot(cur.h * v);
    ht -= n.dot(cur.g) * Eigen::Matrix2d::Identity();
    Eigen::Vector2d step;
    const double det = ht.determinant();
    if (ht(0, 0) < 0 && det > 0) {
      step = -ht.inverse() * r;  // negative definite: the Newton step to the maximum
    } else {
      step = r.norm() > 0 ? Eigen::Vector2d(r / r.norm() * kMaxStep * 0.5) : Eigen::Vector2d::Zero();
    }
    double sn = step.norm();
    if (!(sn > kConverged) || !std::isfinite(sn)) break;
    if (sn > kMaxStep) {
      step *= kMaxStep / sn;
      sn = kMaxStep;
    }
    // The full step is tried with its derivatives (it is usually taken, and they are the next
    // step's); the backtracked ones without. (Its S is the same either way, bit for bit.)
    bool rose = false, full = false;
    Eval next;
    for (int back = 0; back < 8 && !rose; ++back, step *= 0.5) {
      const Eigen::Vector3d cand = (n + step.x() * u + step.y() * v).normalized();
      const Eval e = evaluate(cp, mp, patch, cand, tau, back == 0);
      if (e.s > cur.s) {
        n = cand;
        rose = true;
        full = back == 0;
        if (full) next = e;
      }
    }
    ++out.iterations;
    if (!rose) break;
    cur = full ? next : evaluate(cp, mp, patch, n, tau, true);
    if (sn < 1e-5) break;
  }
  out.normal = n;
  out.separation = cur.s;
  return out;
}

}  // namespace gshaptics
