#include "gshaptics/ros2/device_sim.h"

#include <cmath>
#include <string>

#include "gshaptics/error.h"
#include "gshaptics/device/clock.h"

namespace gshaptics {

DeviceLoopResult run_device_loop(HapticDevice& device, Ros2DeviceLink& link, const DeviceLoopParams& params,
                                 const std::atomic<int>* stop, const DeviceLoopProgressFn& progress) {
  if (!(params.rate_hz > 0) || !std::isfinite(params.rate_hz))
    throw InputError("device loop: rate_hz must be a positive number of Hz, got " + std::to_string(params.rate_hz));
  if (!(params.duration_s > 0) || !std::isfinite(params.duration_s))
    throw InputError("device loop: duration_s must be > 0 s, got " + std::to_string(params.duration_s));
  DeviceLoopResult out;
  const Nanos period = to_nanos(1.0 / params.rate_hz);
  const auto n_ticks = std::size_t(std::ceil(params.duration_s * params.rate_hz));
  out.ticks.reserve(n_ticks);
  out.latencies_us.reserve(n_ticks);
  MonotonicClock& clock = MonotonicClock::instance();
  const Nanos t0 = clock.now();
  device.start(t0);
  const bool admittance = device.info().admittance;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  RosTime last_echo;
  const auto progress_every = std::size_t(std::max(1.0, 2.0 * params.rate_hz));
  for (std::size_t k = 0; k < n_ticks; ++k) {
    if (stop != nullptr && stop->load(std::memory_order_relaxed) != 0) {
      out.interrupted = true;
      break;
    }
    clock.sleep_until(t0 + Nanos(k) * period);
    const Nanos now = clock.now();
    const DeviceSample s = device.read(now);
    const RosTime stamp = RosTime::now();
    link.publish(s.position, s.orientation, s.velocity, stamp);
    ++out.poses_sent;
    // An admittance-type device (a robot with a force sensor): its sensor out, its setpoint in.
    if (admittance) {
      link.publish_sensor(s.user_force, s.user_torque, stamp);
      Setpoint sp;
      if (link.take_setpoint(sp)) {
        device.write_setpoint(sp, now);
        ++out.setpoints_received;
        out.last_setpoint = sp;
      }
    }
    TickRecord r;
    Eigen::Vector3d f;
    RosTime echo;
    if (link.take_wrench(f, echo)) {
      ++out.wrenches_received;
      force = f;
      if (echo.nanos() != last_echo.nanos() && echo.nanos() > 0) {
        r.latency_us = float(double(RosTime::now().nanos() - echo.nanos()) * 1e-3);
        out.latencies_us.push_back(double(r.latency_us));
        last_echo = echo;
      }
    }
    Wrench w;
    w.force = force;
    device.write(w, now);
    r.time = to_seconds(now - t0);
    r.position = s.position;
    r.velocity = s.velocity;
    r.force = force;
    r.desired = force;
    r.user_force = s.user_force;
    out.ticks.push_back(r);
    out.peak_force = std::max(out.peak_force, force.norm());
    if (progress && k % progress_every == 0)
      progress(r.time, out.poses_sent, out.wrenches_received, force.norm());
  }
  device.stop(clock.now());
  return out;
}

}  // namespace gshaptics
