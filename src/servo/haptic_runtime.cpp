#include "gshaptics/servo/haptic_runtime.h"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "gshaptics/error.h"
#include "gshaptics/servo/realtime_thread.h"

namespace gshaptics {

namespace {

std::string errno_text(int e) { return std::strerror(e); }

}  // namespace

std::size_t runtime_log_capacity(const RuntimeConfig& c) {
  if (c.log_capacity > 0) return c.log_capacity;
  const double seconds = c.duration > 0 ? c.duration + 1.0 : 600.0;
  return std::size_t(std::ceil(seconds * c.rate_hz));
}

Nanos stop_ramp_limit(const RuntimeConfig& c) {
  double s = c.stop_timeout;
  if (c.control.mode == ControlMode::kAdmittance) {
    const RobotSafetyParams& r = c.control.robot;
    s += std::max(r.max_speed / r.max_acceleration, r.max_angular_speed / r.max_angular_acceleration);
  }
  return to_nanos(s);
}

Nanos validate_runtime_config(const RuntimeConfig& config, const DeviceInfo& info) {
  if (!(config.rate_hz > 0) || !std::isfinite(config.rate_hz))
    throw InputError("runtime: rate_hz must be a positive number of Hz");
  if (config.rate_hz > info.max_rate_hz)
    throw InputError("runtime: rate " + std::to_string(config.rate_hz) + " Hz is above what device '" +
                     info.name + "' accepts (" + std::to_string(info.max_rate_hz) + " Hz)");
  if (!(config.tool.semi_axes.minCoeff() > 0) || !config.tool.semi_axes.allFinite())
    throw InputError("runtime: tool semi-axes must be finite and > 0");
  if (!(config.duration >= 0) || !std::isfinite(config.duration)) throw InputError("runtime: duration must be >= 0 s");
  if (config.latency_ticks < 1) throw InputError("runtime: latency_ticks must be >= 1");
  if (!(config.safety.continuous_window > 0)) throw InputError("runtime: the continuous-force window must be > 0 s");
  if (config.control.mode == ControlMode::kAdmittance) {
    if (!info.admittance)
      throw InputError("runtime: admittance control needs an admittance-type device (one that measures the "
                       "user's force and takes position setpoints); '" + info.name + "' is impedance-type");
    const AdmittanceParams& a = config.control.admittance;
    if (!(a.mass > 0) || !std::isfinite(a.mass) || !(a.damping >= 0) || !std::isfinite(a.damping) ||
        !(a.inertia > 0) || !std::isfinite(a.inertia) || !(a.angular_damping >= 0) || !std::isfinite(a.angular_damping))
      throw InputError("runtime: the virtual tool's mass (kg) and inertia (kg m^2) must be > 0 and its damping "
                       "(N s/m, N m s/rad) >= 0");
    const RobotSafetyParams& r = config.control.robot;
    if (!(r.max_speed > 0) || !(r.max_acceleration > 0) || !std::isfinite(r.max_speed + r.max_acceleration) ||
        !(r.max_angular_speed > 0) || !(r.max_angular_acceleration > 0) ||
        !std::isfinite(r.max_angular_speed + r.max_angular_acceleration) || !(r.torque_dead_band >= 0) ||
        !(r.tare_time >= 0) || !(r.tare_time <= 10) || !(r.dead_band >= 0) || !std::isfinite(r.dead_band))
      throw InputError("runtime: the robot's speed and acceleration limits must be > 0, its tare time in [0, 10] s "
                       "and its dead band >= 0 N");
  } else if (info.admittance) {
    throw InputError("runtime: '" + info.name + "' is admittance-type (it takes position setpoints and does not "
                     "apply a commanded force): drive it with admittance control (--control admittance)");
  }
  const Nanos period = to_nanos(1.0 / config.rate_hz);
  if (period <= 0) throw InputError("runtime: rate too high");
  return period;
}

std::unique_ptr<ForceRenderer> make_runtime_renderer(const RuntimeConfig& config, const CollisionWorld& world) {
  return config.make_renderer ? config.make_renderer(world, config.renderer, config.query)
                              : make_force_renderer(config.renderer, world, config.query);
}

HapticRuntime::HapticRuntime(const CollisionWorld& world, HapticDevice& device,
                             const RuntimeConfig& config, Clock& clock)
    : HapticRuntime(device, config,
                    (validate_runtime_config(config, device.info()),
                     make_runtime_renderer(config, world)),
                    clock) {}

HapticRuntime::HapticRuntime(HapticDevice& device, const RuntimeConfig& config,
                             std::unique_ptr<ForceRenderer> renderer, Clock& clock)
    : device_(device), config_(config), clock_(clock), period_(0),
      log_(0) {
  period_ = validate_runtime_config(config, device.info());
  if (!renderer) throw InputError("runtime: no force renderer given");
  log_ = TickLog(runtime_log_capacity(config));
  worker_ = std::make_unique<CollisionWorker>(config.tool, std::move(renderer), 1.0 / config.rate_hz, clock);
  if (config.query_threads > 1) {
    // Pool workers on the CPUs below the worker's and the servo's (those take the last two).
    const int cpus = int(std::max(1u, std::thread::hardware_concurrency()));
    std::vector<int> pin;
    if (config.realtime.pin_threads)
      for (int k = 0; k < config.query_threads - 1 && k < cpus - 2; ++k) pin.push_back(cpus - 3 - k);
    query_pool_ = std::make_unique<QueryPool>(config.query_threads, pin);
    for (const std::string& w : query_pool_->warnings()) warnings_.push_back(w);
    worker_->renderer().set_executor(query_pool_.get(), config.parallel_min_candidates);
  }
  servo_ = std::make_unique<ServoController>(device, config.safety, period_, poses_, results_,
                                             stats_, &log_, clock, &monitor_, config.control);
}

HapticRuntime::~HapticRuntime() {
  request_stop();
  go_.store(true);
  worker_stop_.store(true);
  pose_signal_.fetch_add(1);
  pose_signal_.notify_all();
  if (servo_thread_.joinable()) servo_thread_.join();
  if (worker_thread_.joinable()) worker_thread_.join();
}

void HapticRuntime::apply_realtime() {
  const RealtimeOptions& rt = config_.realtime;
  if (rt.lock_memory && mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
    warnings_.push_back("memory locking (mlockall) refused: " + errno_text(errno) +
                        "; page faults may delay ticks (raise RLIMIT_MEMLOCK, e.g. ulimit -l)");
  const auto set_priority = [&](std::thread& t, int prio, const char* who) {
    if (prio <= 0 || !t.joinable()) return;
    const int e = set_fifo_priority(t.native_handle(), prio);
    if (e != 0)
      warnings_.push_back(std::string("real-time priority (SCHED_FIFO ") + std::to_string(prio) +
                          ") for the " + who + " thread refused: " + errno_text(e) +
                          "; running at normal priority (grant CAP_SYS_NICE or an rtprio limit "
                          "in /etc/security/limits.conf)");
  };
  set_priority(servo_thread_, rt.servo_priority, "servo");
  set_priority(worker_thread_, rt.worker_priority, "collision worker");
  if (rt.pin_threads) {
    const long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    if (ncpu < 2) {
      warnings_.push_back("CPU pinning skipped: only one CPU online");
      return;
    }
    const auto pin = [&](std::thread& t, long cpu, const char* who) {
      if (!t.joinable()) return;
      const int e = pin_thread_to_cpu(t.native_handle(), int(cpu));
      if (e != 0)
        warnings_.push_back(std::string("CPU pinning of the ") + who + " thread to CPU " +
                            std::to_string(cpu) + " refused: " + errno_text(e));
    };
    pin(servo_thread_, ncpu - 1, "servo");
    pin(worker_thread_, ncpu - 2, "collision worker");
  }
}

void HapticRuntime::start() {
  if (servo_thread_.joinable()) throw InputError("runtime: already started");
  running_.store(true, std::memory_order_release);
  servo_thread_ = std::thread([this] { servo_main(); });
  if (!config_.inline_query) worker_thread_ = std::thread([this] { worker_main(); });
  apply_realtime();
  go_.store(true, std::memory_order_release);
  go_.notify_all();
}

void HapticRuntime::wait() {
  if (servo_thread_.joinable()) servo_thread_.join();
  worker_stop_.store(true, std::memory_order_release);
  pose_signal_.fetch_add(1, std::memory_order_release);
  pose_signal_.notify_all();
  if (worker_thread_.joinable()) worker_thread_.join();
  if (start_error_) std::rethrow_exception(std::exchange(start_error_, nullptr));
}

void HapticRuntime::worker_main() {
  go_.wait(false, std::memory_order_acquire);
  std::uint32_t seen = pose_signal_.load(std::memory_order_acquire);
  while (!worker_stop_.load(std::memory_order_acquire)) {
    // Sleep until the servo thread publishes a pose (futex wait; no lock, no spinning).
    pose_signal_.wait(seen, std::memory_order_acquire);
    seen = pose_signal_.load(std::memory_order_acquire);
    worker_->step(poses_, results_);
  }
}

void HapticRuntime::servo_main() {
  go_.wait(false, std::memory_order_acquire);
  // Without a real-time policy, Linux may wake a sleeper up to its timer slack (50 us by
  // default) late; 1 ns makes clock_nanosleep wake as close to the deadline as the timer allows.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  try {
    servo_->start(clock_.now());
  } catch (...) {
    start_error_ = std::current_exception();
    running_.store(false, std::memory_order_release);
    return;
  }
  CollisionWorker* inline_worker = config_.inline_query ? worker_.get() : nullptr;
  const Nanos t0 = servo_->start_time();
  const Nanos end_at = config_.duration > 0 ? t0 + to_nanos(config_.duration) : INT64_MAX;
  const Nanos stop_timeout = stop_ramp_limit(config_);
  Nanos stop_at = -1;
  Nanos deadline = t0;
  const Nanos spin = to_nanos(config_.realtime.spin_s);
  for (;;) {
    if (spin > 0) {
      clock_.sleep_until(deadline - spin);
      while (clock_.now() < deadline) {
      }
    } else {
      clock_.sleep_until(deadline);
    }
    const Nanos end = servo_->tick(deadline, inline_worker);
    if (!config_.inline_query) {
      pose_signal_.fetch_add(1, std::memory_order_release);
      pose_signal_.notify_one();
    }
    if (stop_at < 0 &&
        (stop_requested_.load(std::memory_order_relaxed) || deadline >= end_at || device_.finished() ||
         servo_->faulted())) {
      servo_->request_stop();
      stop_at = deadline;
    }
    if (stop_at >= 0 && (servo_->force_released() || deadline - stop_at >= stop_timeout)) break;
    deadline += period_;
    if (end > deadline) {
      // Behind by more than a period: drop the periods already past instead of bursting.
      const Nanos behind = (end - deadline) / period_;
      if (behind > 0) {
        deadline += behind * period_;
        stats_.skipped_periods.fetch_add(std::uint64_t(behind), std::memory_order_relaxed);
      }
    }
  }
  servo_->finish(clock_.now());
  running_.store(false, std::memory_order_release);
}

bool HapticRuntime::latest_tick(TickRecord& out) noexcept {
  if (monitor_.read_if_new(latest_)) have_latest_ = true;
  out = latest_;
  return have_latest_;
}

RuntimeSummary HapticRuntime::summary() const { return summarize(stats_, worker_->latency(), config_.rate_hz); }

}  // namespace gshaptics
