#pragma once
/// @file
/// The per-tick record every haptic loop logs (the simulated probe run, the real-time runtime,
/// the ROS node and the device side of a two-process run), and its one CSV writer.

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "gshaptics/collision/contact_query.h"

namespace gshaptics {

/// What happened at one servo tick. World frame, SI units. A loop fills the fields it has and
/// leaves the others at their defaults (see TickColumns for which log shows which).
struct TickRecord {
  double time = 0;          ///< scheduled tick time since the run started, s
  float jitter_us = 0;      ///< wake-up lateness, microseconds (real-time loops)
  float tick_us = 0;        ///< work in the tick, microseconds (real-time loops)
  Eigen::Vector3d position = Eigen::Vector3d::Zero();    ///< tool centre, m
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();    ///< tool velocity, m/s
  QueryCounts counts;                                    ///< of the result rendered
  Eigen::Vector3d desired = Eigen::Vector3d::Zero();     ///< force model output, N (eq. 11)
  Eigen::Vector3d force = Eigen::Vector3d::Zero();       ///< force sent to the device, N
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();      ///< torque after the safety layer, N m (about the TCP)
  Eigen::Vector3d user_force = Eigen::Vector3d::Zero();  ///< force of the (simulated) hand, N
  float query_us = 0;        ///< collision query (+ force model in the runtime), microseconds
  float result_age_us = 0;   ///< now - stamp of the rendered result's pose, microseconds
  float latency_us = -1;     ///< device side: pose -> wrench round trip, microseconds (-1: none)
  std::uint32_t flags = 0;   ///< SafetyFlag bits (servo/safety.h)
  Eigen::Vector3d proxy = Eigen::Vector3d::Zero();  ///< proxy centre of the rendered result, m
  std::uint8_t constraints = 0;                     ///< its constraint planes (0..3)
  double energy = 0;   ///< passivity observer: energy into the environment so far, J (servo/passivity.h)
  float damping = 0;   ///< passivity controller's damping this tick, N s/m
  /// What a vibrotactile device plays, of the result rendered (RenderOutput): the texture
  /// force's RMS over 20 ms, N, and the material's vibration level, [0, 1].
  float texture_rms = 0;
  float vibration = 0;
  /// Admittance control: the setpoint commanded to the device, m (the virtual tool's position,
  /// servo/admittance.h); the device's position under impedance control.
  Eigen::Vector3d setpoint = Eigen::Vector3d::Zero();
};

/// Column groups of the tick log. Each column is declared once (tick_log.cpp) with its group;
/// a log shows the groups its loop fills, always in the same order.
enum TickColumns : unsigned {
  kColumnsMotion = 1u << 0,   ///< time_s, x, y, z, vx, vy, vz
  kColumnsQuery = 1u << 1,    ///< candidates, prefiltered, contacts, query_us
  kColumnsForce = 1u << 2,    ///< fx, fy, fz, user_fx, user_fy, user_fz
  kColumnsServo = 1u << 3,    ///< desired_f*, jitter_us, tick_us, result_age_us, held, fading, flags
  kColumnsLatency = 1u << 4,  ///< latency_us
  kColumnsProxy = 1u << 5,    ///< proxy_x, proxy_y, proxy_z, constraints
  kColumnsPassivity = 1u << 6,  ///< energy_j, pc_damping
  kColumnsTorque = 1u << 7,     ///< tx, ty, tz: torque sent about the TCP, N m (compound tools)
  kColumnsAdmittance = 1u << 8, ///< setpoint_x, setpoint_y, setpoint_z: the virtual tool, m (admittance control)
};
/// The probe run's log (`simulate`, probe_log.csv): the paper's Fig. 5 quantities.
inline constexpr unsigned kProbeLogColumns =
    kColumnsMotion | kColumnsQuery | kColumnsForce | kColumnsProxy | kColumnsPassivity;
/// The real-time runtime's log (`run`, `serve`, `node`, servo_log.csv): the probe log's columns
/// first, so the same plot and the replay device read both.
inline constexpr unsigned kServoLogColumns = kProbeLogColumns | kColumnsServo | kColumnsProxy | kColumnsTorque;
/// The device side of a two-process run (`device-sim`, device_log.csv).
inline constexpr unsigned kDeviceLogColumns = kColumnsMotion | kColumnsForce | kColumnsLatency;

/// The CSV header line (no newline) of a log with `columns`.
[[nodiscard]] std::string tick_log_header(unsigned columns);

/// Writes the records as CSV (header, then one row per record) to a temporary name, then
/// renames. Throws InputError naming the file when it cannot be written.
void write_tick_log_csv(const std::string& path, std::span<const TickRecord> records, unsigned columns);

/// Per-tick log with all memory reserved up front; push() drops (and counts) records past the
/// capacity instead of allocating, so it may be called from the servo tick.
class TickLog {
 public:
  explicit TickLog(std::size_t capacity = 0) { records_.reserve(capacity); }
  void push(const TickRecord& r) noexcept {
    if (records_.size() < records_.capacity())
      records_.push_back(r);
    else
      ++dropped_;
  }
  [[nodiscard]] const std::vector<TickRecord>& records() const noexcept { return records_; }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return dropped_; }

 private:
  std::vector<TickRecord> records_;
  std::uint64_t dropped_ = 0;
};

}  // namespace gshaptics
