// Format detection from content and the errors for empty, missing and garbage files.

#include "gshaptics/io/scene_loader.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "gshaptics/error.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

TEST(SceneLoader, DetectsFormatFromContentNotExtension) {
  GSHAPTICS_REQUIRE_SCENES();
  const auto splat = test::read_bytes(test::scene_path("burger.splat"));
  const std::string as_bin = test::temp_path(".bin");
  test::write_bytes(as_bin, splat);
  EXPECT_EQ(load_scene(as_bin).report.format, SceneFormat::kSplat);

  const auto ply = test::read_bytes(test::scene_path("donut.ply"));
  const std::string as_splat = test::temp_path(".splat");  // a PLY with a misleading name
  test::write_bytes(as_splat, ply);
  const LoadedScene s = load_scene(as_splat);
  EXPECT_EQ(s.report.format, SceneFormat::kInriaPly);
  EXPECT_EQ(s.scene.size(), 45624u);

  EXPECT_EQ(detect_scene_format(test::read_bytes(test::scene_path("biker.spz")), "x"), SceneFormat::kSpz);
  EXPECT_EQ(load_scene(test::scene_path("biker.spz")).report.frame, SceneFrame::kRub);
  EXPECT_EQ(load_scene(test::scene_path("donut.ply")).report.frame, SceneFrame::kRdf);
  EXPECT_EQ(detect_scene_format(test::read_bytes(test::scene_path("guitar.compressed.ply")), "x"),
            SceneFormat::kCompressedPly);
}

TEST(SceneLoader, EmptyMissingAndDirectoryAreErrors) {
  const std::string empty = test::temp_path(".ply");
  test::write_bytes(empty, {});
  EXPECT_NE(test::load_error(empty).find("empty"), std::string::npos) << test::load_error(empty);
  EXPECT_NE(test::load_error("/nonexistent/scene.ply").find("cannot open"), std::string::npos);
  EXPECT_NE(test::load_error(std::filesystem::temp_directory_path().string()).find("not a regular file"),
            std::string::npos);
}

TEST(SceneLoader, GarbageNeverCrashesAndIsNamed) {
  std::mt19937_64 rng(42);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<std::uint8_t> bytes(std::size_t(1 + rng() % 5000));
    for (auto& b : bytes) b = std::uint8_t(rng());
    if (trial % 3 == 0) {  // garbage after a PLY magic
      const std::string h = "ply\nformat binary_little_endian 1.0\n";
      std::copy(h.begin(), h.end(), bytes.begin());
      if (bytes.size() < h.size()) continue;
    }
    const std::string p = test::temp_path(trial % 2 ? ".splat" : ".dat");
    test::write_bytes(p, bytes);
    try {
      const LoadedScene s = load_scene(p);
      // Random bytes can form valid .splat records only by chance; then every kept one is valid.
      for (const auto& q : s.scene.rotations) EXPECT_NEAR(q.norm(), 1.f, 1e-4f);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {
TEST(SceneLoader, ColourIsKeptOnlyWhenAsked) {
  GSHAPTICS_REQUIRE_SCENES();
  LoadOptions no_color;
  no_color.keep_color = false;
  for (const char* f : {"fruitdrops.ply", "truck.splat", "guitar.compressed.ply", "biker.spz"}) {
    const LoadedScene with = load_scene(test::scene_path(f), test::with_color());
    const LoadedScene without = load_scene(test::scene_path(f), no_color);
    EXPECT_EQ(with.scene.colors_dc.size(), with.scene.size()) << f;
    EXPECT_TRUE(without.scene.colors_dc.empty()) << f;
    EXPECT_TRUE(without.scene.sh_rest.empty()) << f;
    EXPECT_EQ(without.scene.means, with.scene.means) << f;
  }
  EXPECT_EQ(load_scene(test::scene_path("fruitdrops.ply"), test::with_color()).scene.sh_rest_count, 45);
}
}  // namespace
}  // namespace gshaptics
