#pragma once
/// @file
/// One servo tick (paper Sec. IV-V, docs/design.md Sec. 6): read the device, publish its pose to the
/// collision worker, take the newest collision result, pass it through the safety layer and
/// command the wrench. In admittance control the pose published is the virtual tool's, which the
/// user's force and the rendered force move, and the device is commanded its position. No threads here: HapticRuntime calls tick() from its servo thread, and
/// tests call it with a ManualClock to check hold, fade, ramp, limits and the watchdog exactly.
///
/// Threading: a ServoController belongs to the servo thread. tick() never allocates, locks,
/// logs or throws (given a device whose read()/write() keep the same promise).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "gshaptics/servo/admittance.h"
#include "gshaptics/servo/collision_worker.h"
#include "gshaptics/device/haptic_device.h"
#include "gshaptics/servo/runtime_stats.h"
#include "gshaptics/servo/safety.h"
#include "gshaptics/servo/tick_log.h"

namespace gshaptics {

class ServoController {
 public:
  /// `safety.f_max` is the configured force limit, N. `period` is the servo period, ns (> 0). `log` may be null. When `monitor` is given, every
  /// tick's record is also written to it (for a display thread, which is its single reader).
  /// `control`: impedance (command force) or admittance (command the virtual tool's position to
  /// a DeviceInfo::admittance device; servo/admittance.h).
  ServoController(HapticDevice& device, const SafetyParams& safety, Nanos period,
                  PoseChannel& poses, ResultChannel& results, RuntimeStats& stats, TickLog* log,
                  Clock& clock, TripleBuffer<TickRecord>* monitor = nullptr, const ControlParams& control = {});

  /// Starts the device, applies its own force limits to the safety layer (the limit becomes
  /// min(safety.f_max, DeviceInfo::max_force); the continuous limit DeviceInfo::max_continuous_force),
  /// and arms the soft start; `now` becomes the run's time zero. Throws what the device's
  /// start() throws.
  void start(Nanos now);
  /// One tick scheduled at `scheduled` (absolute, ns), run now. In the inline mode pass the
  /// worker: it runs between publishing the pose and reading the result. Returns the time the
  /// tick's work ended (after the device write); a tick ending after scheduled + period counts
  /// as a deadline miss.
  Nanos tick(Nanos scheduled, CollisionWorker* inline_worker = nullptr) noexcept;
  /// Begins the shutdown: later ticks ramp the force to zero through the rate limit.
  void request_stop() noexcept { stopping_ = true; }
  /// True after a stop request once the force sent is zero (and, under admittance control, the
  /// virtual tool the robot follows is at rest).
  [[nodiscard]] bool force_released() const noexcept {
    return stopping_ && safety_.last_force().squaredNorm() == 0.0 &&
           (control_.mode != ControlMode::kAdmittance || !virtual_tool_ready_ || admittance_.at_rest());
  }
  /// A fault that ends the run (the force sensor saturated): the runtime stops as on a request.
  [[nodiscard]] bool faulted() const noexcept { return faulted_; }
  /// Commands an exact zero wrench and stops the device (the last call of a run).
  void finish(Nanos now) noexcept;

  [[nodiscard]] const SafetyFilter& safety() const noexcept { return safety_; }
  /// The passivity observer and controller (energy so far).
  [[nodiscard]] const PassivityController& passivity() const noexcept { return passivity_; }
  [[nodiscard]] Nanos start_time() const noexcept { return t0_; }
  /// Admittance control: the virtual tool (its position is what the force model sees).
  [[nodiscard]] const AdmittanceController& admittance() const noexcept { return admittance_; }

 private:
  // One tick's facts, for the statistics and the log.
  struct TickFacts {
    Nanos scheduled = 0, now = 0, end = 0, result_age = 0;
    const DeviceSample* sample = nullptr;
    SafetyOutput out;
    Eigen::Vector3d torque_sent = Eigen::Vector3d::Zero();
    double damping = 0;  // the passivity controller's
    std::uint32_t flags = 0;
    bool fresh = false, have_result = false, torque_dropped = false;
  };
  // Gate 1 of the safety layer on the device's sample: watchdog, finite pose, workspace (flags).
  std::uint32_t gate_device(const DeviceSample& s, Nanos now) noexcept;
  // The tool the force model sees: the device's, or in admittance control the virtual tool.
  void tool_state(const DeviceSample& s, std::uint32_t device_flags, Eigen::Vector3d& position,
                  Eigen::Vector3d& velocity, Eigen::Quaterniond& orientation) noexcept;
  // Admittance control: the virtual tool's tick (sensor, limits, braking) and its setpoint to the
  // device; returns the tick's kFlagSetpointLimited / kFlagBraking / kFlagSensorSaturated / kFlagTaring.
  std::uint32_t drive_setpoint(const DeviceSample& s, std::uint32_t device_flags, const SafetyOutput& out,
                               Nanos now, double dt) noexcept;
  // The runtime's statistics for one tick.
  void count(const TickFacts& t) noexcept;
  // The tick's record to the log and the monitor.
  void record(const TickFacts& t) noexcept;
  HapticDevice& device_;
  SafetyFilter safety_;
  Nanos period_;
  PoseChannel& poses_;
  ResultChannel& results_;
  RuntimeStats& stats_;
  TickLog* log_;
  Clock& clock_;
  TripleBuffer<TickRecord>* monitor_;
  PassivityController passivity_;
  ControlParams control_;
  AdmittanceController admittance_;
  ForceSensorFilter sensor_;
  bool virtual_tool_ready_ = false, faulted_ = false;
  Nanos t0_ = 0, prev_now_ = 0, last_device_data_ = 0;
  std::uint64_t last_device_seq_ = 0, pose_seq_ = 0;
  bool have_device_data_ = false, stopping_ = false, was_fading_ = false;
  CollisionResult result_;
};

}  // namespace gshaptics
