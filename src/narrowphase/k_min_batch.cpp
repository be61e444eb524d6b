#include "gshaptics/narrowphase/k_min_batch.h"

#include "detail/newton_lane.h"

#include <Eigen/Core>
#include <cmath>

namespace gshaptics {

namespace {
constexpr int L = kBatchLanes;
// Largest certified distance of a reported K_min from the true minimum (the tolerance is 1e-5).
constexpr double kCertifiedGap = 1e-6;
}

BatchTool make_batch_tool(const Eigen::Matrix3d& R_tool, const Eigen::Vector3d& a_tool) noexcept {
  BatchTool t{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) t.rt[3 * i + j] = R_tool(j, i);
  for (int k = 0; k < 3; ++k) t.inv_a[k] = 1.0 / a_tool[k];
  t.inv_adj_a[0] = t.inv_a[1] * t.inv_a[2];
  t.inv_adj_a[1] = t.inv_a[0] * t.inv_a[2];
  t.inv_adj_a[2] = t.inv_a[0] * t.inv_a[1];
  t.inv_volume = t.inv_a[0] * t.inv_a[1] * t.inv_a[2];
  return t;
}

// One clone per instruction set; the loader picks the best the CPU has (GCC ifunc).
__attribute__((target_clones("avx512f", "avx2", "default")))
void k_min_batch(PairBatch& b, const BatchTool& t, bool stop_when_separated) noexcept {
  alignas(64) double q0[L], q1[L], q2[L], e1[L], e2[L], e3[L];
  // Coefficients (see pair_coefficients): in the tool frame d_t = R_t^T d and Q = R_t^T R_G;
  // v = inv_a * d_t, F_j = s_j inv_a * Q_j, G_j = sigma_j inv_adj_a * Q_j,
  // q2 = sum (sigma_j (Q_j . d_t) inv_volume)^2.
#pragma omp simd
  for (int l = 0; l < L; ++l) {
    // Written out (no inner loops) so that the lane loop is the only loop and vectorises.
    const double dx = b.dx[l], dy = b.dy[l], dz = b.dz[l];
    const double dtx = t.rt[0] * dx + t.rt[1] * dy + t.rt[2] * dz;
    const double dty = t.rt[3] * dx + t.rt[4] * dy + t.rt[5] * dz;
    const double dtz = t.rt[6] * dx + t.rt[7] * dy + t.rt[8] * dz;
    const double vx = t.inv_a[0] * dtx, vy = t.inv_a[1] * dty, vz = t.inv_a[2] * dtz;
    const double s0 = b.sx[l], s1 = b.sy[l], s2 = b.sz[l];
    const double sg0 = s1 * s2, sg1 = s0 * s2, sg2 = s0 * s1;
    double a1 = 0, a2 = 0, c1 = 0, c2 = 0;
#define GSH_AXIS(j, sj, sgj)                                                                   \
  {                                                                                           \
    const double qx = t.rt[0] * b.r[j][l] + t.rt[1] * b.r[3 + j][l] + t.rt[2] * b.r[6 + j][l]; \
    const double qy = t.rt[3] * b.r[j][l] + t.rt[4] * b.r[3 + j][l] + t.rt[5] * b.r[6 + j][l]; \
    const double qz = t.rt[6] * b.r[j][l] + t.rt[7] * b.r[3 + j][l] + t.rt[8] * b.r[6 + j][l]; \
    const double fx = sj * t.inv_a[0] * qx, fy = sj * t.inv_a[1] * qy, fz = sj * t.inv_a[2] * qz; \
    const double gx = sgj * t.inv_adj_a[0] * qx, gy = sgj * t.inv_adj_a[1] * qy,               \
                 gz = sgj * t.inv_adj_a[2] * qz;                                              \
    a1 += fx * fx + fy * fy + fz * fz;                                                        \
    a2 += gx * gx + gy * gy + gz * gz;                                                        \
    const double cx = fy * vz - fz * vy, cy = fz * vx - fx * vz, cz = fx * vy - fy * vx;      \
    c1 += cx * cx + cy * cy + cz * cz;                                                        \
    const double dg = (qx * dtx + qy * dty + qz * dtz) * sgj * t.inv_volume;                  \
    c2 += dg * dg;                                                                            \
  }
    GSH_AXIS(0, s0, sg0)
    GSH_AXIS(1, s1, sg1)
    GSH_AXIS(2, s2, sg2)
#undef GSH_AXIS
    q0[l] = vx * vx + vy * vy + vz * vz;
    q1[l] = c1;
    q2[l] = c2;
    e1[l] = a1;
    e2[l] = a2;
    const double det_f = s0 * s1 * s2 * t.inv_volume;
    e3[l] = det_f * det_f;
  }

  // Newton iterations in float (twice the lanes per instruction, cheaper divisions), then K_min
  // in double at the point found: phi is flat at its optimum, so a location good to ~1e-3 in
  // mu gives phi to ~1e-7 of its curvature there, and the double evaluation removes float's own
  // rounding. Float stops a lane as separated only with a margin (phi > 1 + 1e-3); near the
  // boundary the double value decides. The shared lane logic (detail/newton_lane.h) is
  // branch-free, so each loop over lanes is if-converted and vectorised.
  using Lim = detail::NewtonLimits<float>;
  alignas(64) float fq0[L], fq1[L], fq2[L], fe1[L], fe2[L], fe3[L];
  alignas(64) float mu[L], lo[L], hi[L], best_phi[L], best_mu[L], uphill[L], active[L], sep[L];
  const float want_sep = stop_when_separated ? 1.f : 0.f;
#pragma omp simd
  for (int l = 0; l < L; ++l) {
    fq0[l] = float(q0[l]);
    fq1[l] = float(q1[l]);
    fq2[l] = float(q2[l]);
    fe1[l] = float(e1[l]);
    fe2[l] = float(e2[l]);
    fe3[l] = float(e3[l]);
    mu[l] = detail::initial_mu<float>(fq0[l], fq1[l], fq2[l], fe1[l], fe2[l], fe3[l]);
    lo[l] = Lim::kMuMin;
    hi[l] = Lim::kMuMax;
    best_phi[l] = 0.f;
    best_mu[l] = mu[l];
    uphill[l] = float(detail::kUphillStep);
    active[l] = ((l < b.count) & (fq0[l] > 0)) ? 1.f : 0.f;  // coincident centres: K == 1
    sep[l] = 0.f;
  }
  for (int it = 0; it < detail::kMaxNewton; ++it) {
#pragma omp simd
    for (int l = 0; l < L; ++l)
      detail::newton_step<float>(mu[l], lo[l], hi[l], best_phi[l], best_mu[l], uphill[l], active[l],
                                 sep[l], fq0[l], fq1[l], fq2[l], fe1[l], fe2[l], fe3[l], want_sep,
                                 1e-3f);
    // Kept out of the loop above: an omp simd reduction there defeats GCC 12's vectoriser.
    bool any = false;
    for (int l = 0; l < L; ++l) any |= active[l] > 0;
    if (!any) break;
  }
  // Certificate in double. From the float point, one double Newton step (in t) polishes the
  // location; there phi' = dphi/dlambda gives, by concavity of phi in lambda, the tangent bound
  //   max phi <= phi(lambda') + |phi'| * (1 - lambda' if phi' > 0 else lambda').
  // A lane is accepted when that gap is below kCertifiedGap, so its K_min is within the gap of
  // the true minimum whatever the float iterations did. Otherwise (rare: flat splats whose phi
  // is flat over many e-folds of mu, where float curvature is noise) the lane is redone by the
  // scalar double search.
  alignas(64) double dmu[L], redo[L];
#pragma omp simd
  for (int l = 0; l < L; ++l) dmu[l] = mu[l];
#pragma omp simd
  for (int l = 0; l < L; ++l) {
    // Start from the last float point (a converged lane stays at or next to its best point; if
    // it did not, the certificate fails and the lane is redone).
    const double m_c = dmu[l];
    double p_c, dphi_c, phi_t, phi_tt;
    detail::derivatives<double>(q0[l], q1[l], q2[l], e1[l], e2[l], e3[l], m_c, p_c, dphi_c, phi_t, phi_tt);
    const double step = phi_tt < 0 ? detail::min_of<double>(detail::max_of<double>(-phi_t / phi_tt, -0.5), 0.5) : 0.0;
    const double m2 = m_c * detail::exp_small<double>(step);
    double p2, dphi2, t2, tt2;
    detail::derivatives<double>(q0[l], q1[l], q2[l], e1[l], e2[l], e3[l], m2, p2, dphi2, t2, tt2);
    const double lam2 = m2 / (1 + m2);
    const double dphi_dlambda = dphi2 * (1 + m2) * (1 + m2);
    const double gap = dphi_dlambda > 0 ? dphi_dlambda * (1 - lam2) : -dphi_dlambda * lam2;
    const double phi = detail::max_of<double>(p_c, p2);
    // A lane stopped as separated reports 1 - (largest phi it saw), a negative upper bound of
    // its K_min (as the scalar search does); its last iterate has moved on from that point.
    const double k_at = sep[l] > 0 ? 1.0 - double(best_phi[l]) : 1.0 - phi;
    b.k_min[l] = q0[l] > 0 ? k_at : 1.0;
    redo[l] = ((q0[l] > 0) & !(gap < kCertifiedGap)) ? 1.0 : 0.0;
  }
  for (int l = 0; l < L; ++l) {
    b.separated[l] = sep[l] > 0 ? 1 : 0;
    if (b.separated[l]) redo[l] = 0;
  }
  b.redone = 0;
  for (int l = 0; l < b.count; ++l) {
    if (redo[l] == 0) continue;
    ++b.redone;
    double lambda;
    bool separated;
    int iterations;
    b.k_min[l] = detail::newton_k_min({q0[l], q1[l], q2[l], e1[l], e2[l], e3[l]}, stop_when_separated,
                                      lambda, separated, iterations);
    b.separated[l] = separated ? 1 : 0;
  }
}

}  // namespace gshaptics
