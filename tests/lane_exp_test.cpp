// lane_exp against std::exp (glibc's, correctly rounded to within an ulp) over the range the
// shaded normal uses and beyond, and its fixed points.
#include "gshaptics/force/lane_exp.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace gshaptics {
namespace {

TEST(LaneExp, MatchesStdExpWithinAFewUlpsOnNonPositiveArguments) {
  std::mt19937_64 rng(3);
  double worst = 0;
  const auto check = [&](double x) {
    const double ref = std::exp(x), got = lane_exp(x);
    const double rel = std::fabs(got - ref) / ref;
    worst = std::max(worst, rel);
    ASSERT_LT(rel, 4 * std::numeric_limits<double>::epsilon()) << "x = " << x << ": " << got << " vs " << ref;
  };
  std::uniform_real_distribution<double> near(-40.0, 0.0), far(-708.0, -40.0), tiny(-1e-6, 0.0);
  for (int i = 0; i < 200000; ++i) check(near(rng));
  for (int i = 0; i < 20000; ++i) check(far(rng));
  for (int i = 0; i < 20000; ++i) check(tiny(rng));
  // The reduction's seams: multiples of ln 2 / 2, where n steps.
  for (int k = -2040; k <= 0; ++k) {
    const double x = k * 0.5 * std::log(2.0);
    check(x);
    check(std::nextafter(x, -1e9));
    check(std::nextafter(x, 1e9) > 0 ? 0.0 : std::nextafter(x, 1e9));
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(LaneExp, IsOneAtZeroClampsBelowAndKeepsNaN) {
  EXPECT_EQ(lane_exp(0.0), 1.0);
  EXPECT_EQ(lane_exp(-0.0), 1.0);
  EXPECT_EQ(lane_exp(1.0), 1.0);  // x > 0 is taken as 0
  EXPECT_EQ(lane_exp(-800.0), lane_exp(-708.0));
  EXPECT_GT(lane_exp(-708.0), 0.0);
  EXPECT_TRUE(std::isnormal(lane_exp(-1e300)));
  EXPECT_TRUE(std::isnan(lane_exp(std::numeric_limits<double>::quiet_NaN())));
}

}  // namespace
}  // namespace gshaptics
