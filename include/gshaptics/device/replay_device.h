#pragma once
/// @file
/// A device that plays a recorded pose log in real time (any CSV with time_s,x,y,z columns, such
/// as the probe_log.csv / servo_log.csv gshaptics writes), so a session can be re-run against a
/// new scene, registration or force model. Commanded wrenches are kept but move nothing.

#include <string>
#include <vector>

#include "gshaptics/device/haptic_device.h"

namespace gshaptics {

/// One recorded pose.
struct PoseLogRow {
  double time = 0;  ///< s from the start of the log
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
};

struct PoseLog {
  std::vector<PoseLogRow> rows;
  bool has_velocity = false;     ///< vx,vy,vz columns present (else finite differences)
  bool has_orientation = false;  ///< qw,qx,qy,qz columns present (else identity)
  std::size_t non_finite_rows = 0;  ///< rows holding NaN/Inf (kept: replayed as a faulty device)
};

/// Reads a pose log. Columns by header name: time_s, x, y, z required; vx, vy, vz and
/// qw, qx, qy, qz optional; others ignored. Times must increase. Throws InputError naming the
/// file, line and column for a missing column, a malformed number or a time that goes back.
[[nodiscard]] PoseLog load_pose_log(const std::string& path);
/// The same from the file's text; `path` names it in errors. Throws InputError only.
[[nodiscard]] PoseLog parse_pose_log(const std::string& text, const std::string& path);

/// Plays a PoseLog: linear interpolation of position (and normalised-lerp of orientation)
/// between rows; velocity from the log or by finite differences. Time zero of the log is the
/// `now` given to start(). After the last row it holds the last pose and reports finished().
class ReplayDevice final : public HapticDevice {
 public:
  /// Throws InputError when the log has no rows.
  ReplayDevice(PoseLog log, std::string name = "replay");
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos now) override;
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override { (void)now, last_ = wrench; }
  void stop(Nanos now) noexcept override { (void)now, last_ = Wrench{}; }
  [[nodiscard]] bool finished() const noexcept override { return finished_; }
  [[nodiscard]] double duration() const noexcept { return log_.rows.back().time; }
  /// Rows of the log holding NaN/Inf (replayed as a faulty device).
  [[nodiscard]] std::size_t non_finite_rows() const noexcept { return log_.non_finite_rows; }
  [[nodiscard]] const Wrench& last_wrench() const noexcept { return last_; }

 private:
  PoseLog log_;
  DeviceInfo info_;
  Nanos t0_ = 0;
  std::size_t cursor_ = 0;
  std::uint64_t sequence_ = 0;
  bool finished_ = false;
  Wrench last_;
};

}  // namespace gshaptics
