#pragma once
/// @file
/// Coulomb friction on the proxy by a friction cone (one of the proxy renderer's four parts):
/// Salisbury, Brock, Massie, Swarup & Zilles (1995), "Haptic rendering: programming touch
/// interaction with force-feedback devices". While the device is inside the cone of half-angle
/// atan(mu) around the contact normal at the proxy, the proxy sticks; outside it, the proxy
/// slides, held mu_k times the depth behind the device along the sliding direction, for as long
/// as the device keeps moving on (kinetic friction needs relative motion).
///
/// Threading: one thread; update() allocates, locks, logs and throws nothing.

#include <Eigen/Core>

namespace gshaptics {

/// What the friction cone decides for one tick. World frame, m.
struct FrictionStep {
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();  ///< where the proxy solver should head
  Eigen::Vector3d slip_dir = Eigen::Vector3d::Zero();  ///< unit sliding direction (zero unless sliding)
  bool sticking = false;  ///< the proxy stays where it is (goal = proxy)
  bool sliding = false;   ///< kinetic friction acts along -slip_dir
};

class FrictionCone {
 public:
  /// Coefficients as ProxyParams::mu_s, mu_k (0 <= mu_k <= mu_s; mu_s = 0 turns friction off;
  /// the caller validates them).
  FrictionCone(double mu_s, double mu_k) noexcept : mu_s_(mu_s), mu_k_(mu_k) {}

  /// One tick. `in_contact`: the proxy held the device at the last tick, along the unit
  /// `normal` (Gaussians -> tool; zero when unknown). `device`, `proxy`: positions, m;
  /// `device_step`: the device's motion since the last tick, m; `radius`: the tool's bounding
  /// radius, m (a scale for "no tangential motion"). Without contact, friction or depth the goal
  /// is the device itself.
  FrictionStep update(bool in_contact, const Eigen::Vector3d& normal, const Eigen::Vector3d& device,
                      const Eigen::Vector3d& proxy, const Eigen::Vector3d& device_step, double radius) noexcept;

  /// Forget the sliding state (a new placement or a free proxy).
  void reset() noexcept { sliding_ = false; }
  [[nodiscard]] bool sliding() const noexcept { return sliding_; }
  [[nodiscard]] double mu_k() const noexcept { return mu_k_; }
  /// New coefficients from this tick on (a material under the contact; 0 <= mu_k <= mu_s).
  void set_coefficients(double mu_s, double mu_k) noexcept {
    mu_s_ = mu_s;
    mu_k_ = mu_k;
  }

 private:
  double mu_s_, mu_k_;
  bool sliding_ = false;
};

}  // namespace gshaptics
