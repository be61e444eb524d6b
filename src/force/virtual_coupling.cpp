#include "gshaptics/force/virtual_coupling.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

Eigen::Vector3d VirtualCoupling::force(const Eigen::Vector3d& e, const Eigen::Vector3d& n,
                                       const Eigen::Vector3d& velocity, double dt, std::span<const Contact> blockers,
                                       const FrictionStep& friction, double mu_k) noexcept {
  double k = k_;
  if (opacity_stiffness_ && !blockers.empty()) {
    double a = 0;
    for (const Contact& c : blockers) a += c.opacity;
    a /= double(blockers.size());
    const double beta = tau_ > 0 ? 1.0 - std::exp(-dt / tau_) : 1.0;
    opacity_ += beta * (a - opacity_);
    k *= opacity_;
  }
  const double fn = std::max(0.0, k * e.dot(n) - b_ * velocity.dot(n));
  Eigen::Vector3d f = coupling_force(fn, n, e, k, friction, mu_k);
  const double fm = f.norm();
  if (fm > f_max_) f *= f_max_ / fm;
  return f;
}

}  // namespace gshaptics
