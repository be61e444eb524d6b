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

TEST(SpzAsGzip, V4IsRepackedAsV3WithTheSameGaussians) {
  GSHAPTICS_REQUIRE_SCENES();
  const auto v4 = test::read_bytes(test::scene_path("biker.spz"));
  ASSERT_EQ(v4[0], 'N');  // the real file is v4 (NGSP header, zstd streams)
  const std::vector<std::uint8_t> gz = spz_as_gzip(v4, "biker.spz");
  ASSERT_GE(gz.size(), 2u);
  EXPECT_EQ(gz[0], 0x1f);
  EXPECT_EQ(gz[1], 0x8b);
  const LoadOptions colour = test::with_color();
  const LoadedScene a = read_spz(v4, "v4", colour);
  const LoadedScene b = read_spz(gz, "v3", colour);
  EXPECT_EQ(b.report.version, 3);
  ASSERT_EQ(a.scene.size(), b.scene.size());
  for (std::size_t i = 0; i < a.scene.size(); ++i) {  // the same bytes, so bit-identical values
    ASSERT_EQ(a.scene.means[i], b.scene.means[i]) << i;
    ASSERT_EQ(a.scene.scales[i], b.scene.scales[i]) << i;
    ASSERT_EQ(a.scene.rotations[i], b.scene.rotations[i]) << i;
    ASSERT_EQ(a.scene.opacities[i], b.scene.opacities[i]) << i;
    ASSERT_EQ(a.scene.colors_dc[i], b.scene.colors_dc[i]) << i;
  }
  // A gzip (v2/v3) file comes back unchanged; garbage is an error naming the file.
  EXPECT_EQ(spz_as_gzip(gz, "v3"), gz);
  std::vector<std::uint8_t> broken(v4.begin(), v4.begin() + 40);
  try {
    (void)spz_as_gzip(broken, "broken.spz");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("broken.spz"), std::string::npos);
  }
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
