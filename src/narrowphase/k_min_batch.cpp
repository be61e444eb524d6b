#include "gshaptics/narrowphase/k_min_batch.h"

#include "detail/newton_lane.h"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <type_traits>

namespace gshaptics {

namespace {
constexpr int L = kBatchLanes;
constexpr int C = kBatchCapacity;
static_assert(C % L == 0);
// Largest certified distance of a reported K_min from the true minimum (the tolerance is 1e-5).
constexpr double kCertifiedGap = 1e-6;

// The lanes l < n whose flag is > 0, in order, into idx; returns their count. A block's flags
// become a bit mask, then only its set bits are visited: the selected lanes are the few
// unconverged or uncertified ones.
template <typename T>
inline int select_lanes(const T* flag, int n, int* idx) noexcept {
  int count = 0;
  for (int base = 0; base < n; base += L) {
    // A reduction the vectoriser takes (a compare, a blend of the lane bits, an OR tree): the
    // flags were just written by wide stores, which scalar loads of single lanes could not
    // forward from.
    std::uint32_t mask = 0;
#pragma omp simd reduction(| : mask)
    for (int j = 0; j < L; ++j) mask |= flag[base + j] > 0 ? (1u << j) : 0u;
    if (n - base < L) mask &= (1u << (n - base)) - 1u;
    while (mask != 0) {
      idx[count++] = base + __builtin_ctz(mask);
      mask &= mask - 1u;
    }
  }
  return count;
}

// One array of a lane copy: dst[j] = src[lane].
template <typename D, typename S>
struct LaneCopy {
  D* dst;
  const S* src;
};

// Packs the selected lanes into blocks of their own, every array in one loop: dst[j] =
// src[idx[j]] for j < count, and the padding lanes count <= j < pad copy lane idx[0] (a live
// lane: the padding computes nothing new and holds no NaN).
template <typename... Copies>
inline void pack_lanes(const int* idx, int count, int pad, Copies... c) noexcept {
  for (int j = 0; j < pad; ++j) {
    const int l = idx[j < count ? j : 0];
    ((c.dst[j] = static_cast<std::remove_reference_t<decltype(c.dst[0])>>(c.src[l])), ...);
  }
}
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
  t.sphere = a_tool[0] == a_tool[1] && a_tool[1] == a_tool[2];
  const Eigen::Quaterniond q = Eigen::Quaterniond(R_tool).normalized();
  t.qt[0] = q.w();
  t.qt[1] = -q.x();
  t.qt[2] = -q.y();
  t.qt[3] = -q.z();
  return t;
}

// One clone per instruction set; the loader picks the best the CPU has (GCC ifunc).
__attribute__((target_clones("avx512f", "avx2", "default")))
void k_min_batch(PairBatch& b, const BatchTool& t, bool stop_when_separated) noexcept {
  const int n = b.count < 0 ? 0 : (b.count > C ? C : b.count);
  const int n_pad = (n + L - 1) / L * L;
  // Padding lanes: coincident, unit Gaussians (inactive in the kernel, no NaN/denormals).
  for (int l = n; l < n_pad; ++l) {
    b.dx[l] = b.dy[l] = b.dz[l] = 0;
    b.q[0][l] = 1.f;
    b.q[1][l] = b.q[2][l] = b.q[3][l] = 0.f;
    b.sx[l] = b.sy[l] = b.sz[l] = 1;
  }
  // Every stage below loops over blocks of L lanes with a fixed-length inner loop, so each lane
  // runs through the same vector code whatever its position (no remainder loops).
  alignas(64) double q0[C], q1[C], q2[C], e1[C], e2[C], e3[C];
  if (t.sphere) {
    // A spherical tool of radius a (ia = 1/a): with the Gaussian's semi-axes and the offset in
    // its own frame, both in tool radii (u_j = s_j ia, w = R_G^T d ia), the coefficients of
    // pair_coefficients become positive sums:
    //   q0 = |w|^2, e1 = sum u_j^2, e2 = sum (u_k u_l)^2, e3 = (u_0 u_1 u_2)^2,
    //   q1 = sum_j u_j^2 (|w|^2 - w_j^2) = sum_j u_j^2 (w_k^2 + w_l^2),
    //   q2 = sum_j (u_k u_l)^2 w_j^2     ({j, k, l} = {0, 1, 2}),
    // because the tool's frame drops out (Q = R_t^T R_G only rotates v, and the Gaussian frame
    // is as good as the tool's). q0 is taken from d itself, the most direct value.
    const double ia = t.inv_a[0];
    for (int base = 0; base < n_pad; base += L) {
#pragma omp simd
      for (int j = 0; j < L; ++j) {
        const int l = base + j;
        const double dx = b.dx[l] * ia, dy = b.dy[l] * ia, dz = b.dz[l] * ia;
        // w = R_G^T d / a by the quaternion itself, without the matrix: with the same near-unit
        // correction s = 2 (2 - |q|^2) as rotation_from_quaternion, R = I + s (w [v]x + [v]x^2)
        // for q = (w, v), so R^T d = d + s (v x (v x d) - w (v x d)).
        const double qw = b.q[0][l], qx = b.q[1][l], qy = b.q[2][l], qz = b.q[3][l];
        const double s = 2 * (2 - (qw * qw + qx * qx + qy * qy + qz * qz));
        const double cx = qy * dz - qz * dy, cy = qz * dx - qx * dz, cz = qx * dy - qy * dx;  // v x d
        const double ex = qy * cz - qz * cy, ey = qz * cx - qx * cz, ez = qx * cy - qy * cx;  // v x (v x d)
        const double w0 = dx + s * (ex - qw * cx);
        const double w1 = dy + s * (ey - qw * cy);
        const double w2 = dz + s * (ez - qw * cz);
        const double u0 = b.sx[l] * ia, u1 = b.sy[l] * ia, u2 = b.sz[l] * ia;
        const double uu0 = u0 * u0, uu1 = u1 * u1, uu2 = u2 * u2;
        const double ww0 = w0 * w0, ww1 = w1 * w1, ww2 = w2 * w2;
        const double sg0 = uu1 * uu2, sg1 = uu0 * uu2, sg2 = uu0 * uu1;  // (u_k u_l)^2
        q0[l] = dx * dx + dy * dy + dz * dz;
        q1[l] = uu0 * (ww1 + ww2) + uu1 * (ww0 + ww2) + uu2 * (ww0 + ww1);
        q2[l] = sg0 * ww0 + sg1 * ww1 + sg2 * ww2;
        e1[l] = uu0 + uu1 + uu2;
        e2[l] = sg0 + sg1 + sg2;
        e3[l] = sg0 * uu0;
      }
    }
  } else {
  // Coefficients (see pair_coefficients): in the tool frame d_t = R_t^T d and Q = R_t^T R_G;
  // v = inv_a * d_t, F_j = s_j inv_a * Q_j, G_j = sigma_j inv_adj_a * Q_j,
  // q2 = sum (sigma_j (Q_j . d_t) inv_volume)^2.
  for (int base = 0; base < n_pad; base += L) {
#pragma omp simd
    for (int j = 0; j < L; ++j) {
      const int l = base + j;
      // Written out (no inner loops) so that the lane loop is the only loop and vectorises.
      const double dx = b.dx[l], dy = b.dy[l], dz = b.dz[l];
      // Q = R_t^T R_G straight from the quaternions: R(conj(q_t) q_G) = R(q_t)^T R(q_G), a
      // quaternion product (16 multiply-adds) instead of a 3x3 matrix product (27).
      const double gw = b.q[0][l], gx_ = b.q[1][l], gy_ = b.q[2][l], gz_ = b.q[3][l];
      const double pw = t.qt[0] * gw - t.qt[1] * gx_ - t.qt[2] * gy_ - t.qt[3] * gz_;
      const double px = t.qt[0] * gx_ + t.qt[1] * gw + t.qt[2] * gz_ - t.qt[3] * gy_;
      const double py = t.qt[0] * gy_ - t.qt[1] * gz_ + t.qt[2] * gw + t.qt[3] * gx_;
      const double pz = t.qt[0] * gz_ + t.qt[1] * gy_ - t.qt[2] * gx_ + t.qt[3] * gw;
      double m0, m1, m2, m3, m4, m5, m6, m7, m8;
      rotation_from_quaternion<double>(pw, px, py, pz, m0, m1, m2, m3, m4, m5, m6, m7, m8);
      const double Q[9] = {m0, m1, m2, m3, m4, m5, m6, m7, m8};
      const double dtx = t.rt[0] * dx + t.rt[1] * dy + t.rt[2] * dz;
      const double dty = t.rt[3] * dx + t.rt[4] * dy + t.rt[5] * dz;
      const double dtz = t.rt[6] * dx + t.rt[7] * dy + t.rt[8] * dz;
      const double vx = t.inv_a[0] * dtx, vy = t.inv_a[1] * dty, vz = t.inv_a[2] * dtz;
      const double s0 = b.sx[l], s1 = b.sy[l], s2 = b.sz[l];
      const double sg0 = s1 * s2, sg1 = s0 * s2, sg2 = s0 * s1;
      double a1 = 0, a2 = 0, c1 = 0, c2 = 0;
#define GSH_AXIS(j, sj, sgj)                                                                   \
  {                                                                                           \
    const double qx = Q[j], qy = Q[3 + j], qz = Q[6 + j];                                     \
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
  }
  }

  // Newton iterations in float (twice the lanes per instruction, cheaper divisions), then K_min
  // in double at the point found: phi is flat at its optimum, so a location good to ~1e-3 in
  // mu gives phi to ~1e-7 of its curvature there, and the double evaluation removes float's own
  // rounding. Float stops a lane as separated only with a margin (phi > 1 + 1e-3); near the
  // boundary the double value decides. The shared lane logic (detail/newton_lane.h) is
  // branch-free, so each loop over lanes is if-converted and vectorised.
  using Lim = detail::NewtonLimits<float>;
  alignas(64) float fq0[C], fq1[C], fq2[C], fe1[C], fe2[C], fe3[C];
  alignas(64) float mu[C], lo[C], hi[C], best_phi[C], uphill[C], active[C], sep[C];
  const float want_sep = stop_when_separated ? 1.f : 0.f;
  for (int base = 0; base < n_pad; base += L) {
#pragma omp simd
    for (int j = 0; j < L; ++j) {
      const int l = base + j;
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
      uphill[l] = float(detail::kUphillStep);
      active[l] = ((l < n) & (fq0[l] > 0)) ? 1.f : 0.f;  // coincident centres: K == 1
      sep[l] = 0.f;
    }
  }
  // The first steps for every lane, in place: on real scenes a third of the pairs converge in
  // one step and nine in ten in two (a step on a finished lane changes nothing).
  // Both steps of a block in one pass, so its state stays in registers between them.
  constexpr int kInPlaceSteps = 2;
  for (int base = 0; base < n_pad; base += L) {
#pragma omp simd
    for (int j = 0; j < L; ++j) {
      const int l = base + j;
      float unused_mu = 0.f;  // where the best phi was: not tracked (kTrackBestMu = false)
      for (int it = 0; it < kInPlaceSteps; ++it)
        detail::newton_step<float, false>(mu[l], lo[l], hi[l], best_phi[l], unused_mu, uphill[l], active[l],
                                          sep[l], fq0[l], fq1[l], fq2[l], fe1[l], fe2[l], fe3[l], want_sep,
                                          1e-3f);
    }
  }
  // The rest: the lanes still active, packed into blocks of their own and iterated together to
  // the end (the same step function; unused lanes of the last block are inactive copies of a
  // live lane, so they compute nothing new and hold no NaN). The blocks are independent, so
  // their iterations overlap in the CPU.
  alignas(64) int tail[C];
  const int n_tail = select_lanes(active, n, tail);
  b.tail = n_tail;
  if (n_tail > 0) {
    const int t_pad = (n_tail + L - 1) / L * L;
    alignas(64) float tq0[C], tq1[C], tq2[C], te1[C], te2[C], te3[C];
    alignas(64) float tmu[C], tlo[C], thi[C], tbp[C], tup[C], tact[C], tsep[C];
    pack_lanes(tail, n_tail, t_pad, LaneCopy{tq0, fq0}, LaneCopy{tq1, fq1}, LaneCopy{tq2, fq2}, LaneCopy{te1, fe1},
               LaneCopy{te2, fe2}, LaneCopy{te3, fe3}, LaneCopy{tmu, mu}, LaneCopy{tlo, lo}, LaneCopy{thi, hi},
               LaneCopy{tbp, best_phi}, LaneCopy{tup, uphill});
    // An active lane has not been stopped as separated, so the tail starts with sep = 0.
    for (int j = 0; j < t_pad; ++j) {
      tact[j] = j < n_tail ? 1.f : 0.f;
      tsep[j] = 0.f;
    }
    int live = t_pad;  // blocks past `live` are all inactive
    for (int it = kInPlaceSteps; it < detail::kMaxNewton && live > 0; ++it) {
      for (int base = 0; base < live; base += L) {
#pragma omp simd
        for (int j = base; j < base + L; ++j) {
          float unused_mu = 0.f;
          detail::newton_step<float, false>(tmu[j], tlo[j], thi[j], tbp[j], unused_mu, tup[j], tact[j], tsep[j],
                                            tq0[j], tq1[j], tq2[j], te1[j], te2[j], te3[j], want_sep, 1e-3f);
        }
      }
      // Kept out of the loop above: an omp simd reduction there defeats GCC 12's vectoriser.
      while (live > 0) {
        bool any = false;
        for (int j = live - L; j < live; ++j) any |= tact[j] > 0;
        if (any) break;
        live -= L;
      }
    }
    for (int j = 0; j < n_tail; ++j) {
      const int l = tail[j];
      mu[l] = tmu[j];
      best_phi[l] = tbp[j];
      sep[l] = tsep[j];
    }
  }
  // Certificate in double, by concavity of phi in lambda: at any lambda', with
  // phi' = dphi/dlambda there, the tangent bound
  //   max phi <= phi(lambda') + |phi'| * (1 - lambda' if phi' > 0 else lambda')
  // holds. A lane is accepted when that gap is below kCertifiedGap, so its K_min is within the
  // gap of the true minimum whatever the float iterations did.
  // Stage 1, every lane: phi and its slope at the last float point (three in four lanes of real
  // scenes are certified right there; a lane stopped as separated needs no certificate).
  // Stage 2, the others packed together: one double Newton step (in t) polishes the location
  // and the bound is taken there. A lane that still fails (rare: flat splats whose phi is flat
  // over many e-folds of mu, where float curvature is noise) is redone by the scalar double
  // search. With lambda = m / (1 + m): dphi/dlambda = dphi/dmu (1 + m)^2 and
  // 1 - lambda = 1 / (1 + m), so the bound's two cases need no division.
  // Which stage decides depends on the lane's own values only, so its result does not depend
  // on its position in the batch.
  alignas(64) double phi_c[C], redo[C];  // double, like the lane's other values: mixed widths defeat the vectoriser
  for (int base = 0; base < n_pad; base += L) {
#pragma omp simd
    for (int j = 0; j < L; ++j) {
      const int l = base + j;
      const double m_c = mu[l];
      double p_c, dphi_c;
      detail::phi_and_slope<double>(q0[l], q1[l], q2[l], e1[l], e2[l], e3[l], m_c, p_c, dphi_c);
      const double gap = dphi_c > 0 ? dphi_c * (1 + m_c) : -dphi_c * (1 + m_c) * m_c;
      // A lane stopped as separated reports 1 - (largest phi it saw), a negative upper bound of
      // its K_min (as the scalar search does); its last iterate has moved on from that point.
      const bool separated = sep[l] > 0;
      phi_c[l] = p_c;
      b.k_min[l] = q0[l] > 0 ? (separated ? 1.0 - double(best_phi[l]) : 1.0 - p_c) : 1.0;
      redo[l] = ((q0[l] > 0) & !(gap < kCertifiedGap) & !separated) ? 1.0 : 0.0;
    }
  }
  for (int l = 0; l < n; ++l) b.separated[l] = sep[l] > 0 ? 1 : 0;
  b.redone = 0;
  const int n_polish = select_lanes(redo, n, tail);
  if (n_polish > 0) {
    const int p_pad = (n_polish + L - 1) / L * L;
    alignas(64) double pq0[C], pq1[C], pq2[C], pe1[C], pe2[C], pe3[C], pmu[C], pphi[C], pk[C], predo[C];
    pack_lanes(tail, n_polish, p_pad, LaneCopy{pq0, q0}, LaneCopy{pq1, q1}, LaneCopy{pq2, q2}, LaneCopy{pe1, e1},
               LaneCopy{pe2, e2}, LaneCopy{pe3, e3}, LaneCopy{pmu, mu}, LaneCopy{pphi, phi_c});
    for (int base = 0; base < p_pad; base += L) {
#pragma omp simd
      for (int j = base; j < base + L; ++j) {
        const double m_c = pmu[j];
        double p_c, dphi_c, phi_t, phi_tt;
        detail::derivatives<double>(pq0[j], pq1[j], pq2[j], pe1[j], pe2[j], pe3[j], m_c, p_c, dphi_c, phi_t, phi_tt);
        // The polishing step only moves the point where the bound is evaluated, so its ratio
        // is taken in float (a cheap division); the bound itself is evaluated in double.
        const float step_f = float(-phi_t) / float(phi_tt);
        const double step = phi_tt < 0 ? detail::min_of<double>(detail::max_of<double>(double(step_f), -0.5), 0.5) : 0.0;
        const double m2 = m_c * detail::exp_small<double>(step);
        double p2, dphi2;
        detail::phi_and_slope<double>(pq0[j], pq1[j], pq2[j], pe1[j], pe2[j], pe3[j], m2, p2, dphi2);
        const double gap = dphi2 > 0 ? dphi2 * (1 + m2) : -dphi2 * (1 + m2) * m2;
        pk[j] = 1.0 - detail::max_of<double>(pphi[j], p2);
        predo[j] = gap < kCertifiedGap ? 0.0 : 1.0;
      }
    }
    for (int j = 0; j < n_polish; ++j) b.k_min[tail[j]] = pk[j];
    // Only a polished lane can still be uncertified: the scalar double search redoes it. (A
    // loop over the polished lanes, not over the batch: reading back the certificate's wide
    // stores one lane at a time stalled on store forwarding.)
    for (int j = 0; j < n_polish; ++j) {
      if (predo[j] == 0) continue;
      const int l = tail[j];
      ++b.redone;
      double lambda;
      bool separated;
      int iterations;
      b.k_min[l] = detail::newton_k_min({q0[l], q1[l], q2[l], e1[l], e2[l], e3[l]}, stop_when_separated,
                                        lambda, separated, iterations);
      b.separated[l] = separated ? 1 : 0;
    }
  }
  b.polished = n_polish;
}

}  // namespace gshaptics
