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

// phi at mu (no derivatives).
inline double phi_at_mu(const PairCoefficients& c, double mu) noexcept {
  const double a = 1.0 / (1.0 + mu), b = mu * a;
  const double g = a * a * c.q0 + a * b * c.q1 + b * b * c.q2;
  const double h = a * a * a + a * a * b * c.e1 + a * b * b * c.e2 + b * b * b * c.e3;
  return a * b * g / h;
}

// min/max as plain selects: std::fmin/fmax keep NaN rules that stop vectorisation.
inline double min_of(double x, double y) noexcept { return x < y ? x : y; }
inline double max_of(double x, double y) noexcept { return x > y ? x : y; }

inline double clamp_mu(double mu) noexcept { return min_of(max_of(mu, 2 * kMuMin), 0.5 * kMuMax); }

// exp(x) for |x| <= kMaxStep: Pade [2/2] of exp(x / 16), squared four times (rel. error < 1e-13).
inline double exp_small(double x) noexcept {
  const double y = x * (1.0 / 16), y2 = y * y;
  double p = (12 + 6 * y + y2) / (12 - 6 * y + y2);
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
  const double mu = s_mu, a = 1.0 / (1.0 + mu), b = mu * a;
  const double g = a * a * c.q0 + a * b * c.q1 + b * b * c.q2;
  const double dg = -2 * a * c.q0 + (a - b) * c.q1 + 2 * b * c.q2;
  const double d2g = 2 * (c.q0 - c.q1 + c.q2);
  const double h = a * a * a + a * a * b * c.e1 + a * b * b * c.e2 + b * b * b * c.e3;
  const double dh = -3 * a * a + (a * a - 2 * a * b) * c.e1 + (2 * a * b - b * b) * c.e2 +
                    3 * b * b * c.e3;
  const double d2h = 6 * a + (2 * b - 4 * a) * c.e1 + (2 * a - 4 * b) * c.e2 + 6 * b * c.e3;
  const double inv_h = 1.0 / h;
  const double u = a * b, du = a - b;
  const double r = g * inv_h;
  const double dr = (dg - r * dh) * inv_h;
  const double d2r = (d2g - 2 * dr * dh - r * d2h) * inv_h;
  const double phi = u * r, dphi = du * r + u * dr, d2phi = -2 * r + 2 * du * dr + u * d2r;
  // Derivatives in t = ln(mu): dlambda/dt = a b.
  const double phi_t = u * dphi, phi_tt = u * u * d2phi + du * u * dphi;

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
