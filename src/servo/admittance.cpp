#include "gshaptics/servo/admittance.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

const char* control_mode_name(ControlMode mode) noexcept {
  return mode == ControlMode::kAdmittance ? "admittance" : "impedance";
}

void ForceSensorFilter::reset(Nanos now, double range) noexcept {
  (void)now;
  range_ = range > 0 ? range : std::numeric_limits<double>::infinity();
  tare_end_ = -1;  // the tare starts with the first reading (a networked sensor may come late)
  sum_.setZero();
  tare_.setZero();
  torque_sum_.setZero();
  torque_tare_.setZero();
  count_ = 0;
  taring_ = params_.tare_time > 0;
  saturated_ = false;
}

Eigen::Vector3d ForceSensorFilter::apply(const Eigen::Vector3d& raw, const Eigen::Vector3d& raw_torque, Nanos now,
                                         Eigen::Vector3d& torque) noexcept {
  torque.setZero();
  if (!raw.allFinite() || !raw_torque.allFinite()) return Eigen::Vector3d::Zero();
  if (std::isfinite(range_) && raw.cwiseAbs().maxCoeff() >= 0.99 * range_) saturated_ = true;
  if (taring_) {
    if (tare_end_ < 0) tare_end_ = now + to_nanos(params_.tare_time);
    if (now < tare_end_) {
      sum_ += raw;
      torque_sum_ += raw_torque;
      ++count_;
      return Eigen::Vector3d::Zero();
    }
    taring_ = false;
    if (count_ > 0) {
      tare_ = sum_ / double(count_);
      torque_tare_ = torque_sum_ / double(count_);
    }
  }
  const Eigen::Vector3d t = raw_torque - torque_tare_;
  if (t.norm() > params_.torque_dead_band) torque = t;
  // A dead band, not a shrink: above it the hand's whole force counts, so a wall's reaction
  // equals the push.
  const Eigen::Vector3d f = raw - tare_;
  return f.norm() > params_.dead_band ? f : Eigen::Vector3d::Zero();
}

namespace {

// v held to a change of at most `max_change` from v0; true when it was.
bool limit_change(Eigen::Vector3d& v, const Eigen::Vector3d& v0, double max_change) noexcept {
  const Eigen::Vector3d dv = v - v0;
  if (!(dv.norm() > max_change)) return false;
  v = v0 + dv * (max_change / dv.norm());
  return true;
}

// v held to a norm of at most `max`; true when it was.
bool limit_norm(Eigen::Vector3d& v, double max) noexcept {
  const double n = v.norm();
  if (!(n > max)) return false;
  v *= max / n;
  return true;
}

// v shortened by `by` toward zero (braking), zero when it is shorter.
void shrink_toward_zero(Eigen::Vector3d& v, double by) noexcept {
  const double n = v.norm();
  if (n <= by)
    v.setZero();
  else
    v *= (n - by) / n;
}

// The highest speed from which braking by u = a dt per tick (each speed held one tick: v, v - u,
// ..., down to the last one below u, then 0) covers at most d in ticks of dt: with n = floor(v/u)
// the distance is dt ((n+1) v - u n (n+1) / 2), monotone in v; solved for v with n found from
// the continuous answer and corrected by whole steps.
double braking_speed(double d, double u, double dt) noexcept {
  if (!(d > 0)) return 0;
  const double guess = std::sqrt(u * u / 4 + 2 * (u / dt) * d) - u / 2;
  // Far from the wall (or an unbounded box) the tick count does not fit, and does not matter.
  if (!(guess < 1e6 * u)) return guess;
  long n = long(guess / u);
  for (int k = 0; k < 8; ++k) {
    const double v = d / (dt * double(n + 1)) + u * double(n) / 2;
    if (v < u * double(n) && n > 0)
      --n;
    else if (v >= u * double(n + 1))
      ++n;
    else
      return v;
  }
  return guess;
}

}  // namespace

const Setpoint& AdmittanceController::step(const Eigen::Vector3d& user_force, const Eigen::Vector3d& user_torque,
                                           const Eigen::Vector3d& environment_force,
                                           const Eigen::Vector3d& environment_torque, double dt) noexcept {
  (void)step(user_force, environment_force, dt);
  if (!(dt > 0)) return setpoint_;
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  if (user_torque.allFinite()) t += user_torque;
  if (environment_torque.allFinite()) t += environment_torque;
  turn(t, dt);
  return setpoint_;
}

void AdmittanceController::turn(const Eigen::Vector3d& torque, double dt) noexcept {
  Eigen::Vector3d& w = setpoint_.angular_velocity;
  const Eigen::Vector3d w0 = w;
  w += (dt / params_.inertia) * (torque - params_.angular_damping * w0);
  limited_ |= limit_change(w, w0, limits_.max_angular_acceleration * dt);
  limited_ |= limit_norm(w, limits_.max_angular_speed);
  rotate(dt);
}

void AdmittanceController::rotate(double dt) noexcept {
  const Eigen::Vector3d& w = setpoint_.angular_velocity;
  const double angle = w.norm() * dt;
  if (angle > 0)
    setpoint_.orientation = (Eigen::Quaterniond(Eigen::AngleAxisd(angle, w.normalized())) * setpoint_.orientation).normalized();
}

const Setpoint& AdmittanceController::step(const Eigen::Vector3d& user_force,
                                           const Eigen::Vector3d& environment_force, double dt) noexcept {
  limited_ = false;
  if (!(dt > 0)) return setpoint_;
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  if (user_force.allFinite()) f += user_force;
  if (environment_force.allFinite()) f += environment_force;
  const Eigen::Vector3d v0 = setpoint_.velocity;
  setpoint_.velocity += (dt / params_.mass) * (f - params_.damping * v0);
  limit(v0, dt);
  setpoint_.position += dt * setpoint_.velocity;
  // The workspace: the setpoint stays in the box, and does not keep pushing out of it.
  for (int i = 0; i < 3; ++i) {
    const double lo = workspace_.min()[i], hi = workspace_.max()[i];
    double& x = setpoint_.position[i];
    double& v = setpoint_.velocity[i];
    if (x < lo || x > hi) {
      x = std::clamp(x, lo, hi);
      v = 0;
      limited_ = true;
    }
  }
  return setpoint_;
}

void AdmittanceController::limit(const Eigen::Vector3d& v0, double dt) noexcept {
  Eigen::Vector3d& v = setpoint_.velocity;
  // Toward a wall of the workspace no faster than braking at the limit stops at the wall
  // (braking_speed of the distance left along each axis).
  const double adt = limits_.max_acceleration * dt;
  for (int i = 0; i < 3; ++i) {
    const double d = v[i] > 0 ? workspace_.max()[i] - setpoint_.position[i]
                              : setpoint_.position[i] - workspace_.min()[i];
    const double cap = braking_speed(d, adt, dt);
    if (std::abs(v[i]) > cap) {
      v[i] = std::copysign(cap, v[i]);
      limited_ = true;
    }
  }
  limited_ |= limit_change(v, v0, adt);
  limited_ |= limit_norm(v, limits_.max_speed);
}

const Setpoint& AdmittanceController::brake(double dt) noexcept {
  limited_ = false;
  if (!(dt > 0)) return setpoint_;
  shrink_toward_zero(setpoint_.velocity, limits_.max_acceleration * dt);
  setpoint_.position += dt * setpoint_.velocity;
  shrink_toward_zero(setpoint_.angular_velocity, limits_.max_angular_acceleration * dt);
  rotate(dt);
  return setpoint_;
}

}  // namespace gshaptics
