#include "gshaptics/force/force_model.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

namespace {

// exp(x) for the softmax of eq. 7, on eight values at once (GCC vector extension: one AVX-512
// register, two AVX2 or four SSE2 ones, by the clone). Contacts have K_min in (0, 1], so
// x = K - max K lies in (-1, 0]; there a degree-9 Taylor polynomial around -0.5 is exact to 3e-10
// relative and costs a few multiply-adds instead of a libm call (thousands of contacts per
// tick). x is clamped to that range (it cannot leave it for valid contacts).
using Lanes = double __attribute__((vector_size(8 * sizeof(double))));
constexpr int kLanes = 8;

// In place (a reference, not a 64-byte value, so no clone's calling convention is involved).
inline void softmax_exp(Lanes& x) noexcept {
  x = x < -1.0 ? Lanes{} - 1.0 : x;
  x = x > 0.0 ? Lanes{} : x;
  const Lanes y = x + 0.5;
  Lanes p = Lanes{} + 1.0 / 362880;  // 1/9!
  p = p * y + 1.0 / 40320;
  p = p * y + 1.0 / 5040;
  p = p * y + 1.0 / 720;
  p = p * y + 1.0 / 120;
  p = p * y + 1.0 / 24;
  p = p * y + 1.0 / 6;
  p = p * y + 0.5;
  p = p * y + 1.0;
  p = p * y + 1.0;
  x = 0.6065306597126334 * p;  // e^-0.5
}

struct WeightedSums {
  double w = 0, alpha = 0, x = 0, y = 0, z = 0;
};

// Softmax-weighted sums of eq. 7-9 over all contacts; vectorised, with one clone per instruction
// set picked at run time (like the narrow-phase kernel).
__attribute__((target_clones("avx512f", "avx2", "default")))
WeightedSums softmax_sums(const Contact* cs, std::size_t n) noexcept {
  double k_max = cs[0].k_min;
#pragma omp simd reduction(max : k_max)
  for (std::size_t i = 0; i < n; ++i) k_max = cs[i].k_min > k_max ? cs[i].k_min : k_max;
  // Eight contacts at a time, in eight lane sums (the contacts are an array of structures, so
  // the loads are scalar; the polynomial and the sums are not). The last block is padded with
  // weight-0 copies of the last contact.
  Lanes w_sum{}, alpha{}, px{}, py{}, pz{};
  for (std::size_t i = 0; i < n; i += kLanes) {
    Lanes k, x, y, z, a, valid;
    for (int l = 0; l < kLanes; ++l) {
      const Contact& c = cs[i + std::size_t(l) < n ? i + std::size_t(l) : n - 1];
      k[l] = c.k_min;
      x[l] = c.center.x();
      y[l] = c.center.y();
      z[l] = c.center.z();
      a[l] = double(c.opacity);
      valid[l] = i + std::size_t(l) < n ? 1.0 : 0.0;
    }
    Lanes w = k - k_max;
    softmax_exp(w);
    w *= valid;
    w_sum += w;
    px += w * x;
    py += w * y;
    pz += w * z;
    alpha += w * a;
  }
  WeightedSums sums;
  for (int l = 0; l < kLanes; ++l) {
    sums.w += w_sum[l];
    sums.alpha += alpha[l];
    sums.x += px[l];
    sums.y += py[l];
    sums.z += pz[l];
  }
  return sums;
}

}  // namespace

double ema_factor(double tau, double dt) noexcept {
  if (!(tau > 0)) return 1.0;
  if (!(dt > 0)) return 0.0;
  return 1.0 - std::exp(-dt / tau);
}

ForceOutput ForceModel::update(std::span<const Contact> contacts,
                               const Eigen::Vector3d& tool_center,
                               const Eigen::Vector3d& tool_velocity, double dt) noexcept {
  ForceOutput out;
  // The velocity filter tracks the tool whether or not it touches anything.
  if (tool_velocity.allFinite()) {
    if (!state_.has_velocity) {
      state_.v_filtered = tool_velocity;
      state_.has_velocity = true;
    } else {
      const double bv = ema_factor(params_.tau_velocity, dt);
      state_.v_filtered = bv * tool_velocity + (1 - bv) * state_.v_filtered;
    }
  }
  out.contacts = contacts.size();
  if (contacts.empty() || !tool_center.allFinite()) {  // N = 0: zero force, contact filters reset
    state_.in_contact = false;
    state_.has_normal = false;
    state_.alpha = 0;
    state_.n_smooth.setZero();
    return out;
  }

  // eq. 7-8: softmax over K_min (shifted by the max for stability), weighted centroid.
  const WeightedSums sums = softmax_sums(contacts.data(), contacts.size());
  const Eigen::Vector3d p_eff = Eigen::Vector3d(sums.x, sums.y, sums.z) / sums.w;
  const double alpha_raw = sums.alpha / sums.w;
  out.centroid = p_eff;

  const bool new_contact = !state_.in_contact;
  state_.in_contact = true;
  // Repulsive direction: from the contact centroid toward the tool centre.
  const Eigen::Vector3d to_tool = tool_center - p_eff;
  const double len = to_tool.norm();
  if (len > 1e-12) {
    const Eigen::Vector3d n_raw = to_tool / len;
    if (!state_.has_normal) {
      state_.n_smooth = n_raw;
      state_.has_normal = true;
    } else {
      const double bn = ema_factor(params_.tau_normal, dt);
      const Eigen::Vector3d blended = bn * n_raw + (1 - bn) * state_.n_smooth;
      const double bl = blended.norm();
      if (bl > 1e-12) state_.n_smooth = blended / bl;  // opposite vectors: keep the previous n
    }
  }
  // eq. 9: opacity EMA, reset to the raw value on a new contact.
  if (new_contact) {
    state_.alpha = alpha_raw;
  } else {
    const double ba = ema_factor(params_.tau_opacity, dt);
    state_.alpha = ba * alpha_raw + (1 - ba) * state_.alpha;
  }
  out.k_eff = params_.k_base * state_.alpha;
  out.elastic = out.k_eff * double(contacts.size());  // eq. 10
  if (!state_.has_normal) return out;  // centroid at the tool centre on first touch: no direction yet

  out.normal = state_.n_smooth;
  out.damping_along_normal = (-params_.damping * state_.v_filtered).dot(out.normal);
  out.magnitude = std::clamp(out.elastic + out.damping_along_normal, 0.0, params_.f_max);  // eq. 11
  out.force = out.magnitude * out.normal;
  return out;
}

}  // namespace gshaptics
