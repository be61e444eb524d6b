#include "gshaptics/servo/simulated_runtime.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "gshaptics/error.h"

namespace gshaptics {

SimulatedRuntime::SimulatedRuntime(const CollisionWorld& world, HapticDevice& device, const RuntimeConfig& config)
    : SimulatedRuntime(device, config,
                       (validate_runtime_config(config, device.info()),
                        make_runtime_renderer(config, world))) {}

SimulatedRuntime::SimulatedRuntime(HapticDevice& device, const RuntimeConfig& config,
                                   std::unique_ptr<ForceRenderer> renderer)
    : device_(device), config_(config), clock_(0), log_(0) {
  period_ = validate_runtime_config(config, device.info());
  if (!renderer) throw InputError("simulated runtime: no force renderer given");
  log_ = TickLog(runtime_log_capacity(config));
  worker_ = std::make_unique<CollisionWorker>(config.tool, std::move(renderer), 1.0 / config.rate_hz, clock_);
  servo_ = std::make_unique<ServoController>(device, config.safety, period_, poses_, results_,
                                             stats_, &log_, clock_, nullptr, config.control);
  const std::size_t slots = std::size_t(config.latency_ticks) + 1;
  in_flight_.assign(slots, CollisionResult{});
}

void SimulatedRuntime::run(const SimulatedProgressFn& progress) {
  if (ran_) throw InputError("simulated runtime: run() was already called");
  ran_ = true;
  servo_->start(clock_.now());
  const Nanos t0 = servo_->start_time();
  const Nanos end_at = config_.duration > 0 ? t0 + to_nanos(config_.duration) : INT64_MAX;
  const Nanos stop_timeout = stop_ramp_limit(config_);
  // A run with no duration ends when the device does; bound it all the same (one day).
  const Nanos hard_end = t0 + to_nanos(86400.0);
  const std::size_t lat = std::size_t(config_.latency_ticks), slots = lat + 1;
  const std::uint64_t report_every =
      config_.duration > 0 ? std::max<std::uint64_t>(1, std::uint64_t(config_.duration * config_.rate_hz / 100)) : 1000;
  Nanos stop_at = -1;
  Nanos deadline = t0;
  for (std::uint64_t k = 0;; ++k) {
    clock_.set(deadline);
    if (config_.inline_query) {
      servo_->tick(deadline, worker_.get());
    } else {
      // The result the worker computed latency_ticks ago arrives now.
      const std::size_t due = std::size_t(k % slots);
      if (in_flight_[due].pose_sequence != 0) {
        results_.write(in_flight_[due]);
        in_flight_[due] = CollisionResult{};
      }
      servo_->tick(deadline, nullptr);
      // The worker answers the pose this tick published; its result is rendered lat ticks on.
      const std::size_t slot = std::size_t((k + lat) % slots);
      if (worker_->step(poses_, staged_)) (void)staged_.read_if_new(in_flight_[slot]);
    }
    if (stop_at < 0 &&
        (stop_requested_ || deadline >= end_at || device_.finished() || deadline >= hard_end || servo_->faulted())) {
      servo_->request_stop();
      stop_at = deadline;
    }
    if (stop_at >= 0 && (servo_->force_released() || deadline - stop_at >= stop_timeout)) break;
    deadline += period_;
    if (progress && config_.duration > 0 && k % report_every == 0)
      progress(std::min(1.0, to_seconds(deadline - t0) / config_.duration));
  }
  servo_->finish(clock_.now());
  if (progress) progress(1.0);
}

RuntimeSummary SimulatedRuntime::summary() const { return summarize(stats_, worker_->latency(), config_.rate_hz); }

}  // namespace gshaptics
