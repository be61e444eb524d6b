#include "gshaptics/force/virtual_coupling.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

double SpringEnergyBound::depth(const Eigen::Vector3d& e, const Eigen::Vector3d& n, double k) noexcept {
  const double d = e.dot(n);
  if (valid_) {
    // This tick's turn of the normal: the depth now against the depth along last tick's normal
    // (the proxy's own move since, and the device's, are rendered as they are), and the
    // rendered spring's energy V(d - withheld) either side of it.
    const double before = e.dot(normal_);
    const auto energy = [k](double x) { return x > 0 ? 0.5 * k * x * x : 0.0; };
    if (d >= before) {  // a rise: paid from the bank, the rest withheld
      const double cost = energy(d - withheld_) - energy(before - withheld_);
      if (cost <= bank_) {
        bank_ -= cost;
      } else {
        const double base = std::max(0.0, before - withheld_);
        withheld_ = d - std::sqrt(base * base + 2 * std::max(bank_, 0.0) / k);
        bank_ = 0;
      }
    } else {  // a fall: pays the withheld depth back first; what is left is rendered and banked
      const double was = energy(before - withheld_);
      withheld_ = std::max(0.0, withheld_ + d - before);
      // (A fall that the withheld depth absorbs whole banks 0, up to rounding: never below 0,
      // or the next rise's square root would read a negative bank as a NaN depth.)
      bank_ = std::max(0.0, bank_ + was - energy(d - withheld_));
    }
  }
  normal_ = n;
  valid_ = true;
  return d - withheld_;
}

Eigen::Vector3d VirtualCoupling::force_at_depth(double depth, const Eigen::Vector3d& e, const Eigen::Vector3d& n,
                                                const Eigen::Vector3d& velocity, double dt,
                                                std::span<const Contact> blockers, const FrictionStep& friction,
                                                double mu_k) noexcept {
  double k = k_;
  if (opacity_stiffness_ && !blockers.empty()) {
    double a = 0;
    for (const Contact& c : blockers) a += c.opacity;
    a /= double(blockers.size());
    const double beta = tau_ > 0 ? 1.0 - std::exp(-dt / tau_) : 1.0;
    opacity_ += beta * (a - opacity_);
    k *= opacity_;
  }
  const double fn = std::max(0.0, k * depth - b_ * velocity.dot(n));
  return clamp(coupling_force(fn, n, e, k, friction, mu_k));
}

Eigen::Vector3d VirtualCoupling::add_wall(const Eigen::Vector3d& f, const Eigen::Vector3d& wall,
                                          const Eigen::Vector3d& normal, const Eigen::Vector3d& offset,
                                          const Eigen::Vector3d& velocity, double dt) noexcept {
  Eigen::Vector3d w = wall - wall.dot(normal) * normal;
  const double len = w.norm();
  if (!(len > 1e-3)) return f;
  w /= len;
  if (!(offset.dot(w) > 0)) return f;
  return clamp(f + force_at_depth(offset.dot(w), offset, w, velocity, dt, {}, FrictionStep{}, 0.0));
}

}  // namespace gshaptics
