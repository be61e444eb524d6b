#include "gshaptics/servo/safety.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

namespace {

// Scales `v` down to length `limit` (same direction); true when it had to.
bool clamp_length(Eigen::Vector3d& v, double limit) noexcept {
  const double n = v.norm();
  if (!(n > limit)) return false;
  v *= limit / n;
  return true;
}

// Moves `target` back toward `last` so it is at most `max_step` from it; true when it had to.
bool limit_step(Eigen::Vector3d& target, const Eigen::Vector3d& last, double max_step) noexcept {
  Eigen::Vector3d step = target - last;
  if (!clamp_length(step, max_step)) return false;
  target = last + step;
  return true;
}

}  // namespace

void SafetyFilter::set_device_limits(double peak, double continuous) noexcept {
  device_peak_ = peak > 0 ? peak : std::numeric_limits<double>::infinity();
  continuous_ = continuous > 0 ? continuous : std::numeric_limits<double>::infinity();
  f_max_ = std::min(option_f_max_, device_peak_);
}

void SafetyFilter::set_device_torque_limit(double peak) noexcept {
  tau_max_ = peak > 0 ? std::min(params_.tau_max, peak) : params_.tau_max;
}

ForceLimits SafetyFilter::limits() const noexcept {
  ForceLimits l;
  l.f_max = f_max_;
  l.option_f_max = option_f_max_;
  l.device_max = device_peak_;
  l.continuous = continuous_;
  l.bound_by_device = device_peak_ < option_f_max_;
  return l;
}

void SafetyFilter::reset(Nanos now) noexcept {
  heat_ = 0;
  last_.setZero();
  last_torque_.setZero();
  ramp_start_ = now;
  gated_ = false;
}

SafetyOutput SafetyFilter::apply(const SafetyInput& in, double dt) noexcept {
  SafetyOutput out;
  // The continuous-force average follows the force actually sent (exponential window).
  const double decay = params_.continuous_window > 0 ? -std::expm1(-std::max(dt, 0.0) / params_.continuous_window) : 1.0;
  // 1. Device gate: zero at once (no rate limit: the data that would justify a force is gone).
  if (!in.device_ok) {
    out.flags = in.device_flags;
    last_.setZero();
    last_torque_.setZero();
    heat_ -= heat_ * decay;
    gated_ = true;
    return out;
  }
  if (gated_) {  // resume after a gate: soft start again
    gated_ = false;
    ramp_start_ = in.now;
  }

  // 2. Hold, then fade, a result that stopped coming.
  double scale = 1.0;
  if (!in.have_result) {
    out.flags |= kFlagNoResult;
    scale = 0.0;
  } else {
    if (!in.fresh_result) out.flags |= kFlagHeld;
    const double age = to_seconds(in.result_age);
    if (age > params_.hold_timeout) {
      const double f = params_.fade_time > 0 ? 1.0 - (age - params_.hold_timeout) / params_.fade_time : 0.0;
      if (f > 0) {
        out.flags |= kFlagFading;
        scale = f;
      } else {
        out.flags |= kFlagFaded;
        scale = 0.0;
      }
    }
  }

  // 3. Soft start: a share of the force once it is limited (4.), so the ramp bounds it by
  // ramp * f_max too. (Scaling first let a request above f_max reach f_max mid-ramp.)
  double ramp = 1.0;
  if (params_.ramp_time > 0) {
    const double r = to_seconds(in.now - ramp_start_) / params_.ramp_time;
    if (r < 1.0) {
      out.flags |= kFlagRamping;
      ramp = std::clamp(r, 0.0, 1.0);
    }
  }
  if (in.stopping) {
    out.flags |= kFlagStopping;
    scale = 0.0;
  }
  out.scale = scale * ramp;

  Eigen::Vector3d target = scale * in.desired;
  if (!target.allFinite()) target.setZero();

  // 4. Force limit.
  if (clamp_length(target, f_max_)) out.flags |= kFlagForceLimited;
  // Continuous limit (I^2 t): above 80 % of the heat budget the allowed force tapers linearly
  // from f_max to the continuous force, reached when the budget is used up, so a sustained push
  // settles at the continuous force with the budget exactly used (no chatter at the threshold).
  if (continuous_ < f_max_) {
    const double budget = continuous_ * continuous_;
    const double free_share = std::clamp((budget - heat_) / (0.2 * budget), 0.0, 1.0);
    const double cap = continuous_ + (f_max_ - continuous_) * free_share;
    if (clamp_length(target, cap)) out.flags |= kFlagContinuousLimited;
  }
  target *= ramp;

  // 5. Force-rate limit.
  if (limit_step(target, last_, params_.max_force_rate * std::max(dt, 0.0))) out.flags |= kFlagRateLimited;
  last_ = target;
  heat_ += (target.squaredNorm() - heat_) * decay;
  out.force = target;

  // 6. Torque: the same scale (hold, fade, stop) and ramp, its own limit and rate limit.
  Eigen::Vector3d torque = scale * in.desired_torque;
  if (!torque.allFinite()) torque.setZero();
  if (clamp_length(torque, tau_max_)) out.flags |= kFlagTorqueLimited;
  torque *= ramp;
  if (limit_step(torque, last_torque_, params_.max_torque_rate * std::max(dt, 0.0))) out.flags |= kFlagTorqueLimited;
  last_torque_ = torque;
  out.torque = torque;
  return out;
}

}  // namespace gshaptics
