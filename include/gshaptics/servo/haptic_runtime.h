#pragma once
/// @file
/// The real-time haptic runtime (paper Sec. IV-V): a servo thread ticking at a fixed rate on
/// absolute deadlines and, in the decoupled mode (the paper's, the default), a collision worker
/// thread; the servo loop never waits on collision work and renders the newest valid force
/// through the safety layer.
///
/// Threading contract:
///   - start(), wait(), request_stop() and the accessors are called from one controlling thread
///     (the CLI's main thread). request_stop() is a single atomic store, so it may also be
///     called from any thread.
///   - Between start() and the end of wait(), the servo thread owns the device and the servo
///     state; the worker thread owns the CollisionWorker. They share only the two triple buffers
///     (PoseChannel, ResultChannel) and relaxed atomic counters (stats()).
///   - log() and summary() are complete after wait() returned.

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/servo/admittance.h"
#include "gshaptics/servo/collision_worker.h"
#include "gshaptics/device/haptic_device.h"
#include "gshaptics/servo/query_pool.h"
#include "gshaptics/servo/runtime_stats.h"
#include "gshaptics/servo/safety.h"
#include "gshaptics/servo/servo_controller.h"

namespace gshaptics {

/// How the runtime asks the OS for real-time service. Each step that the OS refuses is reported
/// as a warning; the run goes on without it.
struct RealtimeOptions {
  int servo_priority = 80;   ///< SCHED_FIFO priority of the servo thread (0: do not ask)
  int worker_priority = 70;  ///< SCHED_FIFO priority of the collision worker (0: do not ask)
  bool pin_threads = true;   ///< servo thread on the last CPU, worker on the one before it
  bool lock_memory = false;  ///< mlockall(MCL_CURRENT | MCL_FUTURE): no page faults in a tick
  /// Sleep until this long before each deadline, then spin on the clock: trades CPU time on the
  /// servo's core for wake-up jitter below the kernel's timer latency. 0: sleep only.
  double spin_s = 0;
};

/// The runtime's default execution mode, for every entry point (real-time runs, simulated runs,
/// probe runs, the fidelity matrix): inline, the query inside the tick. Measured on the fidelity
/// matrix (bench/RESULTS.md, "One servo step"): the decoupled worker's one tick of force age makes
/// 154 of 1,100 press cycles active (W < 0), inline 4; and the renderers' p99 on the shared
/// scenes (at most about 250 us) fits the 1 ms tick. Choose the decoupled worker
/// (inline_query = false) for a renderer whose p99 does not fit the tick budget.
inline constexpr bool kDefaultInlineQuery = true;

/// The servo rate every loop runs at unless told otherwise, Hz (paper Sec. IV: 1 kHz). The one
/// home of that default: the runtime, the probe run, the benchmarks and the ROS device simulator
/// read it.
inline constexpr double kDefaultServoRateHz = 1000;

/// Makes a run's renderer on its world with the config's renderer spec and query options, instead
/// of make_force_renderer(): a scene with rigid objects renders through its own
/// (objects/object_renderer.h). Called once, at set-up; may throw InputError.
using RendererFactory =
    std::function<std::unique_ptr<ForceRenderer>(const CollisionWorld&, const RendererSpec&, const QueryOptions&)>;

struct RuntimeConfig {
  double rate_hz = kDefaultServoRateHz;  ///< servo rate, Hz (paper: 1 kHz)
  bool inline_query = kDefaultInlineQuery;  ///< query inside the tick instead of on the worker thread
  /// Simulated time only (SimulatedRuntime), decoupled mode: ticks from a pose to the first tick
  /// that renders its result (>= 1; HapticRuntime's worker thread answers within 1-2 ticks).
  int latency_ticks = 1;
  double duration = 0;      ///< s; 0: until request_stop() or the device finishes
  /// Longest stop ramp: the force is zeroed at the latest this long after a stop request, s.
  double stop_timeout = 0.1;
  ToolShape tool;
  RendererSpec renderer;  ///< the force renderer and its parameters (default: the proxy)
  /// When set, makes the renderer instead of make_force_renderer(renderer, world, query).
  RendererFactory make_renderer;
  QueryOptions query;
  /// Threads sharing one large query's narrow phase (the paper model's contact query), the
  /// collision worker included: 1: none besides it. Workers are pinned to the CPUs below the
  /// worker's and the servo's when pinning is on. See servo/query_pool.h.
  int query_threads = 1;
  /// Queries with fewer candidates stay on one thread (waking workers costs microseconds).
  std::size_t parallel_min_candidates = 2048;
  SafetyParams safety;
  /// Impedance (command force; every device) or admittance control (command the virtual tool's
  /// position; DeviceInfo::admittance devices only). servo/admittance.h.
  ControlParams control;
  RealtimeOptions realtime;
  /// Ticks kept in the per-tick log (reserved up front). 0: duration * rate + 1 s worth when a
  /// duration is set, else 10 minutes' worth.
  std::size_t log_capacity = 0;
};

/// Checks `config` against `device` (rate within its limit, tool axes > 0, duration >= 0,
/// latency_ticks >= 1, admittance control only on an admittance-type device with a virtual
/// tool of positive mass, and an admittance-type device only under admittance control) and returns the servo period, ns. Throws InputError naming the setting.
/// HapticRuntime and SimulatedRuntime both call it.
Nanos validate_runtime_config(const RuntimeConfig& config, const DeviceInfo& device);
/// The renderer a run of `config` uses on `world`: config.make_renderer's when set, else
/// make_force_renderer(config.renderer, world, config.query). Throws InputError as they do.
[[nodiscard]] std::unique_ptr<ForceRenderer> make_runtime_renderer(const RuntimeConfig& config,
                                                                   const CollisionWorld& world);

/// The longest stop ramp of a run, ns: config.stop_timeout, plus under admittance control the time
/// the virtual tool takes to brake from the speed limit (max_speed / max_acceleration), so the
/// robot comes to rest before the run ends.
Nanos stop_ramp_limit(const RuntimeConfig& config);

/// The log capacity a run reserves: config.log_capacity, or duration * rate + 1 s worth when a
/// duration is set, else 10 minutes' worth.
std::size_t runtime_log_capacity(const RuntimeConfig& config);

class HapticRuntime {
 public:
  /// Validates the config against the device (rate within its limit, tool axes > 0) and reserves
  /// all memory. Throws InputError naming the setting that is wrong.
  HapticRuntime(const CollisionWorld& world, HapticDevice& device, const RuntimeConfig& config,
                Clock& clock = MonotonicClock::instance());
  /// With the caller's own renderer (any ForceRenderer; config.renderer is then not used).
  HapticRuntime(HapticDevice& device, const RuntimeConfig& config, std::unique_ptr<ForceRenderer> renderer,
                Clock& clock = MonotonicClock::instance());
  ~HapticRuntime();
  HapticRuntime(const HapticRuntime&) = delete;
  HapticRuntime& operator=(const HapticRuntime&) = delete;

  /// Starts the threads (and the device, on the servo thread). Throws InputError when the device
  /// cannot start. Returns at once.
  void start();
  /// Asks the run to end: the force ramps to zero, the device is left at zero force.
  void request_stop() noexcept { stop_requested_.store(true, std::memory_order_relaxed); }
  /// True while the servo thread runs.
  [[nodiscard]] bool running() const noexcept { return running_.load(std::memory_order_acquire); }
  /// Blocks until the run has ended and the threads are joined; rethrows a device start error.
  void wait();

  [[nodiscard]] const RuntimeStats& stats() const noexcept { return stats_; }
  [[nodiscard]] const CollisionWorker& worker() const noexcept { return *worker_; }
  void set_observer(ResultObserver* observer) noexcept { worker_->set_observer(observer); }
  /// Messages about real-time service the OS refused (priority, affinity, memory locking).
  [[nodiscard]] const std::vector<std::string>& warnings() const noexcept { return warnings_; }
  [[nodiscard]] const TickLog& log() const noexcept { return log_; }
  [[nodiscard]] RuntimeSummary summary() const;
  [[nodiscard]] const RuntimeConfig& config() const noexcept { return config_; }
  /// The newest servo tick (pose, counts, force sent, flags), for one display thread: the single
  /// reader of this hand-off. Returns false before the first tick.
  bool latest_tick(TickRecord& out) noexcept;

 private:
  void servo_main();
  void worker_main();
  void apply_realtime();

  HapticDevice& device_;
  RuntimeConfig config_;
  Clock& clock_;
  Nanos period_;
  PoseChannel poses_;
  ResultChannel results_;
  RuntimeStats stats_;
  TickLog log_;
  TripleBuffer<TickRecord> monitor_;
  TickRecord latest_;
  bool have_latest_ = false;
  std::unique_ptr<QueryPool> query_pool_;  // declared before the worker: outlives its use
  std::unique_ptr<CollisionWorker> worker_;
  std::unique_ptr<ServoController> servo_;
  std::thread servo_thread_, worker_thread_;
  std::atomic<bool> go_{false}, stop_requested_{false}, running_{false}, worker_stop_{false};
  std::atomic<std::uint32_t> pose_signal_{0};  // bumped by the servo thread: wakes the worker
  std::exception_ptr start_error_;
  std::vector<std::string> warnings_;
};

}  // namespace gshaptics
