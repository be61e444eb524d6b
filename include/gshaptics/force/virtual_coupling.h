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
#include "gshaptics/force/proxy_params.h"

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

/// The energy bound on the shaded normal's turns. The coupling's spring acts along the contact
/// normal n, F = k d n with d = e . n (e = x_proxy - x_device): with the proxy and n fixed a
/// conservative field, which gives the hand back what it stored. But the normal is shaded (force
/// shading, Morgenbesser and Srinivasan 1996), and a shaded field is not the gradient of a
/// potential: each re-reading turns n under a loaded spring and changes the depth at the device's
/// fixed position from e . n_prev to e . n. A fall dissipates; a rise makes energy. On faces the
/// turns are small and cancel, but in a Gaussian crease the proxy creeps along the crease under
/// load, the field (which picks the nearer wall) turns by tens of degrees with it, and it does not
/// turn back the same way: a 60-degree groove's press gave back up to 12 mJ (bench/RESULTS.md,
/// twenty-sixth session). This renders the depth d - delta, delta >= 0, with an energy bank
/// B >= 0 (J), over each tick's turn from d' = e . n_prev to d = e . n, with V(x) = k/2 max(0, x)^2:
///   - a rise (d > d') costs V(d - delta) - V(d' - delta): paid from B while B lasts; past it,
///     delta grows so that the rendered energy rises by B exactly (B = 0);
///   - a fall pays delta back first (the force does not move); what is left of it lowers the
///     rendered energy, and that goes into B.
/// So the turns add no energy that earlier turns of the contact did not take out, and the force
/// is continuous across a withheld rise. The proxy's own moves (e - e_prev + the device's step,
/// along n_prev) are rendered as they are: they are the god-object following the Gaussians' bumps,
/// and bounding them too sank a slide's force by up to 17 % (bench/RESULTS.md). Where the turns'
/// rises outrun the bank, the force ends delta before the depth at which it began (measured in
/// bench/RESULTS.md). delta and B start at zero with each contact. The energy-bounding idea of Kim
/// and Ryu (2004, "Energy bounding algorithm based on passivity theorem for stable haptic
/// interaction control", there for the zero-order hold) with the energy tank of the passivity
/// observer (Hannaford and Ryu 2002), applied to force shading.
/// Threading: one thread; allocation-free and noexcept.
class SpringEnergyBound {
 public:
  /// The depth (m, along `normal`) to render this tick for the spring offset `offset` = x_proxy -
  /// x_device (m), the unit contact `normal` and the spring's stiffness `k` (N/m, > 0). World
  /// frame. offset . normal minus the withheld depth (>= 0); may be negative (no force).
  double depth(const Eigen::Vector3d& offset, const Eigen::Vector3d& normal, double k) noexcept;
  /// Out of contact: the next call starts a new contact (no withheld depth, an empty bank).
  void release() noexcept {
    valid_ = false;
    withheld_ = 0;
    bank_ = 0;
  }
  /// delta, m: the depth withheld now.
  [[nodiscard]] double withheld() const noexcept { return withheld_; }
  /// B, J: what the contact's turns dissipated and later ones may still spend.
  [[nodiscard]] double bank() const noexcept { return bank_; }

 private:
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero();
  double withheld_ = 0, bank_ = 0;
  bool valid_ = false;
};

/// The coupling of both proxies (ProxyRenderer and CompoundProxy's translation): the spring's
/// depth along the contact normal, bounded by SpringEnergyBound when ProxyParams::energy_bound is
/// on, and the force from it with damping, friction, the opacity-scaled stiffness and the clamp.
class VirtualCoupling {
 public:
  /// Reads stiffness k (N/m), damping b (N s/m, along the normal), opacity_stiffness,
  /// tau_opacity (s) and energy_bound of `params`; `f_max`, N (+inf: none). The caller validates.
  VirtualCoupling(const ProxyParams& params, double f_max) noexcept
      : k_(params.stiffness), b_(params.damping), f_max_(f_max), opacity_stiffness_(params.opacity_stiffness),
        tau_(params.tau_opacity), energy_bound_(params.energy_bound) {}

  /// The spring's depth to render along the unit contact `normal` for `offset` = x_proxy -
  /// x_device (m, world): offset . normal less what SpringEnergyBound withholds (energy_bound
  /// on; at this coupling's stiffness, opacity-scaled as at the last tick), else offset . normal.
  /// Call once a tick while in contact. m; may be negative (no force).
  double bounded_depth(const Eigen::Vector3d& offset, const Eigen::Vector3d& normal) noexcept {
    return energy_bound_ ? bound_.depth(offset, normal, k_ * opacity_) : offset.dot(normal);
  }

  /// The force on the device, N, world frame, for a spring of `depth` m along the unit contact
  /// `normal` (Gaussians -> tool): F_n = max(0, k depth - b v . n) n, plus friction (coupling_force:
  /// `offset` = x_proxy - x_device, m, gives the tangential spring while sticking), |F| <= f_max.
  /// `velocity`: the device's, m/s; `dt`: tick, s; `blockers`: the Gaussians holding the proxy
  /// (for the opacity scaling); `friction`: this tick's friction decision; `mu_k`: the kinetic
  /// coefficient.
  Eigen::Vector3d force_at_depth(double depth, const Eigen::Vector3d& offset, const Eigen::Vector3d& normal,
                                 const Eigen::Vector3d& velocity, double dt, std::span<const Contact> blockers,
                                 const FrictionStep& friction, double mu_k) noexcept;
  /// force_at_depth() at the depth offset . normal.
  Eigen::Vector3d force(const Eigen::Vector3d& offset, const Eigen::Vector3d& normal, const Eigen::Vector3d& velocity,
                        double dt, std::span<const Contact> blockers, const FrictionStep& friction,
                        double mu_k) noexcept {
    return force_at_depth(offset.dot(normal), offset, normal, velocity, dt, blockers, friction, mu_k);
  }

  /// `f` (the force along the contact's unit `normal`) plus the spring of a second plane the proxy
  /// stands against, a wall with outward unit normal `wall`: force_at_depth() along w, the part of
  /// `wall` that `normal` leaves out, when the device is past it (offset . w > 0); |F| <= f_max.
  /// A god-object on two planes (Zilles and Salisbury 1995): the seen proxies' wall across their
  /// contact's axis (seen_proxy.h, seen_compound_proxy.h). No friction on the wall.
  Eigen::Vector3d add_wall(const Eigen::Vector3d& f, const Eigen::Vector3d& wall, const Eigen::Vector3d& normal,
                           const Eigen::Vector3d& offset, const Eigen::Vector3d& velocity, double dt) noexcept;

  /// The force's bound, N (+inf: none).
  [[nodiscard]] double f_max() const noexcept { return f_max_; }
  /// `f` (N) scaled down to |f| <= f_max, its direction kept: the one clamp every force this
  /// coupling makes goes through (and a proxy's sum of the coupling and its own reaction).
  [[nodiscard]] Eigen::Vector3d clamp(const Eigen::Vector3d& f) const noexcept {
    const double m = f.norm();
    return m > f_max_ ? Eigen::Vector3d(f * (f_max_ / m)) : f;
  }
  /// The proxy is free: the opacity smoothing starts again from 1, the energy bound anew.
  void release() noexcept {
    opacity_ = 1.0;
    bound_.release();
  }
  /// New stiffness k (N/m, > 0) and damping b (N s/m, >= 0) from this tick on: a material under
  /// the contact (force/material.h).
  void set_gains(double k, double b) noexcept {
    k_ = k;
    b_ = b;
  }
  /// The smoothed opacity factor on k (1 without opacity stiffness).
  [[nodiscard]] double opacity_factor() const noexcept { return opacity_; }
  /// The depth the energy bound withholds now, m (SpringEnergyBound::withheld; 0 without contact).
  [[nodiscard]] double withheld() const noexcept { return bound_.withheld(); }

 private:
  double k_, b_, f_max_;
  bool opacity_stiffness_;
  double tau_;
  bool energy_bound_;
  double opacity_ = 1.0;
  SpringEnergyBound bound_;
};

}  // namespace gshaptics
