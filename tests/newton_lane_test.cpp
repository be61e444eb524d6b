// The float search's building blocks in src/narrowphase/detail/newton_lane.h: exp_step (the
// step length's exponential) and log_midpoint (the bracket's bisection point). Both sit on the
// batch kernel's critical path and were written for it; a wrong one would not break K_min (the
// bracket and the double certificate keep it right) but would quietly cost iterations, which
// the kernel's own tests would not see.

#include "narrowphase/detail/newton_lane.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace gshaptics::detail {
namespace {

TEST(NewtonLane, ExpStepMatchesExpOverTheWholeStepRange) {
  // Every step the search can take, |x| <= kMaxStep, on a fine grid plus the ends.
  double worst = 0;
  for (int i = -80000; i <= 80000; ++i) {
    const float x = float(kMaxStep) * float(i) / 80000.f;
    const double want = std::exp(double(x));
    const double got = exp_step(x);
    worst = std::max(worst, std::fabs(got - want) / want);
  }
  EXPECT_LT(worst, 1e-6);  // the rounding of x log2(e) in float is most of it
  EXPECT_EQ(exp_step(0.f), 1.f);
}

TEST(NewtonLane, LogMidpointIsInsideTheBracketNearItsLogMiddle) {
  std::mt19937 rng(7);
  // Brackets anywhere in the float search's range [kMuMin, kMuMax], the widest included (their
  // bit patterns' sum needs the 32nd bit).
  std::uniform_real_distribution<double> e(std::log2(NewtonLimits<float>::kMuMin), std::log2(NewtonLimits<float>::kMuMax));
  for (int i = 0; i < 200000; ++i) {
    float lo = float(std::exp2(e(rng))), hi = float(std::exp2(e(rng)));
    if (i == 0) {
      lo = NewtonLimits<float>::kMuMin;
      hi = NewtonLimits<float>::kMuMax;
    }
    if (lo > hi) std::swap(lo, hi);
    if (!(lo < hi)) continue;
    const float m = log_midpoint<float>(lo, hi);
    ASSERT_GE(m, lo) << lo << " " << hi;
    ASSERT_LE(m, hi) << lo << " " << hi;
    const double middle = 0.5 * (std::log2(double(lo)) + std::log2(double(hi)));
    ASSERT_LT(std::fabs(std::log2(double(m)) - middle), 0.09) << lo << " " << hi;
    // A bracket wider than two floats shrinks.
    if (std::nextafter(std::nextafter(lo, hi), hi) < hi) {
      ASSERT_GT(m, lo);
      ASSERT_LT(m, hi);
    }
  }
  EXPECT_EQ(log_midpoint<double>(1.0, 4.0), 2.0);
}

TEST(NewtonLane, ApproxSqrtRatioIsWithinTenPercentAndClamped) {
  std::mt19937 rng(11);
  // num and den over the whole positive normal float range; the result is sqrt(num / den)
  // within 0.13 in log2 (9 %: half the difference of two piecewise-linear log2s, each off by at
  // most 0.086, then read back through the same piecewise-linear map), or the float search's
  // clamp where the ratio leaves it.
  std::uniform_real_distribution<double> e(-125.0, 127.0);
  const double lo = 2.0 * NewtonLimits<float>::kMuMin, hi = 0.5 * NewtonLimits<float>::kMuMax;
  double worst = 0;
  for (int i = 0; i < 200000; ++i) {
    const float num = float(std::exp2(e(rng))), den = float(std::exp2(e(rng)));
    const double want = std::sqrt(double(num) / double(den));
    const double got = approx_sqrt_ratio(num, den);
    ASSERT_GE(got, float(lo)) << num << " / " << den;
    ASSERT_LE(got, float(hi)) << num << " / " << den;
    if (want > lo * 1.1 && want < hi / 1.1) {
      worst = std::max(worst, std::fabs(std::log2(got / want)));
    } else if (want < lo / 1.1) {
      ASSERT_EQ(got, float(lo));
    } else if (want > hi * 1.1) {
      ASSERT_EQ(got, float(hi));
    }
  }
  EXPECT_LT(worst, 0.13);
  EXPECT_GT(worst, 0.01);  // it is an approximation, and the test sees it
  EXPECT_EQ(approx_sqrt_ratio(4.0f, 1.0f), 2.0f);  // exact on powers of four
}

}  // namespace
}  // namespace gshaptics::detail
