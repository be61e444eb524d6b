#pragma once
/// @file
/// A device whose target pose arrives from another thread at its own rate: a mouse in a browser,
/// a network link. The servo thread reads servo-rate poses interpolated between the last two
/// targets (so a 30-60 Hz input gives a smooth 1 kHz pose, one input period behind) with the
/// matching velocity. The commanded wrench is kept for whoever displays it.
///
/// Threading contract: one producer thread calls set_target() (wait-free, allocation-free);
/// the servo thread calls read()/write(). last_force() may be called from any thread.

#include <atomic>
#include <string>

#include "gshaptics/device/haptic_device.h"
#include "gshaptics/device/triple_buffer.h"

namespace gshaptics {

struct StreamDeviceParams {
  std::string name = "stream";
  /// No target for this long: the device stops delivering data, so the runtime's watchdog
  /// zeroes the force (a closed browser tab, a dead link). s.
  double input_timeout = 0.5;
  /// > 0: the timeout stretches to this many input periods when the input is slower than
  /// input_timeout / timeout_periods (a browser page at 7-15 frames/s, or stalling: one late
  /// frame must not cut the force mid-contact), up to max_input_timeout. The period is a running
  /// average of the intervals between targets. 0: input_timeout as it is (network devices).
  double timeout_periods = 0;
  double max_input_timeout = 1.0;  ///< s
  double max_rate_hz = 100000;
  /// true: interpolate between the last two targets over one input period (smooth servo-rate
  /// poses from a 30-60 Hz input, one period behind); false: use the newest target as it is
  /// (inputs at the servo rate, e.g. a device across a network).
  bool interpolate = true;
  /// true: before the first target the device sits at its initial pose and counts as alive
  /// (a mouse starting at a chosen point); false: it delivers no data until the first target
  /// (a network device must not render forces for a pose nobody sent).
  bool alive_before_first_target = true;
  Eigen::AlignedBox3d workspace{Eigen::Vector3d::Constant(-1e300), Eigen::Vector3d::Constant(1e300)};
};

/// A target pose as handed from the producer to the servo thread.
struct StreamTarget {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Nanos stamp = 0;
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  bool has_velocity = false;
};

class StreamDevice final : public HapticDevice {
 public:
  /// `initial` is the pose before any target arrives (world frame, m).
  StreamDevice(const StreamDeviceParams& params, const Eigen::Vector3d& initial);
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos now) override;
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  void stop(Nanos now) noexcept override;

  /// Producer: a new target pose arrived at `stamp` (ns on the runtime's clock). `velocity`
  /// (m/s, world) when the source measures it; otherwise it is estimated from the targets.
  void set_target(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                  Nanos stamp, const Eigen::Vector3d* velocity = nullptr) noexcept;
  /// |F| last commanded, N (any thread).
  [[nodiscard]] double last_force() const noexcept { return last_force_.load(std::memory_order_relaxed); }
  /// The input timeout in force now, s (servo thread; see StreamDeviceParams::timeout_periods).
  [[nodiscard]] double input_timeout() const noexcept;

 private:
  using Target = StreamTarget;
  StreamDeviceParams params_;
  DeviceInfo info_;
  TripleBuffer<Target> targets_;
  // Servo thread only:
  Target prev_, last_;
  bool have_last_ = false;
  std::uint64_t sequence_ = 0;
  Nanos start_ = 0;
  double period_s_ = 0;  // running average of the intervals between targets (0: none yet)
  std::atomic<double> last_force_{0};
};

}  // namespace gshaptics
