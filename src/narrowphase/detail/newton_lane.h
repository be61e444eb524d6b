#pragma once
// One lane of the K_min search, shared by the scalar k_min() (double) and the batched kernel
// (float iterations, double result). Everything is branch-free (selects only) so that a loop
// over lanes calling these functions is if-converted and vectorised.
//
// With mu = lambda / (1 - lambda) = b / a, the homogeneous g and h of k_min.h give
//   phi = 1 - K = a b g / h = N(mu) / D(mu),
//   N = mu (q0 + q1 mu + q2 mu^2),  D = (1 + e1 mu + e2 mu^2 + e3 mu^3) (1 + mu).
// Every coefficient is >= 0 and mu > 0, so Horner's rule has no cancellation, and phi with its
// derivatives costs one division. The search runs Newton on phi in t = ln(mu): there the
// K-function of each axis is a bump of unit width centred at -ln(delta_j)/2, so flat
// (delta ~ 1e-12) and huge Gaussians converge as fast as round ones. dphi/dt has the sign of
// dphi/dlambda, and phi is concave in lambda (Gilitschenski & Hanebeck), so the bracket
// [lo, hi] on mu always holds the optimum.

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "gshaptics/narrowphase/k_min.h"

namespace gshaptics::detail {

/// Limits of the search per floating-point type. The float bracket keeps mu^3 e3 finite; it
/// still holds the optimum unless a Gaussian is 1e-12 times thinner than the tool.
template <typename T>
struct NewtonLimits;
template <>
struct NewtonLimits<double> {
  static constexpr double kMuMin = 1e-30, kMuMax = 1e30;
  // Stop when a Newton step changes phi by less than this: the step is still taken and its
  // point evaluated, and quadratic convergence leaves an error of the order of its square.
  static constexpr double kConverged = 1e-11;
  static constexpr double kBracket = 1e-13;  // relative width of a collapsed bracket
};
template <>
struct NewtonLimits<float> {
  static constexpr float kMuMin = 1e-8f, kMuMax = 1e8f;  // mu^4 stays finite
  // The predicted change of the last step bounds the error of the best point seen (~half of
  // it), and the step itself lands far closer; the value is then evaluated in double.
  static constexpr float kConverged = 1e-5f;
  static constexpr float kBracket = 1e-5f;
};

inline constexpr double kMaxStep = 8.0;     // largest Newton step in ln(mu)
inline constexpr double kUphillStep = 2.0;  // first step where phi is convex in t
inline constexpr double kNewtonBasin = 0.5; // a converging Newton step is shorter than this in t
inline constexpr int kMaxNewton = 100;

// min/max as plain selects: std::fmin/fmax keep NaN rules that stop vectorisation.
template <typename T>
inline T min_of(T x, T y) noexcept { return x < y ? x : y; }
template <typename T>
inline T max_of(T x, T y) noexcept { return x > y ? x : y; }

template <typename T>
inline T clamp_mu(T mu) noexcept {
  return min_of<T>(max_of<T>(mu, 2 * NewtonLimits<T>::kMuMin), T(0.5) * NewtonLimits<T>::kMuMax);
}

// phi at mu (no derivatives).
template <typename T>
inline T phi_at_mu(T q0, T q1, T q2, T e1, T e2, T e3, T mu) noexcept {
  const T n = mu * (q0 + mu * (q1 + mu * q2));
  const T d = (1 + mu * (e1 + mu * (e2 + mu * e3))) * (1 + mu);
  return n / d;
}
inline double phi_at_mu(const PairCoefficients& c, double mu) noexcept {
  return phi_at_mu<double>(c.q0, c.q1, c.q2, c.e1, c.e2, c.e3, mu);
}

// exp(x) for |x| <= kMaxStep: degree-9 Taylor polynomial of exp(x / 16), squared four times
// (relative error < 1e-8, ample for a step length; no division).
template <typename T>
inline T exp_small(T x) noexcept {
  const T y = x * T(1.0 / 16);
  T p = T(1.0 / 362880);
  p = p * y + T(1.0 / 40320);
  p = p * y + T(1.0 / 5040);
  p = p * y + T(1.0 / 720);
  p = p * y + T(1.0 / 120);
  p = p * y + T(1.0 / 24);
  p = p * y + T(1.0 / 6);
  p = p * y + T(0.5);
  p = p * y + T(1.0);
  p = p * y + T(1.0);
  p *= p;
  p *= p;
  p *= p;
  p *= p;
  return p;
}

// The float search's exp(x), |x| <= kMaxStep: 2^n 2^f with x log2(e) = n + f, |f| <= 1/2, 2^f
// by its degree-6 Taylor polynomial and 2^n put straight into the exponent bits. Relative error
// < 1e-6 (mostly the rounding of x log2(e)): it only places the next iterate, whose phi is then
// evaluated where it landed. A shorter chain of dependent operations than exp_small's
// polynomial and squarings, which sits on every float Newton step's critical path. Branch-free
// and vectorisable (round, convert, integer add).
inline float exp_step(float x) noexcept {
  const float y = x * 1.44269504f;  // log2(e)
  const float n = std::nearbyint(y);
  const float f = (y - n) * 0.693147181f;  // (y - n) ln 2, |f| <= 0.347
  float p = 1.0f / 720;
  p = p * f + 1.0f / 120;
  p = p * f + 1.0f / 24;
  p = p * f + 1.0f / 6;
  p = p * f + 0.5f;
  p = p * f + 1.0f;
  p = p * f + 1.0f;
  return std::bit_cast<float>(std::bit_cast<std::int32_t>(p) + (static_cast<std::int32_t>(n) << 23));
}
template <typename T>
inline T exp_step_of(T x) noexcept {
  if constexpr (std::is_same_v<T, float>) return exp_step(x);
  else return exp_small<T>(x);
}

// The geometric bisection point of a bracket 0 < lo < hi. Float: the mean of the two bit
// patterns (unsigned: their sum fits), which, since a positive float's bits are a
// piecewise-linear log2 of its value, lies in [lo, hi] within 0.09 of the middle in log2 (an
// integer add and shift, where a square root sat on every step's critical path). Double:
// sqrt(lo hi).
template <typename T>
inline T log_midpoint(T lo, T hi) noexcept {
  if constexpr (std::is_same_v<T, float>)
    return std::bit_cast<float>((std::bit_cast<std::uint32_t>(lo) + std::bit_cast<std::uint32_t>(hi)) >> 1);
  else return std::sqrt(lo * hi);
}

// sqrt(num / den) for num, den > 0, within 9 %, clamped like clamp_mu<float>: a positive
// float's bit pattern is a piecewise-linear log2 of its value (as in log_midpoint), so half the
// difference of the two patterns, re-biased, is the square root of the ratio. Integer
// operations only: the float start point needs no more (Newton takes it from there), and this
// replaces two divisions and two square roots on the start's critical path.
inline float approx_sqrt_ratio(float num, float den) noexcept {
  constexpr std::int32_t kOne = 0x3f800000;  // 1.0f
  const std::int32_t lo = std::bit_cast<std::int32_t>(2 * NewtonLimits<float>::kMuMin);
  const std::int32_t hi = std::bit_cast<std::int32_t>(0.5f * NewtonLimits<float>::kMuMax);
  const std::int32_t r = kOne + ((std::bit_cast<std::int32_t>(num) - std::bit_cast<std::int32_t>(den)) >> 1);
  return std::bit_cast<float>(r < lo ? lo : (r > hi ? hi : r));
}

// The starting point: the better of two one-axis optima mu* = 1 / sqrt(delta) (exact for two
// spheres), with delta along the offset (v^T M v / |v|^2) and the smallest eigenvalue of M
// (~ e3 / e2; flat splats put the optimum there). A third guess from the largest eigenvalue
// (~ e1) never changed the iteration count on truck and karangkidul_crop pairs, so it is gone.
template <typename T>
inline T initial_mu(T q0, T q1, T q2, T e1, T e2, T e3) noexcept {
  if constexpr (std::is_same_v<T, float>) {
    // The same two candidates as below, from bit patterns (approx_sqrt_ratio).
    const float tiny = std::numeric_limits<float>::min();
    const float qq = q0 > 0 ? q0 : 1.0f;
    const float m1 = approx_sqrt_ratio(qq, max_of<float>(q0 * e1 - q1, tiny));
    const float m2 = e2 > 0 ? approx_sqrt_ratio(e2, max_of<float>(e3, tiny)) : 0.5f * NewtonLimits<float>::kMuMax;
    const float p1 = phi_at_mu<float>(q0, q1, q2, e1, e2, e3, m1);
    const float p2 = phi_at_mu<float>(q0, q1, q2, e1, e2, e3, m2);
    return p2 > p1 ? m2 : m1;
  } else {
    const T qq = q0 > 0 ? q0 : T(1);
    const T d_offset = max_of<T>(q0 * e1 - q1, 0) / qq;
    const T d_small = e2 > 0 ? e3 / e2 : T(0);
    const T tiny = std::numeric_limits<T>::min();
    const T m1 = clamp_mu<T>(1 / std::sqrt(max_of<T>(d_offset, tiny)));
    const T m2 = clamp_mu<T>(1 / std::sqrt(max_of<T>(d_small, tiny)));
    const T p1 = phi_at_mu<T>(q0, q1, q2, e1, e2, e3, m1);
    const T p2 = phi_at_mu<T>(q0, q1, q2, e1, e2, e3, m2);
    return p2 > p1 ? m2 : m1;
  }
}

// phi at mu, its mu-derivative, and its first two derivatives in t = ln(mu). At large mu the
// second derivative suffers cancellation (terms of order mu^2 |d2phi/dmu2| nearly cancel): in
// float it can be wrong on plateaus, which is why the batch verifies float results in double.
template <typename T>
inline void derivatives(T q0, T q1, T q2, T e1, T e2, T e3, T mu, T& phi, T& dphi, T& phi_t,
                        T& phi_tt) noexcept {
  const T G = q0 + mu * (q1 + mu * q2), G1 = q1 + 2 * mu * q2, G2 = 2 * q2;
  const T H = 1 + mu * (e1 + mu * (e2 + mu * e3));
  const T H1 = e1 + mu * (2 * e2 + 3 * mu * e3), H2 = 2 * e2 + 6 * mu * e3;
  const T N = mu * G, N1 = G + mu * G1, N2 = 2 * G1 + mu * G2;
  const T D = H * (1 + mu), D1 = H1 * (1 + mu) + H, D2 = H2 * (1 + mu) + 2 * H1;
  const T inv_d = 1 / D;
  phi = N * inv_d;
  dphi = (N1 - phi * D1) * inv_d;                        // d phi / d mu
  const T d2phi = (N2 - 2 * dphi * D1 - phi * D2) * inv_d;  // d2 phi / d mu2
  phi_t = mu * dphi;
  phi_tt = mu * dphi + mu * mu * d2phi;
}

// phi at mu and its mu-derivative only (the certificate's slope test).
template <typename T>
inline void phi_and_slope(T q0, T q1, T q2, T e1, T e2, T e3, T mu, T& phi, T& dphi) noexcept {
  const T G = q0 + mu * (q1 + mu * q2), G1 = q1 + 2 * mu * q2;
  const T H = 1 + mu * (e1 + mu * (e2 + mu * e3));
  const T H1 = e1 + mu * (2 * e2 + 3 * mu * e3);
  const T N = mu * G, N1 = G + mu * G1;
  const T D = H * (1 + mu), D1 = H1 * (1 + mu) + H;
  const T inv_d = 1 / D;
  phi = N * inv_d;
  dphi = (N1 - phi * D1) * inv_d;
}

// phi and the t-derivatives of psi = ln(phi), from positive sums only: with N = sum n_k mu^k and
// D = sum d_k mu^k, psi_t = E_N[k] - E_D[k] and psi_tt = Var_N[k] - Var_D[k] (the exponent's
// mean and variance under the weights n_k mu^k and d_k mu^k). Unlike phi_tt these keep their
// sign in float at large mu. Two divisions.
template <typename T>
inline void log_derivatives(T q0, T q1, T q2, T e1, T e2, T e3, T mu, T& phi, T& psi_t,
                            T& psi_tt) noexcept {
  const T m2 = mu * mu, m3 = m2 * mu, m4 = m3 * mu;
  const T n1 = q0 * mu, n2 = q1 * m2, n3 = q2 * m3;
  const T d1 = (1 + e1) * mu, d2 = (e1 + e2) * m2, d3 = (e2 + e3) * m3, d4 = e3 * m4;
  const T sn = n1 + n2 + n3, mn = n1 + 2 * n2 + 3 * n3, qn = n1 + 4 * n2 + 9 * n3;
  const T sd = 1 + d1 + d2 + d3 + d4, md = d1 + 2 * d2 + 3 * d3 + 4 * d4;
  const T qd = d1 + 4 * d2 + 9 * d3 + 16 * d4;
  const T inv_n = 1 / sn, inv_d = 1 / sd;
  const T an = mn * inv_n, ad = md * inv_d;
  phi = sn * inv_d;
  psi_t = an - ad;
  psi_tt = (qn * inv_n - an * an) - (qd * inv_d - ad * ad);
}

// One Newton step of an active lane; inactive lanes are left unchanged. Fields are passed by
// reference (not as a struct) and each is read once and written once, unconditionally: both
// keep GCC able to if-convert and vectorise a loop over structure-of-arrays lanes.
// `sep_margin`: a lane stops as separated when phi > 1 + sep_margin (float iterations use a
// margin; the final decision is then made in double). kTrackBestMu = false leaves s_best_mu
// alone (the batch kernel never reads where the best phi was, only its value).
template <typename T, bool kTrackBestMu = true>
inline void newton_step(T& s_mu, T& s_lo, T& s_hi, T& s_best_phi, T& s_best_mu, T& s_uphill,
                        T& s_active, T& s_separated, T q0, T q1, T q2, T e1, T e2, T e3,
                        T stop_when_separated, T sep_margin) noexcept {
  using Lim = NewtonLimits<T>;
  const T mu = s_mu;
  // Newton on psi = ln(phi) in t: same maximiser, same sign of the slope, no cancellation.
  T phi, psi_t, psi_tt;
  log_derivatives<T>(q0, q1, q2, e1, e2, e3, mu, phi, psi_t, psi_tt);

  const T active = s_active, best_phi = s_best_phi, best_mu = s_best_mu, sep = s_separated;
  const T lo0 = s_lo, hi0 = s_hi, up0 = s_uphill;
  const bool act = active > 0;
  const bool better = act & (phi > best_phi);
  const bool now_sep = act & (stop_when_separated > 0) & (phi > 1 + sep_margin);
  const T lo = psi_t > 0 ? mu : lo0, hi = psi_t > 0 ? hi0 : mu;
  // Where psi is convex in t, step uphill (doubling on long plateaus) instead of Newton.
  const bool newton_ok = psi_tt < 0;
  const T step_n = min_of<T>(max_of<T>(-psi_t / psi_tt, T(-kMaxStep)), T(kMaxStep));
  const T step_u = psi_t > 0 ? up0 : -up0;
  const T dt = newton_ok ? step_n : step_u;
  const T uphill = newton_ok ? T(kUphillStep) : min_of<T>(2 * up0, T(kMaxStep));
  const T tried = mu * exp_step_of<T>(dt);
  const bool in_bracket = (tried > lo) & (tried < hi);
  // Converged: a small Newton step that changes phi (= phi * psi change) by less than
  // kConverged. The step-size condition matters on plateaus (flat splats started far out):
  // there the slope and curvature are both tiny, so the predicted change is tiny although the
  // optimum is many e-folds away.
  const bool converged =
      (newton_ok & (std::fabs(dt) < T(kNewtonBasin)) & (std::fabs(dt * psi_t) * phi < Lim::kConverged)) |
      (hi < lo * (1 + Lim::kBracket));
  // Outside the bracket: bisect geometrically, unless converged (then stay: a bisection step
  // would throw the lane far from its optimum).
  const T next = in_bracket ? tried : (converged ? mu : log_midpoint<T>(lo, hi));
  const T out_best_phi = better ? phi : best_phi;
  const T out_best_mu = better ? mu : best_mu;
  const T out_sep = now_sep ? T(1) : sep;
  const T out_lo = act ? lo : lo0;
  const T out_hi = act ? hi : hi0;
  const T out_mu = act ? next : mu;
  const T out_up = act ? uphill : up0;
  const T out_active = (act & !now_sep & !converged) ? T(1) : T(0);
  s_best_phi = out_best_phi;
  if constexpr (kTrackBestMu) s_best_mu = out_best_mu;
  s_separated = out_sep;
  s_lo = out_lo;
  s_hi = out_hi;
  s_mu = out_mu;
  s_uphill = out_up;
  s_active = out_active;
}

// Scalar driver (double throughout), used by k_min(): returns K_min and where it was found.
inline double newton_k_min(const PairCoefficients& c, bool stop_when_separated, double& lambda,
                           bool& separated, int& iterations) noexcept {
  if (!(c.q0 > 0)) {  // coincident centres: K == 1 everywhere
    lambda = 0.5;
    separated = false;
    iterations = 0;
    return 1.0;
  }
  double mu = initial_mu<double>(c.q0, c.q1, c.q2, c.e1, c.e2, c.e3);
  double lo = NewtonLimits<double>::kMuMin, hi = NewtonLimits<double>::kMuMax;
  double best_phi = 0, best_mu = mu, uphill = kUphillStep, active = 1, sep = 0;
  int it = 0;
  while (active > 0 && it < kMaxNewton) {
    newton_step<double>(mu, lo, hi, best_phi, best_mu, uphill, active, sep, c.q0, c.q1, c.q2,
                        c.e1, c.e2, c.e3, stop_when_separated ? 1.0 : 0.0, 0.0);
    ++it;
  }
  iterations = it;
  separated = sep > 0;
  const double last = phi_at_mu(c, mu);
  const bool take_last = !separated && last > best_phi;
  const double m = take_last ? mu : best_mu;
  lambda = m / (1 + m);
  return 1.0 - (take_last ? last : best_phi);
}

}  // namespace gshaptics::detail
