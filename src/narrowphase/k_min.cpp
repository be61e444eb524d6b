#include "gshaptics/narrowphase/k_min.h"

#include "detail/newton_lane.h"

#include <algorithm>
#include <cmath>
#include <limits>

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


inline double phi_only(const PairCoefficients& c, double lambda) noexcept {
  const double b = lambda, a = 1.0 - lambda;
  const double g = a * a * c.q0 + a * b * c.q1 + b * b * c.q2;
  const double h = a * a * a + a * a * b * c.e1 + a * b * b * c.e2 + b * b * b * c.e3;
  return h > 0 ? a * b * g / h : 0.0;
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

  res.k_min = detail::newton_k_min(c, options.stop_when_separated, res.lambda,
                                   res.separated_early, res.iterations);
  return res;
}

}  // namespace gshaptics
