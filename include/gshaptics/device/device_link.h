#pragma once
/// @file
/// The hand-off between the servo thread and a driver's own I/O thread (a vendor's servo
/// callback, a socket loop): one sample path and one command path, each a wait-free triple
/// buffer, and the rule that a command the servo thread stopped refreshing is sent as zero.
/// Every driver with a thread of its own (OpenHaptics, Haply) uses this one link, so the rule
/// that keeps a hung servo thread from leaving force on the motors is written once.
///
/// Threading: exactly one servo thread calls read(), command() and begin_session(); exactly one
/// I/O thread calls publish() and force_to_send(). All of them are wait-free, allocation-free and
/// noexcept; the counters may be read from any thread.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <atomic>
#include <cstdint>
#include <limits>

#include "gshaptics/device/haptic_device.h"
#include "gshaptics/device/triple_buffer.h"

namespace gshaptics {

/// What the I/O thread hands the servo thread, in the device's frame (m, m/s).
struct LinkSample {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  std::uint32_t buttons = 0;
};

namespace detail {
/// What the servo thread hands the I/O thread: a force in the device's frame, N, and when it was
/// written (steady_ns()).
struct LinkCommand {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  std::int64_t wall_ns = 0;
};
}  // namespace detail

class DeviceLink {
 public:
  /// `command_timeout`: a command older than this is sent as zero, s (the driver validates it;
  /// a value that is not in (0, 1e6) s makes every command stale).
  explicit DeviceLink(double command_timeout) noexcept
      : timeout_ns_(command_timeout > 0 && command_timeout < 1e6 ? static_cast<std::int64_t>(command_timeout * 1e9) : -1) {}
  DeviceLink(const DeviceLink&) = delete;
  DeviceLink& operator=(const DeviceLink&) = delete;

  /// Servo side, before the I/O thread starts: a zero command stamped now, counters at zero.
  void begin_session() noexcept {
    commands_.write(Command{Eigen::Vector3d::Zero(), steady_ns()});
    stale_.store(0, std::memory_order_relaxed);
    zeroed_before_.store(0, std::memory_order_relaxed);
  }
  /// Servo side: the newest sample. `sequence` grows by one for each new one (stamped `now`);
  /// without one the last sample comes back unchanged and the runtime's watchdog decides.
  [[nodiscard]] DeviceSample read(Nanos now) noexcept {
    LinkSample s;
    if (samples_.read_if_new(s)) {
      last_.sequence += 1;
      last_.stamp = now;
      last_.position = s.position;
      last_.velocity = s.velocity;
      last_.orientation = s.orientation;
      last_.buttons = s.buttons;
    }
    return last_;
  }
  /// Servo side: the force to send, in the device's frame, N (stamped with the steady clock).
  void command(const Eigen::Vector3d& force) noexcept { commands_.write(Command{force, steady_ns()}); }

  /// I/O side: a new sample.
  void publish(const LinkSample& s) noexcept { samples_.write(s); }
  /// I/O side: the force to send now. Zero when the newest command was written before
  /// `not_before_ns` (steady clock; a fresh connection must not replay an old force; counted
  /// when that force was not zero) or is older than the timeout (counted as stale).
  [[nodiscard]] Eigen::Vector3d force_to_send(std::int64_t not_before_ns = std::numeric_limits<std::int64_t>::min()) noexcept {
    const Command& c = commands_.read();
    if (c.wall_ns < not_before_ns) {
      if (!c.force.isZero()) zeroed_before_.fetch_add(1, std::memory_order_relaxed);
      return Eigen::Vector3d::Zero();
    }
    if (steady_ns() - c.wall_ns > timeout_ns_) {
      stale_.fetch_add(1, std::memory_order_relaxed);
      return Eigen::Vector3d::Zero();
    }
    return c.force;
  }

  /// Commands sent as zero because the servo thread had not refreshed them within the timeout.
  [[nodiscard]] std::uint64_t stale_commands() const noexcept { return stale_.load(std::memory_order_relaxed); }
  /// Non-zero commands sent as zero because they predate `not_before_ns`.
  [[nodiscard]] std::uint64_t zeroed_before() const noexcept { return zeroed_before_.load(std::memory_order_relaxed); }

 private:
  using Command = detail::LinkCommand;
  std::int64_t timeout_ns_;
  TripleBuffer<LinkSample> samples_{LinkSample{}};
  TripleBuffer<Command> commands_{Command{}};
  std::atomic<std::uint64_t> stale_{0}, zeroed_before_{0};
  DeviceSample last_;  // servo thread only
};

}  // namespace gshaptics
