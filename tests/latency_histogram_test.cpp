// The log-linear latency histogram against exact percentiles of the same samples.

#include "gshaptics/servo/latency_histogram.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace gshaptics {
namespace {

TEST(LatencyHistogram, BucketsAreContiguousAndMonotonic) {
  for (std::uint64_t v = 0; v < 100000; ++v) {
    const int i = LatencyHistogram::index(v);
    ASSERT_LE(v, LatencyHistogram::upper_edge(i)) << v;
    if (i > 0) {
      ASSERT_GT(v, LatencyHistogram::upper_edge(i - 1)) << v;
    }
  }
  const std::uint64_t big = 123'456'789'012ull;
  EXPECT_LE(big, LatencyHistogram::upper_edge(LatencyHistogram::index(big)));
}

TEST(LatencyHistogram, PercentilesWithinThreePercentOfExact) {
  LatencyHistogram h;
  std::mt19937_64 rng(7);
  std::lognormal_distribution<double> d(std::log(20000.0), 1.0);  // ~20 us median
  std::vector<double> v;
  for (int i = 0; i < 50000; ++i) {
    const auto x = std::int64_t(d(rng));
    v.push_back(double(x));
    h.record(x);
  }
  std::sort(v.begin(), v.end());
  EXPECT_EQ(h.count(), v.size());
  EXPECT_EQ(double(h.max()), v.back());
  for (double p : {50.0, 90.0, 99.0, 99.9}) {
    const double exact = v[std::size_t(std::ceil(p / 100 * double(v.size()))) - 1];
    EXPECT_GE(h.percentile(p), exact) << p;
    EXPECT_LE(h.percentile(p), exact * (1 + 1.0 / 32) + 1) << p;
  }
  EXPECT_EQ(h.percentile(100), v.back());
}

TEST(LatencyHistogram, EmptyAndNegative) {
  LatencyHistogram h;
  EXPECT_EQ(h.percentile(99), 0.0);
  h.record(-5);
  EXPECT_EQ(h.count(), 1u);
  EXPECT_EQ(h.max(), 0u);
  h.reset();
  EXPECT_EQ(h.count(), 0u);
}

}  // namespace
}  // namespace gshaptics
