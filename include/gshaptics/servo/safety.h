#pragma once
/// @file
/// The safety layer between the force model and the device: what a device that can push a
/// person must do when something goes wrong. Applied by the servo loop on every tick, in order:
///   1. device gate: no fresh device data within `device_timeout` (watchdog), a non-finite pose or
///      a pose outside the device's workspace -> zero force at once, and the soft start re-arms;
///   2. staleness: the newest collision result is held while it is at most `hold_timeout` old,
///      then faded linearly to zero over `fade_time` (the paper's asynchronous hold, bounded);
///   3. soft start: force scaled by a ramp 0 -> 1 over `ramp_time` after start and every resume,
///      applied to the limited force (so |F| <= ramp * f_max while it ramps);
///   4. force limit: |F| <= min(SafetyParams::f_max, the device's own peak force
///      (DeviceInfo::max_force)), whatever the options say: F_max is the safety layer's, for
///      every renderer; then the continuous limit: the
///      force's mean square over an exponential window of `continuous_window` s is kept at or
///      below the device's continuous force squared (DeviceInfo::max_continuous_force), the I^2 t
///      motor protection of servo drives (heat ~ current^2 ~ force^2): short peaks up to f_max
///      pass, a sustained push settles at the continuous force;
///   5. force-rate limit: |F(t) - F(t - dt)| <= max_force_rate * dt.
/// A stop request ramps the force to zero through the rate limit, then the loop ends.
///
/// Threading: a SafetyFilter belongs to the servo thread. apply() never allocates, locks, logs or
/// throws.

#include <Eigen/Core>
#include <cstdint>
#include <limits>

#include "gshaptics/device/clock.h"
#include "gshaptics/servo/passivity.h"

namespace gshaptics {

/// Limits and time-outs. Units: N, N/s, s.
struct SafetyParams {
  double f_max = 30;              ///< configured force limit F_max, N (> 0); the device's may be lower
  double max_force_rate = 5000;   ///< N/s: 5 N per 1 ms tick
  double hold_timeout = 0.020;    ///< age of the newest result (since its pose) held at full force, s
  double fade_time = 0.020;       ///< linear fade after hold_timeout, s
  double ramp_time = 0.5;         ///< soft start, s
  double device_timeout = 0.010;  ///< watchdog: device data older than this zeroes the force, s
  /// Torque limit, N m (compound tools on 6-DoF devices; the device's own DeviceInfo::max_torque
  /// binds too). 0.5 N m is about what desktop 6-DoF arms give (Phantom Premium 6DOF: 0.2-0.5).
  double tau_max = 0.5;
  double max_torque_rate = 50;    ///< N m/s: 0.05 N m per 1 ms tick
  /// Time constant of the continuous-force (I^2 t) average, s. The RMS force over this window
  /// stays at or below the device's continuous force.
  double continuous_window = 2.0;
  /// The passivity observer and controller the servo step runs before this layer's limits
  /// (servo/passivity.h; Hannaford & Ryu 2002). On by default.
  PassivityParams passivity;
};

/// The force limits in force for a run, and what set them.
struct ForceLimits {
  double f_max = 30;            ///< peak limit applied, N
  double option_f_max = 30;     ///< the configured F_max, N
  double device_max = 0;        ///< the device's own peak force, N (+inf: none)
  double continuous = 0;        ///< the device's continuous force, N (+inf: none)
  bool bound_by_device = false; ///< f_max is the device's limit, below the configured one
};

/// Why a tick's force differs from the force model's (bit flags, several may be set).
enum SafetyFlag : std::uint32_t {
  kFlagHeld = 1u << 0,          ///< no new collision result this tick: the previous one is held
  kFlagFading = 1u << 1,        ///< result older than hold_timeout: fading
  kFlagFaded = 1u << 2,         ///< result older than hold_timeout + fade_time: force zero
  kFlagNoResult = 1u << 3,      ///< no collision result yet
  kFlagRamping = 1u << 4,       ///< soft start below full scale
  kFlagForceLimited = 1u << 5,  ///< clipped to f_max
  kFlagRateLimited = 1u << 6,   ///< clipped by max_force_rate
  kFlagWatchdog = 1u << 7,      ///< device data stopped: force zero
  kFlagInvalidPose = 1u << 8,   ///< NaN/Inf in the device sample: force zero, pose not used
  kFlagOutsideWorkspace = 1u << 9,  ///< tool centre outside the device workspace: force zero
  kFlagStopping = 1u << 10,     ///< stop requested: ramping down to zero
  kFlagContinuousLimited = 1u << 11,  ///< held below f_max by the device's continuous-force budget
  kFlagPassivity = 1u << 12,    ///< the passivity controller added damping (servo/passivity.h)
  kFlagTorqueLimited = 1u << 13,  ///< torque clipped to the torque limit or its rate
  kFlagTorqueDropped = 1u << 14,  ///< torque asked of a device that renders force only: not sent
  // Admittance control (servo/admittance.h):
  kFlagSetpointLimited = 1u << 15,  ///< the setpoint held to the robot's speed, acceleration or workspace
  kFlagBraking = 1u << 16,          ///< the virtual tool brakes to rest (stale device, stop, fault)
  kFlagSensorSaturated = 1u << 17,  ///< the force sensor read its range: the run stops
  kFlagTaring = 1u << 18,           ///< the force sensor is being tared: the virtual tool holds still
};

/// What the safety layer knows at one tick.
struct SafetyInput {
  Nanos now = 0;
  Eigen::Vector3d desired = Eigen::Vector3d::Zero();  ///< force of the newest result, N
  Eigen::Vector3d desired_torque = Eigen::Vector3d::Zero();  ///< its torque about the TCP, N m
  bool have_result = false;   ///< a collision result exists
  bool fresh_result = false;  ///< it arrived since the previous tick
  Nanos result_age = 0;       ///< now - stamp of the pose the result answers, ns
  bool device_ok = true;      ///< gate 1 passed (data fresh, finite, inside the workspace)
  std::uint32_t device_flags = 0;  ///< kFlagWatchdog / kFlagInvalidPose / kFlagOutsideWorkspace
  bool stopping = false;      ///< a stop was requested
};

/// The force to send and why.
struct SafetyOutput {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< N
  /// N m: the same gates, hold, fade, ramp and stop as the force, its own limit and rate limit.
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
  std::uint32_t flags = 0;                          ///< SafetyFlag bits
  double scale = 0;  ///< hold/fade factor times ramp factor in [0, 1]
};

class SafetyFilter {
 public:
  explicit SafetyFilter(const SafetyParams& params = {})
      : params_(params), f_max_(params.f_max), option_f_max_(params.f_max) {}
  /// The device's own limits (DeviceInfo::max_force, ::max_continuous_force; N, +inf: none):
  /// the peak limit becomes min(configured F_max, device peak). Call after the device started
  /// (vendor drivers learn their limits then); ServoController::start does.
  void set_device_limits(double peak, double continuous) noexcept;
  /// The device's own torque limit (DeviceInfo::max_torque, N m; +inf: none): the torque limit
  /// becomes min(SafetyParams::tau_max, this).
  void set_device_torque_limit(double peak) noexcept;
  /// The torque limit in force, N m.
  [[nodiscard]] double tau_max() const noexcept { return tau_max_; }
  /// Arms the soft start at `now` and empties the continuous-force average (call at start).
  void reset(Nanos now) noexcept;
  /// One tick; `dt` is the time since the previous tick, s (> 0).
  SafetyOutput apply(const SafetyInput& in, double dt) noexcept;
  [[nodiscard]] const SafetyParams& params() const noexcept { return params_; }
  /// The peak force limit in force, N: min(configured F_max, the device's peak force).
  [[nodiscard]] double f_max() const noexcept { return f_max_; }
  [[nodiscard]] ForceLimits limits() const noexcept;
  /// The continuous-force average: mean square force over the window, N^2.
  [[nodiscard]] double mean_square_force() const noexcept { return heat_; }
  /// The force last sent, N.
  [[nodiscard]] const Eigen::Vector3d& last_force() const noexcept { return last_; }

 private:
  SafetyParams params_;
  double f_max_, option_f_max_;
  double device_peak_ = std::numeric_limits<double>::infinity();
  double continuous_ = std::numeric_limits<double>::infinity();
  double heat_ = 0;  // mean square of the force sent over continuous_window, N^2
  Eigen::Vector3d last_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_torque_ = Eigen::Vector3d::Zero();
  double tau_max_ = params_.tau_max;
  Nanos ramp_start_ = 0;
  bool gated_ = false;  // gate 1 closed on the previous tick: re-arm the ramp when it opens
};

}  // namespace gshaptics
