#include "gshaptics/device/simulated_device.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/error.h"

namespace gshaptics {

SimulatedDevice::SimulatedDevice(ProbeTrajectory trajectory, const SimulatedDeviceParams& params)
    : trajectory_(std::move(trajectory)), params_(params), device_(params.device) {
  if (trajectory_.waypoints().empty()) throw InputError("simulated device: empty probe trajectory");
  if (!(params.max_step > 0)) throw InputError("simulated device: max_step must be > 0 s");
  const bool admittance = params.causality == Causality::kAdmittance;
  if (admittance && (!(params.robot_mass > 0) || !(params.position_gain > 0) || !(params.velocity_gain >= 0) ||
                     !(params.servo_substep > 0) || !std::isfinite(params.position_gain + params.velocity_gain)))
    throw InputError("simulated device: the robot's mass, position gain and substep must be > 0 and its "
                     "velocity gain >= 0");
  info_.name = admittance ? "sim (admittance robot with a force sensor + simulated hand)"
                          : "sim (ideal mass-damper device + simulated hand)";
  info_.admittance = admittance;
  if (admittance) info_.force_sensor_range = params.sensor_range;
  // The ideal device takes damping up to b T / m < 2 per step (semi-implicit Euler with the force
  // held); the passivity controller may use a quarter of that.
  if (!admittance) info_.max_damping = 0.5 * params.device.mass / params.max_step;
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
  setpoint_ = Setpoint{};
  setpoint_.position = s.position;
  user_force_.setZero();
  sequence_ = 0;
}

void SimulatedDevice::integrate_to(Nanos now) noexcept {
  const bool admittance = params_.causality == Causality::kAdmittance;
  const double step = admittance ? std::min(params_.max_step, params_.servo_substep) : params_.max_step;
  const Nanos max_step = std::max<Nanos>(1, to_nanos(step));
  while (t_ < now) {
    const Nanos h = std::min(max_step, now - t_);
    double ts = to_seconds(t_ - t0_);
    // Loop after the pass and its rest, not at its last instant (a one-pass run ends exactly there).
    if (params_.loop && period_s_ > 0 && ts > period_s_) ts = std::fmod(ts, period_s_);
    Eigen::Vector3d target_p, target_v;
    trajectory_.sample(ts, target_p, target_v);
    user_force_ = user_hand_force(params_.user, device_.state(), target_p, target_v);
    if (admittance)
      servo_step(to_seconds(h));
    else
      device_.step(user_force_ + wrench_.force, to_seconds(h));
    t_ += h;
  }
}

void SimulatedDevice::servo_step(double h) noexcept {
  // Semi-implicit Euler of m a = k_p (x_sp - x) + k_d (v_sp - v) + F_hand.
  DeviceState s = device_.state();
  const Eigen::Vector3d f = params_.position_gain * (setpoint_.position - s.position) +
                            params_.velocity_gain * (setpoint_.velocity - s.velocity) + user_force_;
  s.velocity += f * (h / params_.robot_mass);
  s.position += s.velocity * h;
  device_.set_state(s);
}

DeviceSample SimulatedDevice::read(Nanos now) noexcept {
  integrate_to(now);
  DeviceSample s;
  s.sequence = ++sequence_;
  s.stamp = now;
  s.position = device_.state().position;
  s.velocity = device_.state().velocity;
  s.user_force = params_.causality == Causality::kAdmittance
                     ? user_force_.cwiseMax(-params_.sensor_range).cwiseMin(params_.sensor_range).eval()
                     : user_force_;
  return s;
}

void SimulatedDevice::write(const Wrench& wrench, Nanos now) noexcept {
  (void)now;
  wrench_ = wrench;
}

void SimulatedDevice::write_setpoint(const Setpoint& setpoint, Nanos now) noexcept {
  (void)now;
  if (setpoint.position.allFinite() && setpoint.velocity.allFinite()) setpoint_ = setpoint;
}

void SimulatedDevice::stop(Nanos now) noexcept {
  (void)now;
  wrench_ = Wrench{};
  // A position-controlled robot is left at rest where it is.
  setpoint_.position = device_.state().position;
  setpoint_.velocity.setZero();
}

}  // namespace gshaptics
