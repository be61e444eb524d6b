// antimatter15 .splat reader on the three real .splat scenes and on broken copies.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <utility>
#include <limits>

#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/scene/scene_stats.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

struct Expect {
  const char* file;
  std::uint64_t count;
  Eigen::Vector3d lo, hi;
  double above_02;
  double max_scale_median;
};

void PrintTo(const Expect& e, std::ostream* os) { *os << e.file; }

class RealSplat : public ::testing::TestWithParam<Expect> {};

TEST_P(RealSplat, CountsBoundsOpacityAndScalesMatchSources) {
  const Expect& e = GetParam();
  if (std::string(e.file) != "truck.splat") GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene s = load_scene(test::scene_path(e.file));
  EXPECT_EQ(s.report.format, SceneFormat::kSplat);
  EXPECT_EQ(s.report.in_file, e.count);
  EXPECT_EQ(s.report.loaded, e.count);
  const SceneStats st = compute_scene_stats(s.scene);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(st.bbox_min[k], e.lo[k], 1e-3);
    EXPECT_NEAR(st.bbox_max[k], e.hi[k], 1e-3);
  }
  EXPECT_NEAR(st.opacity_above[1], e.above_02, 1e-3);
  EXPECT_NEAR(st.max_scale_pct[1], e.max_scale_median, 2e-3 * e.max_scale_median);
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, RealSplat,
    ::testing::Values(
        Expect{"truck.splat", 116544, {-1.4756, -0.9603, -1.3815}, {1.727, 0.6236, 1.4522}, 0.9179, 0.005971},
        Expect{"burger.splat", 110529, {-0.7757, 0.2701, -1.4335}, {0.4472, 1.0138, -0.2191}, 0.7736, 0.005588},
        Expect{"skull.splat", 86818, {-0.704, -0.8965, -0.5982}, {0.6665, 0.3828, 0.6407}, 0.5852, 0.01294}),
    [](const auto& param_info) {
      std::string n = param_info.param.file;
      return n.substr(0, n.find('.'));
    });

TEST(SplatReader, DecodesRecordFields) {
  std::vector<std::uint8_t> rec(32, 0);
  const float pos[3] = {1.5f, -2.f, 3.f}, scale[3] = {0.1f, 0.2f, 0.3f};
  std::memcpy(rec.data(), pos, 12);
  std::memcpy(rec.data() + 12, scale, 12);
  rec[27] = 51;                                    // alpha = 0.2
  rec[28] = 128; rec[29] = 255; rec[30] = 128; rec[31] = 128;  // (0, 127/128, 0, 0)
  const LoadedScene s = read_splat(rec, "mem.splat");
  ASSERT_EQ(s.scene.size(), 1u);
  EXPECT_EQ(s.scene.means[0], Eigen::Vector3f(1.5f, -2.f, 3.f));
  EXPECT_EQ(s.scene.scales[0], Eigen::Vector3f(0.1f, 0.2f, 0.3f));
  EXPECT_FLOAT_EQ(s.scene.opacities[0], 0.2f);
  EXPECT_NEAR((s.scene.rotations[0] - Eigen::Vector4f(0, 1, 0, 0)).norm(), 0.f, 1e-6f);
}

TEST(SplatReader, NanRecordAndZeroQuaternionAreCounted) {
  GSHAPTICS_REQUIRE_SCENES();
  auto bytes = test::read_bytes(test::scene_path("skull.splat"));
  bytes.resize(32 * 10);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(bytes.data() + 32 * 3 + 4, &nan, 4);
  for (int k = 28; k < 32; ++k) bytes[32 * 7 + std::size_t(k)] = 128;
  const LoadedScene s = read_splat(bytes, "cut.splat");
  EXPECT_EQ(s.report.in_file, 10u);
  EXPECT_EQ(s.report.skipped_non_finite, 1u);
  EXPECT_EQ(s.report.skipped_zero_quaternion, 1u);
  EXPECT_EQ(s.scene.size(), 8u);
  EXPECT_EQ(s.scene.source_index[3], 4u);
}

TEST(SplatReader, TruncatedFileIsAnErrorNamingTheFile) {
  auto bytes = test::read_bytes(test::scene_path("truck.splat"));
  bytes.resize(32 * 1000 + 17);
  const std::string p = test::temp_path(".splat");
  test::write_bytes(p, bytes);
  try {
    (void)load_scene(p);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(p), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("not a multiple of the 32-byte"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace gshaptics

// What `info` reports as the seen normal's least ring: the median middle axis over the Gaussians a
// viewer draws (opacity >= 1/255), whatever the axes' order; fainter ones are not counted.
TEST(SceneStats, DrawnMiddleScaleIsTheMedianMiddleAxisOfTheDrawnGaussians) {
  gshaptics::GaussianScene g;
  const float middle[5] = {0.4f, 0.1f, 0.5f, 0.2f, 0.3f};  // median 0.3
  for (int k = 0; k < 5; ++k) {
    Eigen::Vector3f axes(2 * middle[k], middle[k], middle[k] / 3);
    if (k % 2) std::swap(axes[0], axes[1]);
    if (k % 3 == 2) std::swap(axes[1], axes[2]);
    g.push_back(Eigen::Vector3f(float(k), 0, 0), axes, Eigen::Vector4f(1, 0, 0, 0), 0.5f, std::uint32_t(k));
  }
  for (int k = 0; k < 6; ++k)  // not drawn
    g.push_back(Eigen::Vector3f(0, float(k), 0), Eigen::Vector3f(0.01f, 0.01f, 0.01f), Eigen::Vector4f(1, 0, 0, 0),
                0.001f, std::uint32_t(5 + k));
  EXPECT_FLOAT_EQ(float(gshaptics::compute_scene_stats(g).drawn_middle_scale), 0.3f);
  EXPECT_EQ(gshaptics::compute_scene_stats(gshaptics::GaussianScene{}).drawn_middle_scale, 0.0);
}
