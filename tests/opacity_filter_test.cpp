#include "gshaptics/scene/opacity_filter.h"

#include <gtest/gtest.h>

namespace gshaptics {
namespace {

GaussianScene five() {
  GaussianScene s;
  const float alpha[] = {0.05f, 0.2f, 0.21f, 0.9f, 1.0f};
  for (std::uint32_t i = 0; i < 5; ++i)
    s.push_back(Eigen::Vector3f(float(i), 0, 0), Eigen::Vector3f::Constant(0.1f),
                Eigen::Vector4f(1, 0, 0, 0), alpha[i], 10 + i);
  return s;
}

TEST(OpacityFilter, KeepsStrictlyAboveThresholdWithSourceIndex) {
  OpacityFilterReport rep;
  const GaussianScene out = filter_by_opacity(five(), 0.2f, &rep);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out.source_index, (std::vector<std::uint32_t>{12, 13, 14}));
  EXPECT_FLOAT_EQ(out.means[0].x(), 2.f);
  EXPECT_EQ(rep.before, 5u);
  EXPECT_EQ(rep.after, 3u);
  EXPECT_NEAR(rep.kept_fraction(), 0.6, 1e-12);
}

TEST(OpacityFilter, ZeroThresholdKeepsAllPositive) {
  EXPECT_EQ(filter_by_opacity(five(), 0.0f).size(), 5u);
  EXPECT_EQ(filter_by_opacity(five(), 1.0f).size(), 0u);
}

}  // namespace
}  // namespace gshaptics
