#include "gshaptics/device/stream_device.h"

#include <algorithm>

namespace gshaptics {

StreamDevice::StreamDevice(const StreamDeviceParams& params, const Eigen::Vector3d& initial)
    : params_(params) {
  info_.name = params.name;
  info_.max_rate_hz = params.max_rate_hz;
  info_.workspace = params.workspace;
  prev_.position = initial;
  last_.position = initial;
}

void StreamDevice::start(Nanos now) {
  start_ = now;
  prev_.stamp = now;
  last_.stamp = now;
  sequence_ = 0;
}

void StreamDevice::set_target(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                              Nanos stamp, const Eigen::Vector3d* velocity) noexcept {
  Target t;
  t.position = position;
  if (velocity != nullptr) {
    t.velocity = *velocity;
    t.has_velocity = true;
  }
  t.orientation = orientation;
  t.stamp = stamp;
  targets_.write(t);
}

DeviceSample StreamDevice::read(Nanos now) noexcept {
  Target t;
  if (targets_.read_if_new(t)) {
    if (!have_last_) {
      prev_ = t;  // first target: no jump from the initial pose's velocity
      prev_.stamp = t.stamp - 1;
    } else {
      prev_ = last_;
      // The input's period: a running average (weight 0.2) of the intervals between targets.
      const double dt = std::clamp(to_seconds(t.stamp - last_.stamp), 0.0, params_.max_input_timeout);
      period_s_ = period_s_ > 0 ? 0.8 * period_s_ + 0.2 * dt : dt;
    }
    last_ = t;
    have_last_ = true;
  }
  DeviceSample s;
  // Before the first target the device sits at its initial pose and counts as alive; after
  // that it is alive while targets keep coming.
  const bool alive = !have_last_ ? params_.alive_before_first_target &&
                                       now - start_ <= to_nanos(params_.input_timeout)
                                 : now - last_.stamp <= to_nanos(input_timeout());
  if (alive) ++sequence_;
  s.sequence = sequence_;
  s.stamp = now;
  if (!params_.interpolate) {
    s.position = last_.position;
    s.orientation = last_.orientation;
    const double dt = to_seconds(last_.stamp - prev_.stamp);
    s.velocity = last_.has_velocity ? last_.velocity
                 : dt > 0 && have_last_ ? Eigen::Vector3d((last_.position - prev_.position) / dt)
                                        : Eigen::Vector3d::Zero();
    return s;
  }
  // Interpolate from prev to last over one input period, starting when last arrived.
  const Nanos period = std::clamp<Nanos>(last_.stamp - prev_.stamp, 1'000'000, 100'000'000);
  const double u = std::clamp(double(now - last_.stamp) / double(period), 0.0, 1.0);
  s.position = prev_.position + u * (last_.position - prev_.position);
  s.velocity = last_.has_velocity ? last_.velocity
                : u < 1.0 ? Eigen::Vector3d((last_.position - prev_.position) / to_seconds(period))
                          : Eigen::Vector3d::Zero();
  s.orientation = prev_.orientation.slerp(u, last_.orientation);
  return s;
}

double StreamDevice::input_timeout() const noexcept {
  if (!(params_.timeout_periods > 0)) return params_.input_timeout;
  return std::clamp(params_.timeout_periods * period_s_, params_.input_timeout,
                    std::max(params_.input_timeout, params_.max_input_timeout));
}

void StreamDevice::write(const Wrench& wrench, Nanos now) noexcept {
  (void)now;
  last_force_.store(wrench.force.norm(), std::memory_order_relaxed);
}

void StreamDevice::stop(Nanos now) noexcept {
  (void)now;
  last_force_.store(0.0, std::memory_order_relaxed);
}

}  // namespace gshaptics
