#include "gshaptics/servo/passivity.h"
#include "gshaptics/servo/tick_log.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

double passivity_damping_cap(double option, double device) noexcept {
  const bool has_option = option > 0 && std::isfinite(option), has_device = device > 0 && std::isfinite(device);
  if (has_option && has_device) return std::min(option, device);
  if (has_option) return option;
  if (has_device) return device;
  return kDefaultPassivityMaxDamping;
}

PassivityController::PassivityController(const PassivityParams& params)
    : params_(params), cap_(passivity_damping_cap(params.max_damping, 0)), forces_(std::size_t(std::max(0, params.max_delay_ticks)) + 1, Eigen::Vector3d::Zero()) {}

void PassivityController::reset(int delay_ticks) noexcept {
  energy_ = 0;
  stale_ = 0;
  have_position_ = false;
  delay_ = std::clamp(delay_ticks, 0, int(forces_.size()) - 1);
  for (auto& f : forces_) f.setZero();
  newest_ = 0;
}

const Eigen::Vector3d& PassivityController::force_sent(int age) const noexcept {
  const std::size_t n = forces_.size();
  return forces_[(newest_ + n - std::size_t(age) % n) % n];
}

void PassivityController::sent(const Eigen::Vector3d& force) noexcept {
  newest_ = (newest_ + 1) % forces_.size();
  forces_[newest_] = force;
}

PassivityStep PassivityController::correct(const Eigen::Vector3d& force, const Eigen::Vector3d& velocity,
                                           double dt) const noexcept {
  PassivityStep out;
  out.force = force;
  // Free space stays free: no force, nothing to correct.
  if (!params_.enabled || !(dt > 0) || force.isZero(0)) return out;
  const double v2 = velocity.squaredNorm();
  const double fv = force.dot(velocity);
  // With this tick's force as it is, and the forces still in flight to the device (sent, not yet
  // paired with the motion they cause), each over one tick at this velocity.
  double given = fv * dt;  // what they would give the hand over the coming ticks, J (> 0: active)
  for (int age = 0; age < delay_; ++age) given += force_sent(age).dot(velocity) * dt;
  const double e = energy_ - given;
  if (!(e < 0) || !(v2 > params_.min_speed * params_.min_speed) || !std::isfinite(v2)) return out;
  double alpha = std::min(-e / (v2 * dt), cap_);
  // What the coming ticks would give, and a deficit run up in this contact, are dissipated in
  // full; a deficit carried over from before the contact (left at a release: stale_) is paid
  // back with at most the force's own magnitude on top, over as many ticks as that takes. Paid at
  // once it was a knock: on the Truck's stylus probe run (seed 7) a 9.5 mJ deficit left 8 s
  // earlier met a 1.2 N touch at 8 cm/s, asked for 1,317 N s/m and sent 30 N for 12 ms. (A
  // passivity controller's abrupt payback is the drawback Ryu, Preusche, Hannaford and Hirzinger
  // 2005 address with reference energy following; this bound is a simpler remedy.)
  const double fresh = std::max(0.0, given) - std::min(0.0, energy_ - stale_);
  alpha = std::min(alpha, fresh / (v2 * dt) + force.norm() / std::sqrt(v2));
  // Never pull: while the force pushes along the motion (unloading) the damping may cancel that
  // component at most; a deficit left over is paid back over the next ticks.
  if (fv > 0) alpha = std::min(alpha, fv / v2);
  out.damping = alpha;
  out.force = force - alpha * velocity;
  return out;
}

void PassivityController::account(const Eigen::Vector3d& position) noexcept {
  // The force acting at the device while it moved from the last read to this one.
  const Eigen::Vector3d& held = force_sent(delay_);
  if (have_position_ && held.allFinite()) {
    energy_ -= held.dot(position - last_position_);
    if (held.isZero(0) && energy_ > 0) energy_ = 0;  // the environment held nothing
    // The deficit carried out of the last contact, less what has been paid back since.
    stale_ = held.isZero(0) ? std::min(0.0, energy_) : std::max(stale_, std::min(0.0, energy_));
  }
  last_position_ = position;
  have_position_ = true;
}

ProxyStepWork proxy_step_work(std::span<const TickRecord> ticks) noexcept {
  ProxyStepWork work;
  for (std::size_t i = 1; i < ticks.size(); ++i) {
    const TickRecord& a = ticks[i - 1];
    const TickRecord& b = ticks[i];
    if (a.constraints == 0 || b.constraints == 0) continue;
    const double w = 0.5 * (a.desired + b.desired).dot(b.proxy - a.proxy);
    if (!std::isfinite(w)) continue;
    work.net += w;
    if (w > 0) work.stored += w;
  }
  return work;
}

}  // namespace gshaptics
