#pragma once
/// @file
/// The virtual coupling between the device and the proxy (one of the proxy renderer's four
/// parts): a spring-damper that turns the proxy-device offset into the force the hand gets.
/// Virtual coupling after Colgate, Stanley & Brown (1995); with one tick T of delay a sampled
/// spring k is passive for b > k T / 2 (Colgate & Schenkel 1997).
///
///   F_n = max(0, k e.n - b v.n) n           e = x_proxy - x_device, n the shaded normal
///   F   = F_n + k (e - (e.n) n)             while the friction cone sticks
///   F   = F_n - mu_k |F_n| slip_dir         while it slides
/// and |F| <= f_max. With `opacity_stiffness` k is scaled by the blocking Gaussians' mean
/// opacity, smoothed with time constant tau (paper eq. 9's opacity modulation on the proxy).
///
/// Threading: one thread; force() allocates, locks, logs and throws nothing.

#include <Eigen/Core>
#include <span>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/friction_cone.h"

namespace gshaptics {

/// The coupling's force for a normal force `fn` (N, >= 0) along the unit contact normal `n`, with
/// the friction cone's decision `friction` (Salisbury et al. 1995): fn n, plus the spring's
/// tangential part k (e - (e . n) n) while sticking (e: proxy - device, m; k: N/m), minus
/// mu_k fn along the sliding direction while sliding. World frame, N; no clamp. Shared by
/// VirtualCoupling and the compound proxy.
[[nodiscard]] inline Eigen::Vector3d coupling_force(double fn, const Eigen::Vector3d& n, const Eigen::Vector3d& e,
                                                    double k, const FrictionStep& friction, double mu_k) noexcept {
  Eigen::Vector3d f = fn * n;
  if (friction.sticking) f += k * (e - e.dot(n) * n);  // static friction: the spring's tangential part
  if (friction.sliding) f -= mu_k * fn * friction.slip_dir;  // kinetic friction: mu_k times the normal force
  return f;
}

class VirtualCoupling {
 public:
  /// `stiffness` k, N/m (> 0); `damping` b, N s/m (>= 0), along the normal; `f_max`, N (+inf:
  /// none); `opacity_stiffness` and `tau_opacity` (s) as ProxyParams. The caller validates.
  VirtualCoupling(double stiffness, double damping, double f_max, bool opacity_stiffness, double tau_opacity) noexcept
      : k_(stiffness), b_(damping), f_max_(f_max), opacity_stiffness_(opacity_stiffness), tau_(tau_opacity) {}

  /// The force on the device, N, world frame. `offset`: x_proxy - x_device, m; `normal`: unit
  /// contact normal (Gaussians -> tool); `velocity`: the device's, m/s; `dt`: tick, s;
  /// `blockers`: the Gaussians holding the proxy (for the opacity scaling); `friction`: this
  /// tick's friction decision; `mu_k`: the kinetic coefficient.
  Eigen::Vector3d force(const Eigen::Vector3d& offset, const Eigen::Vector3d& normal, const Eigen::Vector3d& velocity,
                        double dt, std::span<const Contact> blockers, const FrictionStep& friction,
                        double mu_k) noexcept;

  /// The proxy is free: the opacity smoothing starts again from 1.
  void release() noexcept { opacity_ = 1.0; }
  /// The smoothed opacity factor on k (1 without opacity stiffness).
  [[nodiscard]] double opacity_factor() const noexcept { return opacity_; }

 private:
  double k_, b_, f_max_;
  bool opacity_stiffness_;
  double tau_;
  double opacity_ = 1.0;
};

}  // namespace gshaptics
