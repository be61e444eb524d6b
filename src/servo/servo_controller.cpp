#include "gshaptics/servo/servo_controller.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "gshaptics/error.h"

namespace gshaptics {

namespace {

void max_store(std::atomic<double>& a, double v) noexcept {
  if (v > a.load(std::memory_order_relaxed)) a.store(v, std::memory_order_relaxed);
}

void bump(std::atomic<std::uint64_t>& a, bool cond) noexcept {
  if (cond) a.store(a.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

}  // namespace

ServoController::ServoController(HapticDevice& device, const SafetyParams& safety, Nanos period,
                                 PoseChannel& poses, ResultChannel& results, RuntimeStats& stats,
                                 TickLog* log, Clock& clock, TripleBuffer<TickRecord>* monitor,
                                 const ControlParams& control)
    : device_(device), safety_(safety), period_(period), poses_(poses), results_(results),
      stats_(stats), log_(log), clock_(clock), monitor_(monitor), passivity_(safety.passivity),
      control_(control), admittance_(control.admittance, control.robot), sensor_(control.robot) {}

void ServoController::start(Nanos now) {
  device_.start(now);
  // The device's own limits bind whatever the options say; vendor drivers know them only now.
  const DeviceInfo& info = device_.info();
  const double rate = 1e9 / double(period_);
  if (rate > info.max_rate_hz * (1 + 1e-9)) {
    device_.write(Wrench{}, now);
    device_.stop(now);
    throw InputError("runtime: rate " + std::to_string(rate) + " Hz is above what device '" + info.name +
                     "' accepts (" + std::to_string(info.max_rate_hz) + " Hz, " + info.rate_source + ")");
  }
  safety_.set_device_limits(info.max_force, info.max_continuous_force);
  safety_.set_device_torque_limit(info.max_torque);
  stats_.torque_limit.store(safety_.tau_max(), std::memory_order_relaxed);
  const ForceLimits lim = safety_.limits();
  stats_.force_limit.store(lim.f_max, std::memory_order_relaxed);
  stats_.continuous_force_limit.store(lim.continuous, std::memory_order_relaxed);
  stats_.force_limit_by_device.store(lim.bound_by_device, std::memory_order_relaxed);
  // The passivity controller's damping cap: what the body it damps renders without chattering
  // (the device, or under admittance control the virtual tool: semi-implicit Euler on mass m is
  // stable for b T / m < 2, taken with a factor 4 margin).
  const double damps = control_.mode == ControlMode::kAdmittance
                           ? 0.5 * control_.admittance.mass / to_seconds(period_) : info.max_damping;
  passivity_.set_damping_cap(passivity_damping_cap(safety_.params().passivity.max_damping, damps));
  stats_.passivity_damping_cap.store(passivity_.damping_cap(), std::memory_order_relaxed);
  virtual_tool_ready_ = false;
  faulted_ = false;
  admittance_.set_workspace(info.workspace);
  sensor_.reset(now, info.force_sensor_range);
  t0_ = now;
  prev_now_ = now;
  last_device_data_ = now;
  safety_.reset(now);
  // Forces reach the device and its motion comes back a round trip later (0 ticks on a local device).
  const double delay_ticks = std::isfinite(info.transport_delay) && info.transport_delay > 0
                                 ? std::round(info.transport_delay / to_seconds(period_)) : 0.0;
  passivity_.reset(int(std::min(delay_ticks, 1e6)));
  stats_.start_ns.store(now, std::memory_order_relaxed);
}

std::uint32_t ServoController::gate_device(const DeviceSample& s, Nanos now) noexcept {
  std::uint32_t device_flags = 0;
  if (s.sequence == 0) {
    device_flags |= kFlagWatchdog;  // the device has not delivered any data yet
  } else if (!have_device_data_ || s.sequence != last_device_seq_) {
    have_device_data_ = true;
    last_device_seq_ = s.sequence;
    last_device_data_ = now;
  } else if (now - last_device_data_ > to_nanos(safety_.params().device_timeout)) {
    device_flags |= kFlagWatchdog;
  }
  const bool finite = s.position.allFinite() && s.velocity.allFinite() &&
                      s.orientation.coeffs().allFinite() && s.orientation.coeffs().squaredNorm() > 0;
  if (!finite) {
    device_flags |= kFlagInvalidPose;
  } else if (!device_.info().workspace.contains(s.position)) {
    device_flags |= kFlagOutsideWorkspace;
  }
  return device_flags;
}

void ServoController::tool_state(const DeviceSample& s, std::uint32_t device_flags, Eigen::Vector3d& position,
                                 Eigen::Vector3d& velocity, Eigen::Quaterniond& orientation) noexcept {
  // In admittance control the virtual tool starts at rest at the device's first good sample; from
  // then on it is the robot's setpoint, braked to rest (not reset) while the device is stale.
  position = s.position;
  velocity = s.velocity;
  orientation = s.orientation;
  if (control_.mode != ControlMode::kAdmittance) return;
  if (!virtual_tool_ready_) {
    if (device_flags != 0) return;
    admittance_.reset(s.position, s.orientation);
    virtual_tool_ready_ = true;
  }
  position = admittance_.setpoint().position;
  velocity = admittance_.setpoint().velocity;
  orientation = admittance_.setpoint().orientation;
}

Nanos ServoController::tick(Nanos scheduled, CollisionWorker* inline_worker) noexcept {
  const Nanos now = clock_.now();
  const double dt = prev_now_ < now ? to_seconds(now - prev_now_) : to_seconds(period_);
  prev_now_ = now;

  // Read the device; gate 1 of the safety layer (watchdog, finite pose, workspace).
  const DeviceSample s = device_.read(now);
  const std::uint32_t device_flags = gate_device(s, now);
  const bool finite = (device_flags & kFlagInvalidPose) == 0;
  Eigen::Vector3d tool_position, tool_velocity;
  Eigen::Quaterniond tool_orientation;
  tool_state(s, device_flags, tool_position, tool_velocity, tool_orientation);

  // Publish the pose (never a non-finite one) to the collision side.
  if (finite && (device_flags & kFlagWatchdog) == 0) {
    PoseCommand p;
    p.sequence = ++pose_seq_;
    p.stamp = now;
    p.position = tool_position;
    p.orientation = tool_orientation.normalized();
    p.velocity = tool_velocity;
    poses_.write(p);
  }
  if (inline_worker != nullptr) inline_worker->step(poses_, results_);

  // The newest collision result.
  // The worker writes one result per new pose, so anything new in the buffer is a new result.
  const bool fresh = results_.read_if_new(result_);

  // The passivity controller (Hannaford & Ryu 2002) ahead of the safety layer's limits.
  if (finite) passivity_.account(tool_position);
  PassivityStep pc;
  pc.force = result_.force;
  if (device_flags == 0) pc = passivity_.correct(result_.force, tool_velocity, dt);

  SafetyInput in;
  in.now = now;
  in.desired = pc.force;
  in.desired_torque = result_.torque;
  in.have_result = result_.pose_sequence != 0;
  in.fresh_result = fresh;
  in.result_age = in.have_result ? now - result_.pose_stamp : 0;
  in.device_ok = device_flags == 0;
  in.device_flags = device_flags;
  in.stopping = stopping_;
  TickFacts t;
  t.out = safety_.apply(in, dt);
  const SafetyOutput& out = t.out;
  passivity_.sent(out.force);

  const std::uint32_t robot_flags = drive_setpoint(s, device_flags, out, now, dt);
  Wrench w;
  w.force = out.force;
  const bool renders_torque = device_.info().renders_torque;
  t.torque_dropped = !renders_torque && (out.torque.array() != 0.0).any();
  if (renders_torque) w.torque = out.torque;
  device_.write(w, now);
  t.end = clock_.now();

  t.scheduled = scheduled;
  t.now = now;
  t.sample = &s;
  t.torque_sent = w.torque;
  t.damping = pc.damping;
  t.flags = out.flags | robot_flags | (pc.damping > 0 ? kFlagPassivity : 0u) |
            (t.torque_dropped ? kFlagTorqueDropped : 0u);
  t.fresh = fresh;
  t.have_result = in.have_result;
  t.result_age = in.result_age;
  count(t);
  if (log_ != nullptr || monitor_ != nullptr) record(t);
  return t.end;
}

std::uint32_t ServoController::drive_setpoint(const DeviceSample& s, std::uint32_t device_flags,
                                              const SafetyOutput& out, Nanos now, double dt) noexcept {
  if (control_.mode != ControlMode::kAdmittance || !virtual_tool_ready_) return 0;
  std::uint32_t flags = 0;
  // The sensor's reading is fresh only when the device's sample is.
  Eigen::Vector3d user = Eigen::Vector3d::Zero(), user_torque = Eigen::Vector3d::Zero();
  if (device_flags == 0) user = sensor_.apply(s.user_force, s.user_torque, now, user_torque);
  if (sensor_.saturated()) {
    faulted_ = true;  // a saturated sensor no longer measures the hand: stop the run
    flags |= kFlagSensorSaturated;
  }
  if (sensor_.taring()) flags |= kFlagTaring;
  // The user's force and the rendered force move the virtual tool within the robot's limits; a
  // stale device, a stop, a fault or the tare hold it or brake it to rest.
  const bool hold = device_flags != 0 || stopping_ || faulted_ || sensor_.taring();
  if (hold && !admittance_.at_rest()) flags |= kFlagBraking;
  device_.write_setpoint(hold ? admittance_.brake(dt) : admittance_.step(user, user_torque, out.force, out.torque, dt),
                         now);
  if (admittance_.limited()) flags |= kFlagSetpointLimited;
  return flags;
}

void ServoController::count(const TickFacts& t) noexcept {
  const std::uint32_t f = t.flags;
  stats_.ticks.store(stats_.ticks.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  bump(stats_.deadline_misses, t.end > t.scheduled + period_);
  bump(stats_.stale_ticks, (f & kFlagHeld) != 0);
  bump(stats_.fading_ticks, (f & kFlagFading) != 0);
  bump(stats_.faded_ticks, (f & kFlagFaded) != 0);
  const bool fading = (f & (kFlagFading | kFlagFaded)) != 0;
  bump(stats_.fades, fading && !was_fading_);
  was_fading_ = fading;
  bump(stats_.no_result_ticks, (f & kFlagNoResult) != 0);
  bump(stats_.watchdog_ticks, (f & kFlagWatchdog) != 0);
  bump(stats_.invalid_pose_ticks, (f & kFlagInvalidPose) != 0);
  bump(stats_.outside_workspace_ticks, (f & kFlagOutsideWorkspace) != 0);
  bump(stats_.force_limited_ticks, (f & kFlagForceLimited) != 0);
  bump(stats_.rate_limited_ticks, (f & kFlagRateLimited) != 0);
  bump(stats_.continuous_limited_ticks, (f & kFlagContinuousLimited) != 0);
  bump(stats_.results_used, t.fresh);
  bump(stats_.passivity_ticks, (f & kFlagPassivity) != 0);
  bump(stats_.torque_limited_ticks, (f & kFlagTorqueLimited) != 0);
  bump(stats_.torque_dropped_ticks, t.torque_dropped);
  bump(stats_.setpoint_limited_ticks, (f & kFlagSetpointLimited) != 0);
  bump(stats_.braking_ticks, (f & kFlagBraking) != 0);
  bump(stats_.sensor_saturated_ticks, (f & kFlagSensorSaturated) != 0);
  max_store(stats_.peak_torque, t.out.torque.norm());
  max_store(stats_.passivity_peak_damping, t.damping);
  if (passivity_.energy() < stats_.passivity_min_energy.load(std::memory_order_relaxed))
    stats_.passivity_min_energy.store(passivity_.energy(), std::memory_order_relaxed);
  const double fm = t.out.force.norm();
  stats_.last_force.store(fm, std::memory_order_relaxed);
  max_store(stats_.peak_force, fm);
  stats_.last_contacts.store(result_.counts.contacts, std::memory_order_relaxed);
  stats_.last_tick_ns.store(t.now, std::memory_order_relaxed);
  stats_.jitter.record(t.now - t.scheduled);
  stats_.tick_time.record(t.end - t.now);
  if (t.have_result) stats_.result_age.record(t.result_age);
}

void ServoController::record(const TickFacts& t) noexcept {
  const DeviceSample& s = *t.sample;
  TickRecord r;
  r.time = to_seconds(t.scheduled - t0_);
  r.jitter_us = float(double(t.now - t.scheduled) * 1e-3);
  r.tick_us = float(double(t.end - t.now) * 1e-3);
  r.position = s.position;
  r.velocity = s.velocity;
  r.counts = result_.counts;
  r.desired = result_.force;
  r.force = t.out.force;
  r.torque = t.torque_sent;
  r.user_force = s.user_force;
  r.query_us = result_.query_us;
  r.result_age_us = float(double(t.result_age) * 1e-3);
  r.flags = t.flags;
  r.proxy = result_.pose_sequence != 0 ? result_.proxy : s.position;
  r.constraints = result_.constraints;
  r.texture_rms = result_.texture_rms;
  r.vibration = result_.vibration;
  r.energy = passivity_.energy();
  r.damping = float(t.damping);
  r.setpoint = control_.mode == ControlMode::kAdmittance && virtual_tool_ready_ ? admittance_.setpoint().position
                                                                                : s.position;
  if (log_ != nullptr) log_->push(r);
  if (monitor_ != nullptr) monitor_->write(r);
}

void ServoController::finish(Nanos now) noexcept {
  // A robot is left at rest where its virtual tool is (braked there by the stop ramp).
  if (control_.mode == ControlMode::kAdmittance && virtual_tool_ready_) {
    Setpoint rest;
    rest.position = admittance_.setpoint().position;
    device_.write_setpoint(rest, now);
  }
  device_.write(Wrench{}, now);
  device_.stop(now);
  stats_.last_force.store(0.0, std::memory_order_relaxed);
}

}  // namespace gshaptics
