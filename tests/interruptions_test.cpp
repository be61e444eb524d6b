// Tests of servo/interruptions: the gap profile of a spinning thread.
#include "gshaptics/servo/interruptions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace gshaptics {
namespace {

// A clock that moves 100 ns per read and, every `every`-th read, jumps `gap_ns` instead: a
// machine that interrupts the spinning thread at a known rate for a known time.
class JumpingClock final : public Clock {
 public:
  JumpingClock(int every, Nanos gap_ns) : every_(every), gap_ns_(gap_ns) {}
  [[nodiscard]] Nanos now() const noexcept override {
    ++reads_;
    t_ += reads_ % every_ == 0 ? gap_ns_ : 100;
    return t_;
  }
  void sleep_until(Nanos) noexcept override {}

 private:
  int every_;
  Nanos gap_ns_;
  mutable long reads_ = 0;
  mutable Nanos t_ = 0;
};

TEST(Interruptions, ProfileOfKnownGaps) {
  const std::vector<double> gaps = {10, 20, 30, 40, 1000};
  const InterruptionProfile p = interruption_profile(gaps, 2.0, 5.0);
  EXPECT_EQ(p.count, 5u);
  EXPECT_DOUBLE_EQ(p.per_second, 2.5);
  EXPECT_DOUBLE_EQ(p.median_us, 30);
  EXPECT_DOUBLE_EQ(p.max_us, 1000);
  EXPECT_DOUBLE_EQ(p.p99_us, 1000);
  EXPECT_NEAR(p.lost_fraction, 1100e-6 / 2.0, 1e-15);
  EXPECT_DOUBLE_EQ(p.threshold_us, 5.0);
  // Poisson: a 100 us computation at 2.5 interruptions per second.
  EXPECT_NEAR(p.hit_probability(100), 1 - std::exp(-2.5 * 100e-6), 1e-15);
  EXPECT_EQ(p.hit_probability(0), 0);
}

TEST(Interruptions, NoGapsNoRates) {
  const InterruptionProfile p = interruption_profile({}, 1.0, 5.0);
  EXPECT_EQ(p.count, 0u);
  EXPECT_EQ(p.per_second, 0);
  EXPECT_EQ(p.median_us, 0);
  EXPECT_EQ(p.hit_probability(1e6), 0);
  EXPECT_EQ(interruption_profile(std::vector<double>{7.0}, 0.0, 5.0).per_second, 0);
}

TEST(Interruptions, MeasuresTheGapsOfTheClock) {
  // Every 1000th read jumps 40 us: one gap per 1000 * 100 ns + 40 us = 139.9 us of clock time.
  JumpingClock clock(1000, 40'000);
  const InterruptionProfile p = measure_interruptions(clock, 0.05, 5.0);
  const double period_s = (999 * 100 + 40'000) * 1e-9;
  EXPECT_NEAR(p.per_second, 1.0 / period_s, 0.01 / period_s);
  EXPECT_DOUBLE_EQ(p.median_us, 40.0);
  EXPECT_DOUBLE_EQ(p.max_us, 40.0);
  EXPECT_NEAR(p.lost_fraction, 40e-6 / period_s, 0.01);
  EXPECT_GE(p.seconds, 0.05);
  EXPECT_LT(p.seconds, 0.0502);
  // Gaps at or under the threshold are not interruptions.
  JumpingClock small(1000, 4'000);
  EXPECT_EQ(measure_interruptions(small, 0.01, 5.0).count, 0u);
}

}  // namespace
}  // namespace gshaptics
