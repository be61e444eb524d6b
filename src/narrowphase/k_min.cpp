#include "gshaptics/narrowphase/k_min.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

ToolFrame ToolFrame::from(const Eigen::Matrix3d& R_tool, const Eigen::Vector3d& a_tool) noexcept {
  ToolFrame f;
  f.rotation_t = R_tool.transpose();
  f.inv_a = a_tool.cwiseInverse();
  f.inv_adj_a = Eigen::Vector3d(f.inv_a.y() * f.inv_a.z(), f.inv_a.x() * f.inv_a.z(),
                                f.inv_a.x() * f.inv_a.y());
  f.inv_volume = f.inv_a.prod();
  return f;
}

PairCoefficients pair_coefficients(const ToolFrame& tool, const Eigen::Vector3d& d_world,
                                   const Eigen::Matrix3d& R_gauss,
                                   const Eigen::Vector3d& s_gauss) noexcept {
  // Tool normalisation L^-1 = diag(1/a) R_tool^T. M = F F^T with F = L^-1 R_gauss diag(s), and
  // adj(M) = G G^T with G = diag(1/(a_y a_z), ...) R_tool^T R_gauss diag(s_y s_z, ...), since
  // adj(XY) = adj(Y) adj(X) and the adjugate of a rotation is the rotation itself.
  const Eigen::Matrix3d Q = tool.rotation_t * R_gauss;  // Gaussian axes in the tool frame
  const Eigen::Vector3d v = tool.inv_a.cwiseProduct(tool.rotation_t * d_world);
  const Eigen::Vector3d sigma(s_gauss.y() * s_gauss.z(), s_gauss.x() * s_gauss.z(),
                              s_gauss.x() * s_gauss.y());
  // v^T adj(M) v = |diag(sigma) R_gauss^T d|^2 / (a_x a_y a_z)^2, because adj(L)^T L^-1 = I / det L.
  const Eigen::Vector3d dg = R_gauss.transpose() * d_world;

  PairCoefficients c;
  c.q0 = v.squaredNorm();
  for (int j = 0; j < 3; ++j) {
    const Eigen::Vector3d Fj = s_gauss[j] * tool.inv_a.cwiseProduct(Q.col(j));
    const Eigen::Vector3d Gj = sigma[j] * tool.inv_adj_a.cwiseProduct(Q.col(j));
    c.e1 += Fj.squaredNorm();
    c.e2 += Gj.squaredNorm();
    c.q1 += Fj.cross(v).squaredNorm();  // Lagrange: |F|^2 |v|^2 - (F.v)^2 without cancellation
    const double t = sigma[j] * dg[j] * tool.inv_volume;
    c.q2 += t * t;
  }
  const double det_f = s_gauss.prod() * tool.inv_volume;
  c.e3 = det_f * det_f;
  return c;
}

PairCoefficients pair_coefficients(const Eigen::Vector3d& d_world, const Eigen::Matrix3d& R_gauss,
                                   const Eigen::Vector3d& s_gauss, const Eigen::Matrix3d& R_tool,
                                   const Eigen::Vector3d& a_tool) noexcept {
  return pair_coefficients(ToolFrame::from(R_tool, a_tool), d_world, R_gauss, s_gauss);
}

namespace {

struct Eval {
  double phi, dphi, d2phi;  // phi = 1 - K and its derivatives in lambda
};

inline double phi_only(const PairCoefficients& c, double lambda) noexcept {
  const double b = lambda, a = 1.0 - lambda;
  const double g = a * a * c.q0 + a * b * c.q1 + b * b * c.q2;
  const double h = a * a * a + a * a * b * c.e1 + a * b * b * c.e2 + b * b * b * c.e3;
  return h > 0 ? a * b * g / h : 0.0;
}

inline Eval evaluate(const PairCoefficients& c, double lambda) noexcept {
  const double b = lambda, a = 1.0 - lambda;
  const double g = a * a * c.q0 + a * b * c.q1 + b * b * c.q2;
  const double dg = -2 * a * c.q0 + (a - b) * c.q1 + 2 * b * c.q2;
  const double d2g = 2 * (c.q0 - c.q1 + c.q2);
  const double h = a * a * a + a * a * b * c.e1 + a * b * b * c.e2 + b * b * b * c.e3;
  const double dh = -3 * a * a + (a * a - 2 * a * b) * c.e1 + (2 * a * b - b * b) * c.e2 +
                    3 * b * b * c.e3;
  const double d2h = 6 * a + (2 * b - 4 * a) * c.e1 + (2 * a - 4 * b) * c.e2 + 6 * b * c.e3;
  const double u = a * b, du = a - b;
  const double r = g / h;
  const double dr = (dg - r * dh) / h;
  const double d2r = (d2g - 2 * dr * dh - r * d2h) / h;
  return {u * r, du * r + u * dr, -2 * r + 2 * du * dr + u * d2r};
}

}  // namespace

double k_of_lambda(const PairCoefficients& c, double lambda) noexcept {
  return 1.0 - phi_only(c, lambda);
}

KMinResult k_min(const PairCoefficients& c, const KMinOptions& options) noexcept {
  KMinResult res;
  if (!(c.q0 > 0)) {  // coincident centres: K == 1 everywhere
    res.k_min = 1.0;
    return res;
  }
  if (options.minimiser == Minimiser::kGoldenSection) {
    constexpr double kInvPhi = 0.6180339887498949;
    double lo = 0, hi = 1;
    double x1 = hi - kInvPhi * (hi - lo), x2 = lo + kInvPhi * (hi - lo);
    double f1 = phi_only(c, x1), f2 = phi_only(c, x2);
    for (int i = 0; i < options.golden_iterations; ++i) {
      if (f1 > f2) {  // maximum of phi (minimum of K) lies in [lo, x2]
        hi = x2; x2 = x1; f2 = f1;
        x1 = hi - kInvPhi * (hi - lo); f1 = phi_only(c, x1);
      } else {
        lo = x1; x1 = x2; f1 = f2;
        x2 = lo + kInvPhi * (hi - lo); f2 = phi_only(c, x2);
      }
    }
    res.iterations = options.golden_iterations + 2;
    res.lambda = f1 > f2 ? x1 : x2;
    res.k_min = 1.0 - std::max(f1, f2);
    return res;
  }

  // Initial guess: exact for two spheres, lambda* = 1 / (1 + sqrt(delta)), with delta the
  // Gaussian's normalised variance along the offset direction.
  const double delta = std::max(c.q0 * c.e1 - c.q1, 0.0) / c.q0;  // = v^T M v / |v|^2
  double lambda = 1.0 / (1.0 + std::sqrt(delta));
  double lo = 0.0, hi = 1.0;  // phi' > 0 at lo, < 0 at hi
  double best = 0.0, best_lambda = lambda;
  constexpr int kMaxIterations = 60;
  int it = 0;
  for (; it < kMaxIterations; ++it) {
    const Eval e = evaluate(c, lambda);
    if (e.phi > best) { best = e.phi; best_lambda = lambda; }
    if (options.stop_when_separated && e.phi > 1.0) {
      res.k_min = 1.0 - e.phi;
      res.lambda = lambda;
      res.iterations = it + 1;
      res.separated_early = true;
      return res;
    }
    if (e.dphi > 0) lo = lambda; else hi = lambda;
    double next = (e.d2phi < 0) ? lambda - e.dphi / e.d2phi : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);  // safeguard: bisect the bracket
    const double step = next - lambda;
    lambda = next;
    // Converged when the step changes phi by less than ~1e-15 (quadratic convergence makes the
    // remaining error far smaller still) or the bracket is at machine resolution.
    if (std::fabs(step * e.dphi) < 1e-16 || hi - lo < 1e-15) { ++it; break; }
  }
  const double last = phi_only(c, lambda);
  if (last > best) { best = last; best_lambda = lambda; }
  res.k_min = 1.0 - best;
  res.lambda = best_lambda;
  res.iterations = it;
  return res;
}

}  // namespace gshaptics
