#include "gshaptics/device/clock.h"

#include <cerrno>
#include <chrono>
#include <ctime>

namespace gshaptics {

Nanos MonotonicClock::now() const noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return Nanos(ts.tv_sec) * kNanosPerSecond + Nanos(ts.tv_nsec);
}

void MonotonicClock::sleep_until(Nanos deadline) noexcept {
  timespec ts{};
  ts.tv_sec = time_t(deadline / kNanosPerSecond);
  ts.tv_nsec = long(deadline % kNanosPerSecond);
  // Absolute deadline: an interrupted sleep resumes toward the same instant (no drift).
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

std::int64_t steady_ns() noexcept {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

MonotonicClock& MonotonicClock::instance() noexcept {
  static MonotonicClock clock;
  return clock;
}

}  // namespace gshaptics
