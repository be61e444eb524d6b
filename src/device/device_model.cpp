#include "gshaptics/device/device_model.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "gshaptics/error.h"

namespace gshaptics {


void AdmittanceDevice::step(const Eigen::Vector3d& external_force, double dt) noexcept {
  const Eigen::Vector3d accel = (external_force - params_.damping * state_.velocity) / params_.mass;
  state_.velocity += dt * accel;
  state_.position += dt * state_.velocity;
}

Eigen::Vector3d user_hand_force(const UserHandParams& params, const DeviceState& device,
                                const Eigen::Vector3d& target_position,
                                const Eigen::Vector3d& target_velocity) noexcept {
  Eigen::Vector3d f = params.stiffness * (target_position - device.position) +
                      params.damping * (target_velocity - device.velocity);
  const double n = f.norm();
  if (n > params.max_force) f *= params.max_force / n;
  return f;
}

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw InputError("device model: " + what);
}

}  // namespace

DeviceModel::DeviceModel(const DeviceModelParams& p) : params_(p) {
  const HandImpedance& hand = p.hand;
  require(std::isfinite(p.mass) && p.mass > 0, "mass must be > 0 kg");
  require(std::isfinite(p.damping) && p.damping >= 0, "damping must be >= 0 N s/m");
  require(std::isfinite(p.encoder_resolution) && p.encoder_resolution >= 0, "encoder resolution must be >= 0 m");
  require(std::isfinite(p.force_resolution) && p.force_resolution >= 0, "force resolution must be >= 0 N");
  require(!std::isnan(p.max_force) && p.max_force > 0, "max force must be > 0 N");
  require(std::isfinite(p.delay_up) && p.delay_up >= 0 && p.delay_up <= 1, "delay up must be in [0, 1] s");
  require(std::isfinite(p.delay_down) && p.delay_down >= 0 && p.delay_down <= 1, "delay down must be in [0, 1] s");
  require(std::isfinite(p.substep) && p.substep > 0 && p.substep <= 1e-3, "substep must be in (0, 1 ms]");
  require(std::isfinite(p.max_rate_hz) && p.max_rate_hz > 0 && p.max_rate_hz <= 1e5, "max rate must be in (0, 100 kHz]");
  require(std::isfinite(p.duration) && p.duration >= 0, "duration must be >= 0 s");
  require(std::isfinite(p.position_gain) && p.position_gain >= 0 && std::isfinite(p.velocity_gain) &&
              p.velocity_gain >= 0,
          "position and velocity gains must be >= 0");
  require(std::isfinite(hand.mass) && hand.mass >= 0 && std::isfinite(hand.stiffness) && hand.stiffness >= 0 &&
              std::isfinite(hand.damping) && hand.damping >= 0 && hand.push.allFinite(),
          "hand mass, stiffness and damping must be >= 0 and finite");
  require(p.hand_anchor.allFinite() && p.initial_position.allFinite() && p.initial_velocity.allFinite(),
          "anchor and initial state must be finite");
  h_ = std::max<Nanos>(1, to_nanos(p.substep));
  history_.resize(std::size_t(std::ceil(p.delay_up / p.substep)) + 4);
  commands_.resize(std::size_t(std::ceil(p.delay_down * p.max_rate_hz)) + 4);
  const bool admittance = p.causality == Causality::kAdmittance;
  info_.name = std::string(admittance ? "sim admittance device" : "sim impedance device") + " (m " +
               std::to_string(p.mass) + " kg, b " + std::to_string(p.damping) + " N s/m)";
  info_.admittance = admittance;
  info_.max_rate_hz = p.max_rate_hz;
  info_.rate_source = "model";
  info_.transport_delay = p.delay_up + p.delay_down;
  info_.max_force = p.max_force;
  if (std::isfinite(p.max_force)) info_.limit_source = "model";
  x_ = p.initial_position;
  v_ = p.initial_velocity;
}

void DeviceModel::start(Nanos now) {
  t0_ = t_ = last_read_ = now;
  x_ = params_.initial_position;
  v_ = params_.initial_velocity;
  applied_.setZero();
  last_reported_.setZero();
  setpoint_ = x_;  // the position servo holds where it starts
  setpoint_velocity_.setZero();
  work_ = 0;
  sequence_ = 0;
  have_reported_ = false;
  history_head_ = 0;
  history_size_ = 1;
  history_[0] = Timed{now, x_};
  command_head_ = command_size_ = 0;
}

Eigen::Vector3d DeviceModel::quantize(const Eigen::Vector3d& v, double step) const noexcept {
  if (step <= 0) return v;
  return (v / step).array().round().matrix() * step;
}

void DeviceModel::integrate_to(Nanos now) noexcept {
  const HandImpedance& hand = params_.hand;
  const double h = to_seconds(h_);
  const double inv_mass = 1.0 / (params_.mass + hand.mass);
  const double b = params_.damping + hand.damping;
  while (t_ + h_ <= now) {
    // Commands whose transport delay has passed reach the amplifier.
    while (command_size_ > 0 && commands_[command_head_].t <= t_) {
      const Timed& c = commands_[command_head_];
      if (params_.causality == Causality::kAdmittance) {
        setpoint_ = c.v;
        setpoint_velocity_ = c.w;
      } else {
        applied_ = c.v;
      }
      command_head_ = (command_head_ + 1) % commands_.size();
      --command_size_;
    }
    if (params_.causality == Causality::kAdmittance) {
      applied_ = params_.position_gain * (setpoint_ - x_) + params_.velocity_gain * (setpoint_velocity_ - v_);
      const double n = applied_.norm();
      if (n > params_.max_force) applied_ *= params_.max_force / n;
    }
    const Eigen::Vector3d f = applied_ - b * v_ + hand.stiffness * (params_.hand_anchor - x_) + hand.push;
    v_ += (h * inv_mass) * f;
    const Eigen::Vector3d dx = h * v_;
    work_ += applied_.dot(dx);
    x_ += dx;
    t_ += h_;
    const std::size_t slot = (history_head_ + history_size_) % history_.size();
    history_[slot] = Timed{t_, x_};
    if (history_size_ < history_.size()) {
      ++history_size_;
    } else {
      history_head_ = (history_head_ + 1) % history_.size();
    }
  }
}

Eigen::Vector3d DeviceModel::position_at(Nanos t) const noexcept {
  // Newest first; positions between substeps are interpolated.
  const std::size_t n = history_.size();
  const Timed* later = nullptr;
  for (std::size_t i = history_size_; i-- > 0;) {
    const Timed& e = history_[(history_head_ + i) % n];
    if (e.t <= t) {
      if (later == nullptr || later->t == e.t) return e.v;
      const double w = double(t - e.t) / double(later->t - e.t);
      return e.v + w * (later->v - e.v);
    }
    later = &e;
  }
  return history_[history_head_].v;  // older than the history: the oldest known
}

DeviceSample DeviceModel::read(Nanos now) noexcept {
  integrate_to(now);
  DeviceSample s;
  s.sequence = ++sequence_;
  s.stamp = now - to_nanos(params_.delay_up);
  s.position = quantize(position_at(s.stamp), params_.encoder_resolution);
  if (have_reported_ && now > last_read_) s.velocity = (s.position - last_reported_) / to_seconds(now - last_read_);
  const HandImpedance& hand = params_.hand;
  s.user_force = hand.stiffness * (params_.hand_anchor - x_) - hand.damping * v_ + hand.push;
  last_reported_ = s.position;
  last_read_ = now;
  have_reported_ = true;
  return s;
}

void DeviceModel::enqueue(const Timed& command) noexcept {
  if (command_size_ == commands_.size()) {  // faster than max_rate_hz: the oldest is dropped
    command_head_ = (command_head_ + 1) % commands_.size();
    --command_size_;
  }
  commands_[(command_head_ + command_size_) % commands_.size()] = command;
  ++command_size_;
}

void DeviceModel::write_setpoint(const Setpoint& setpoint, Nanos now) noexcept {
  if (params_.causality != Causality::kAdmittance) return;
  if (!setpoint.position.allFinite() || !setpoint.velocity.allFinite()) return;
  integrate_to(now);
  if (params_.delay_down <= 0) {
    setpoint_ = setpoint.position;
    setpoint_velocity_ = setpoint.velocity;
    return;
  }
  enqueue(Timed{now + to_nanos(params_.delay_down), setpoint.position, setpoint.velocity});
}

void DeviceModel::write(const Wrench& wrench, Nanos now) noexcept {
  if (params_.causality == Causality::kAdmittance) return;  // position-controlled: no force command
  integrate_to(now);  // the previous force is held up to now
  Eigen::Vector3d f = quantize(wrench.force.allFinite() ? wrench.force : Eigen::Vector3d::Zero(),
                               params_.force_resolution);
  const double n = f.norm();
  if (n > params_.max_force) f *= params_.max_force / n;
  if (params_.delay_down <= 0) {
    applied_ = f;
    return;
  }
  enqueue(Timed{now + to_nanos(params_.delay_down), f, Eigen::Vector3d::Zero()});
}

void DeviceModel::stop(Nanos now) noexcept {
  integrate_to(now);
  applied_.setZero();
  setpoint_ = x_;  // an admittance device brakes where it is
  setpoint_velocity_.setZero();
  command_head_ = command_size_ = 0;
}

bool DeviceModel::finished() const noexcept {
  return params_.duration > 0 && t_ - t0_ >= to_nanos(params_.duration);
}

}  // namespace gshaptics
