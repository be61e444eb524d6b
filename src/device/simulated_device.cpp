#include "gshaptics/device/simulated_device.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/error.h"

namespace gshaptics {

SimulatedDevice::SimulatedDevice(ProbeTrajectory trajectory, const SimulatedDeviceParams& params)
    : trajectory_(std::move(trajectory)), params_(params), device_(params.device) {
  if (trajectory_.waypoints().empty()) throw InputError("simulated device: empty probe trajectory");
  if (!(params.max_step > 0)) throw InputError("simulated device: max_step must be > 0 s");
  info_.name = "sim (admittance device + simulated hand)";
  info_.max_rate_hz = 100000;
  Eigen::AlignedBox3d box;
  for (const auto& w : trajectory_.waypoints()) box.extend(w.position);
  const Eigen::Vector3d m = Eigen::Vector3d::Constant(params.workspace_margin);
  info_.workspace = Eigen::AlignedBox3d(box.min() - m, box.max() + m);
  period_s_ = trajectory_.duration() + 0.5;
}

void SimulatedDevice::start(Nanos now) {
  t0_ = now;
  t_ = now;
  DeviceState s;
  Eigen::Vector3d v;
  trajectory_.sample(0.0, s.position, v);
  device_.set_state(s);
  wrench_ = Wrench{};
  user_force_.setZero();
  sequence_ = 0;
}

void SimulatedDevice::integrate_to(Nanos now) noexcept {
  const Nanos max_step = std::max<Nanos>(1, to_nanos(params_.max_step));
  while (t_ < now) {
    const Nanos h = std::min(max_step, now - t_);
    double ts = to_seconds(t_ - t0_);
    // Loop after the pass and its rest, not at its last instant (a one-pass run ends exactly there).
    if (params_.loop && period_s_ > 0 && ts > period_s_) ts = std::fmod(ts, period_s_);
    Eigen::Vector3d target_p, target_v;
    trajectory_.sample(ts, target_p, target_v);
    user_force_ = user_hand_force(params_.user, device_.state(), target_p, target_v);
    device_.step(user_force_ + wrench_.force, to_seconds(h));
    t_ += h;
  }
}

DeviceSample SimulatedDevice::read(Nanos now) noexcept {
  integrate_to(now);
  DeviceSample s;
  s.sequence = ++sequence_;
  s.stamp = now;
  s.position = device_.state().position;
  s.velocity = device_.state().velocity;
  s.user_force = user_force_;
  return s;
}

void SimulatedDevice::write(const Wrench& wrench, Nanos now) noexcept {
  (void)now;
  wrench_ = wrench;
}

void SimulatedDevice::stop(Nanos now) noexcept {
  (void)now;
  wrench_ = Wrench{};
}

}  // namespace gshaptics
