#pragma once
/// @file
/// Time for the servo loop: monotonic nanoseconds, absolute-deadline sleeps, and a manual clock
/// that tests advance by hand.
///
/// Threading: MonotonicClock is stateless and safe from any thread. ManualClock keeps its time in
/// an atomic, so one thread may advance it while others read it.

#include <atomic>
#include <cstdint>

namespace gshaptics {

/// A point in time or a duration, in nanoseconds of a monotonic clock.
using Nanos = std::int64_t;

constexpr Nanos kNanosPerSecond = 1'000'000'000;

/// Seconds -> nanoseconds (rounded to nearest).
[[nodiscard]] constexpr Nanos to_nanos(double seconds) noexcept {
  return Nanos(seconds * 1e9 + (seconds >= 0 ? 0.5 : -0.5));
}
/// Nanoseconds -> seconds.
[[nodiscard]] constexpr double to_seconds(Nanos ns) noexcept { return double(ns) * 1e-9; }

/// std::chrono::steady_clock, ns: the time base of the drivers' I/O threads (command ages), which
/// run beside, not on, the runtime's Clock.
[[nodiscard]] std::int64_t steady_ns() noexcept;

/// The time source of the runtime. now() and sleep_until() never allocate, lock or throw.
class Clock {
 public:
  virtual ~Clock() = default;
  /// Current time, ns.
  [[nodiscard]] virtual Nanos now() const noexcept = 0;
  /// Blocks until now() >= deadline (absolute), or returns at once when it already is.
  virtual void sleep_until(Nanos deadline) noexcept = 0;
};

/// CLOCK_MONOTONIC with clock_nanosleep(TIMER_ABSTIME): absolute deadlines, so sleeping never
/// accumulates drift (POSIX.1-2008, clock_nanosleep(2)).
class MonotonicClock final : public Clock {
 public:
  [[nodiscard]] Nanos now() const noexcept override;
  void sleep_until(Nanos deadline) noexcept override;
  /// The process-wide instance.
  static MonotonicClock& instance() noexcept;
};

/// A clock that moves only when told: sleep_until() jumps to the deadline. For deterministic
/// tests of the servo logic.
class ManualClock final : public Clock {
 public:
  explicit ManualClock(Nanos start = 0) : now_(start) {}
  [[nodiscard]] Nanos now() const noexcept override { return now_.load(std::memory_order_acquire); }
  void sleep_until(Nanos deadline) noexcept override {
    if (deadline > now()) set(deadline);
  }
  void set(Nanos t) noexcept { now_.store(t, std::memory_order_release); }
  void advance(Nanos dt) noexcept { now_.fetch_add(dt, std::memory_order_acq_rel); }

 private:
  std::atomic<Nanos> now_;
};

}  // namespace gshaptics
