#pragma once
// One lane of the K_min search, shared by the scalar k_min() and the batched kernel.
// Everything is branch-free (selects on doubles) so that a loop over lanes calling these
// functions is if-converted and vectorised.
//
// The search runs Newton on phi = 1 - K in t = ln(mu), mu = lambda / (1 - lambda) = b / a. In t
// the K-function of each axis is a bump of unit width centred at -ln(delta_j)/2, so flat
// (delta ~ 1e-12) and huge Gaussians converge as fast as round ones, and a and b are formed
// separately so that a = 1 - lambda keeps its relative precision when lambda -> 1. The sign of
// dphi/dt is that of dphi/dlambda, and phi is concave in lambda (Gilitschenski & Hanebeck), so
// the bracket [lo, hi] on mu always holds the optimum.

#include <cmath>

#include "gshaptics/narrowphase/k_min.h"

namespace gshaptics::detail {

inline constexpr double kMuMin = 1e-30, kMuMax = 1e30;  // bracket of mu
inline constexpr double kMaxStep = 8.0;                  // largest Newton step in ln(mu)
inline constexpr double kUphillStep = 2.0;               // first step where phi is convex in t
inline constexpr int kMaxNewton = 100;
// Stop when a Newton step changes phi by less than this: the step is still taken and its point
// evaluated, and quadratic convergence leaves an error of the order of its square (<< 1e-12).
inline constexpr double kConverged = 1e-11;

struct NewtonLane {
  double mu, lo, hi;  // current point and bracket (mu)
  double best_phi;    // largest phi seen (K_min = 1 - best_phi)
  double best_b;      // lambda where it was seen
  double uphill;      // current uphill step on convex stretches
  double active;      // 1: still iterating
  double separated;   // 1: some phi > 1 seen while stop_when_separated
};

// With a = 1 / (1 + mu), b = mu a, the homogeneous g and h give phi = a b g / h = N(mu) / D(mu):
//   N = mu (q0 + q1 mu + q2 mu^2),  D = (1 + e1 mu + e2 mu^2 + e3 mu^3) (1 + mu).
// Every coefficient is >= 0 and mu > 0, so Horner's rule has no cancellation, and phi with its
// derivatives costs one division.
inline double phi_at_mu(const PairCoefficients& c, double mu) noexcept {
  const double n = mu * (c.q0 + mu * (c.q1 + mu * c.q2));
  const double d = (1 + mu * (c.e1 + mu * (c.e2 + mu * c.e3))) * (1 + mu);
  return n / d;
}

// min/max as plain selects: std::fmin/fmax keep NaN rules that stop vectorisation.
inline double min_of(double x, double y) noexcept { return x < y ? x : y; }
inline double max_of(double x, double y) noexcept { return x > y ? x : y; }

inline double clamp_mu(double mu) noexcept { return min_of(max_of(mu, 2 * kMuMin), 0.5 * kMuMax); }

// exp(x) for |x| <= kMaxStep: degree-9 Taylor polynomial of exp(x / 16), squared four times
// (relative error < 1e-8, ample for a step length; no division).
inline double exp_small(double x) noexcept {
  const double y = x * (1.0 / 16);
  double p = 1.0 / 362880;
  p = p * y + 1.0 / 40320;
  p = p * y + 1.0 / 5040;
  p = p * y + 1.0 / 720;
  p = p * y + 1.0 / 120;
  p = p * y + 1.0 / 24;
  p = p * y + 1.0 / 6;
  p = p * y + 0.5;
  p = p * y + 1.0;
  p = p * y + 1.0;
  p *= p;
  p *= p;
  p *= p;
  p *= p;
  return p;
}

// Starts a lane at the best of three one-axis optima mu* = 1 / sqrt(delta) (exact for two
// spheres): delta along the offset (v^T M v / |v|^2), the smallest eigenvalue of M (~ e3 / e2;
// flat splats put the optimum there) and the largest (~ e1). Inactive when `enabled` is 0 or
// the centres coincide (K == 1 everywhere).
inline void newton_init(NewtonLane& s, const PairCoefficients& c, double enabled) noexcept {
  const double q0 = c.q0 > 0 ? c.q0 : 1.0;
  const double d_offset = max_of(c.q0 * c.e1 - c.q1, 0.0) / q0;
  const double d_small = c.e2 > 0 ? c.e3 / c.e2 : 0.0;
  const double m1 = clamp_mu(1.0 / std::sqrt(max_of(d_offset, 1e-300)));
  const double m2 = clamp_mu(1.0 / std::sqrt(max_of(d_small, 1e-300)));
  const double m3 = clamp_mu(1.0 / std::sqrt(max_of(c.e1, 1e-300)));
  const double p1 = phi_at_mu(c, m1), p2 = phi_at_mu(c, m2), p3 = phi_at_mu(c, m3);
  const double m12 = p2 > p1 ? m2 : m1, p12 = p2 > p1 ? p2 : p1;
  s.mu = p3 > p12 ? m3 : m12;
  s.lo = kMuMin;
  s.hi = kMuMax;
  s.best_phi = 0.0;
  s.best_b = 0.5;
  s.uphill = kUphillStep;
  s.active = ((enabled > 0) & (c.q0 > 0)) ? 1.0 : 0.0;
  s.separated = 0.0;
}

// One Newton step of an active lane (inactive lanes are left unchanged). Takes the lane's
// fields by reference (not the struct) so that loops over structure-of-arrays lanes vectorise.
inline void newton_step(double& s_mu, double& s_lo, double& s_hi, double& s_best_phi,
                        double& s_best_b, double& s_uphill, double& s_active, double& s_separated,
                        const PairCoefficients& c, double stop_when_separated) noexcept {
  const double mu = s_mu;
  // N, D and their mu-derivatives (see phi_at_mu).
  const double G = c.q0 + mu * (c.q1 + mu * c.q2), G1 = c.q1 + 2 * mu * c.q2, G2 = 2 * c.q2;
  const double H = 1 + mu * (c.e1 + mu * (c.e2 + mu * c.e3));
  const double H1 = c.e1 + mu * (2 * c.e2 + 3 * mu * c.e3), H2 = 2 * c.e2 + 6 * mu * c.e3;
  const double N = mu * G, N1 = G + mu * G1, N2 = 2 * G1 + mu * G2;
  const double D = H * (1 + mu), D1 = H1 * (1 + mu) + H, D2 = H2 * (1 + mu) + 2 * H1;
  const double inv_d = 1.0 / D;
  const double phi = N * inv_d;
  const double dphi = (N1 - phi * D1) * inv_d;                 // d phi / d mu
  const double d2phi = (N2 - 2 * dphi * D1 - phi * D2) * inv_d;  // d2 phi / d mu2
  // Derivatives in t = ln(mu).
  const double phi_t = mu * dphi, phi_tt = mu * dphi + mu * mu * d2phi;
  const double b = mu / (1 + mu);

  // Every field is read once and written once, unconditionally, from selects: conditional
  // stores would keep GCC from if-converting (and so vectorising) the loop over lanes.
  const double active = s_active, best_phi = s_best_phi, best_b = s_best_b, sep = s_separated;
  const double lo0 = s_lo, hi0 = s_hi, up0 = s_uphill;
  const bool act = active > 0;
  const bool better = act & (phi > best_phi);
  const bool now_sep = act & (stop_when_separated > 0) & (phi > 1.0);
  const double lo = dphi > 0 ? mu : lo0, hi = dphi > 0 ? hi0 : mu;
  // Where phi is convex in t, step uphill (doubling on long plateaus) instead of Newton.
  const bool newton_ok = phi_tt < 0;
  const double step_n = min_of(max_of(-phi_t / phi_tt, -kMaxStep), kMaxStep);
  const double step_u = phi_t > 0 ? up0 : -up0;
  const double dt = newton_ok ? step_n : step_u;
  const double uphill = newton_ok ? kUphillStep : min_of(2 * up0, kMaxStep);
  const double tried = mu * exp_small(dt);
  const double next = ((tried > lo) & (tried < hi)) ? tried : std::sqrt(lo * hi);
  const bool converged = (newton_ok & (std::fabs(dt * phi_t) < kConverged)) | (hi < lo * (1 + 1e-13));
  const double out_best_phi = better ? phi : best_phi;
  const double out_best_b = better ? b : best_b;
  const double out_sep = now_sep ? 1.0 : sep;
  const double out_lo = act ? lo : lo0;
  const double out_hi = act ? hi : hi0;
  const double out_mu = act ? next : mu;
  const double out_up = act ? uphill : up0;
  const double out_active = (act & !now_sep & !converged) ? 1.0 : 0.0;
  s_best_phi = out_best_phi;
  s_best_b = out_best_b;
  s_separated = out_sep;
  s_lo = out_lo;
  s_hi = out_hi;
  s_mu = out_mu;
  s_uphill = out_up;
  s_active = out_active;
}

inline void newton_step(NewtonLane& s, const PairCoefficients& c, double stop_when_separated) noexcept {
  newton_step(s.mu, s.lo, s.hi, s.best_phi, s.best_b, s.uphill, s.active, s.separated, c,
              stop_when_separated);
}

// K_min from a finished lane: the best phi seen, and phi at the last point unless separated.
inline double newton_finish(const NewtonLane& s, const PairCoefficients& c, double& lambda) noexcept {
  const double last = phi_at_mu(c, s.mu);
  const bool take_last = (s.separated == 0) & (last > s.best_phi);
  const double a = 1.0 / (1.0 + s.mu);
  lambda = take_last ? s.mu * a : s.best_b;
  const double phi = take_last ? last : s.best_phi;
  return c.q0 > 0 ? 1.0 - phi : 1.0;
}

}  // namespace gshaptics::detail
