#include "gshaptics/servo/passivity.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

PassivityStep PassivityController::correct(const Eigen::Vector3d& force, const Eigen::Vector3d& velocity,
                                           double dt) const noexcept {
  PassivityStep out;
  out.force = force;
  // Free space stays free: no force, nothing to correct.
  if (!params_.enabled || !(dt > 0) || force.isZero(0)) return out;
  const double v2 = velocity.squaredNorm();
  const double fv = force.dot(velocity);
  const double e = energy_ - fv * dt;  // with this tick's force as it is
  if (!(e < 0) || !(v2 > params_.min_speed * params_.min_speed) || !std::isfinite(v2)) return out;
  double alpha = std::min(-e / (v2 * dt), params_.max_damping);
  // Never pull: while the force pushes along the motion (unloading) the damping may cancel that
  // component at most; a deficit left over is paid back over the next ticks.
  if (fv > 0) alpha = std::min(alpha, fv / v2);
  out.damping = alpha;
  out.force = force - alpha * velocity;
  return out;
}

void PassivityController::account(const Eigen::Vector3d& position) noexcept {
  if (have_position_ && last_force_.allFinite()) {
    energy_ -= last_force_.dot(position - last_position_);
    if (last_force_.isZero(0) && energy_ > 0) energy_ = 0;  // the environment held nothing
  }
  last_position_ = position;
  have_position_ = true;
}

}  // namespace gshaptics
