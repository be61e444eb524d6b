// The world cache: a round trip gives an identical world (records, BVH, frame, bounds, and the
// same query results); another scene, other parameters, a truncated file and a flipped byte are
// each detected (and say why); a folder that cannot be written is an error naming the file,
// never a crash.

#include "gshaptics/collision/world_cache.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/error.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/sim/pose_sampler.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

namespace fs = std::filesystem;

struct CacheFixture : ::testing::Test {
  void SetUp() override {
    dir = test::temp_path("-worldcache");
    fs::create_directories(dir);
    scene_path = test::data_path("truck.splat");
    config.registration = load_registration_file(test::data_path("truck.registration.json"));
    loaded = load_scene(scene_path);
    world = std::make_unique<CollisionWorld>(CollisionWorld::build(loaded.scene, config));
    key = world_cache_key(scene_path, config);
    path = world_cache_file(dir, scene_path, key);
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string dir, scene_path, path;
  WorldConfig config;
  LoadedScene loaded;
  std::unique_ptr<CollisionWorld> world;
  WorldCacheKey key;
};

TEST_F(CacheFixture, RoundTripGivesAnIdenticalWorld) {
  write_world_cache(*world, key, path, loaded.report);
  EXPECT_NE(path.find("truck-"), std::string::npos);
  EXPECT_TRUE(path.ends_with(".gshworld"));
  std::string why;
  const std::optional<CachedWorld> c = open_world_cache(path, key, &why);
  ASSERT_TRUE(c.has_value()) << why;
  const CollisionWorld& w = c->world;
  ASSERT_EQ(w.size(), world->size());
  EXPECT_EQ(std::memcmp(w.gaussians().data(), world->gaussians().data(), w.size() * sizeof(CollisionGaussian)), 0);
  ASSERT_EQ(w.bvh().nodes().size(), world->bvh().nodes().size());
  EXPECT_EQ(std::memcmp(w.bvh().nodes().data(), world->bvh().nodes().data(), w.bvh().nodes().size() * sizeof(BvhNode)), 0);
  EXPECT_EQ(w.bvh().depth(), world->bvh().depth());
  EXPECT_EQ(w.up(), world->up());
  EXPECT_EQ(w.bounds_lo(), world->bounds_lo());
  EXPECT_EQ(w.bounds_hi(), world->bounds_hi());
  EXPECT_EQ(w.scene_to_world().scale, world->scene_to_world().scale);
  EXPECT_EQ(w.scene_to_world().rotation.coeffs(), world->scene_to_world().rotation.coeffs());
  EXPECT_EQ(w.scene_to_world().translation, world->scene_to_world().translation);
  EXPECT_EQ(w.config().min_opacity, world->config().min_opacity);
  EXPECT_EQ(w.config().leaf_size, world->config().leaf_size);
  EXPECT_EQ(c->source.format, loaded.report.format);
  EXPECT_EQ(c->source.loaded, loaded.report.loaded);
  EXPECT_EQ(c->source.in_file, loaded.report.in_file);
  // The mapped world answers queries exactly like the built one.
  PoseSamplerParams p;
  p.count = 50;
  ContactQuery a(*world), b(w);
  for (const ToolEllipsoid& t : sample_poses(*world, p)) {
    a.run(t);
    b.run(t);
    ASSERT_EQ(a.result().contacts().size(), b.result().contacts().size());
    for (std::size_t i = 0; i < a.result().contacts().size(); ++i) {
      EXPECT_EQ(a.result().contacts()[i].index, b.result().contacts()[i].index);
      EXPECT_EQ(a.result().contacts()[i].k_min, b.result().contacts()[i].k_min);
    }
  }
  // The world outlives its opener's other copies: copies share the mapping.
  const CollisionWorld copy = w;
  EXPECT_EQ(copy.gaussians().data(), w.gaussians().data());
}

TEST_F(CacheFixture, AnotherSceneOrOtherParametersAreStale) {
  write_world_cache(*world, key, path);
  std::string why;
  WorldCacheKey other = key;
  other.scene_hash ^= 1;
  EXPECT_FALSE(open_world_cache(path, other, &why).has_value());
  EXPECT_EQ(why, "stale: built from another scene");
  // A scene file with one byte changed has another key.
  const std::string copy = dir + "/copy.splat";
  std::vector<std::uint8_t> bytes = test::read_bytes(scene_path);
  bytes[bytes.size() / 2] ^= 0x40;
  test::write_bytes(copy, bytes);
  EXPECT_NE(world_cache_key(copy, config).scene_hash, key.scene_hash);
  // Other parameters: another opacity threshold, sigma, registration, up axis or leaf size.
  for (int k = 0; k < 5; ++k) {
    WorldConfig c = config;
    if (k == 0) c.min_opacity = 0.25f;
    if (k == 1) c.sigma = 2.0;
    if (k == 2) c.registration.scale *= 1.0000001;
    if (k == 3) c.up = UpAxis::kYDown;
    if (k == 4) c.leaf_size = 16;
    WorldCacheKey changed = key;
    changed.params_hash = world_config_hash(c);
    EXPECT_NE(changed.params_hash, key.params_hash) << k;
    EXPECT_FALSE(open_world_cache(path, changed, &why).has_value()) << k;
    EXPECT_EQ(why, "stale: built with other parameters") << k;
  }
}

TEST_F(CacheFixture, TruncatedFlippedAndForeignFilesAreDetected) {
  write_world_cache(*world, key, path);
  const std::vector<std::uint8_t> good = test::read_bytes(path);
  std::string why;
  // Truncated by one byte, and to half.
  for (std::size_t cut : {std::size_t(1), good.size() / 2}) {
    test::write_bytes(path, std::vector<std::uint8_t>(good.begin(), good.end() - std::ptrdiff_t(cut)));
    EXPECT_FALSE(open_world_cache(path, key, &why).has_value());
    EXPECT_EQ(why.rfind("truncated", 0), 0u) << why;
  }
  // One flipped bit in a record, in a BVH node, in the padding.
  for (std::size_t at : {std::size_t(4096 + 80 * 1234 + 7), good.size() - 20, good.size() - 32 * 5 - 1}) {
    std::vector<std::uint8_t> bad = good;
    bad[at] ^= 0x01;
    test::write_bytes(path, bad);
    EXPECT_FALSE(open_world_cache(path, key, &why).has_value()) << at;
    EXPECT_EQ(why, "corrupt: payload hash mismatch") << at;
  }
  // One flipped bit in any byte of the header block: the build parameters, frame, bounds and
  // load report that no other check covers as well (in place, one byte at a time).
  {
    std::size_t refused = 0, header_hash = 0;
    test::write_bytes(path, good);
    std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
    for (std::size_t at = 0; at < 4096; ++at) {
      f.seekp(std::streamoff(at));
      f.put(char(good[at] ^ 0x10));
      f.flush();
      refused += open_world_cache(path, key, &why).has_value() ? 0 : 1;
      header_hash += why == "corrupt: header hash mismatch" ? 1 : 0;
      f.seekp(std::streamoff(at));
      f.put(char(good[at]));
      f.flush();
    }
    EXPECT_EQ(refused, 4096u);
    EXPECT_GT(header_hash, 4000u);  // the rest: magic, version, layout sizes and length, checked first
    ASSERT_TRUE(f.good());
  }
  // The header: magic, version, a count.
  std::vector<std::uint8_t> bad = good;
  bad[0] = 'X';
  test::write_bytes(path, bad);
  EXPECT_FALSE(open_world_cache(path, key, &why).has_value());
  EXPECT_EQ(why, "not a gshaptics world cache");
  bad = good;
  bad[8] ^= 0x02;  // version
  test::write_bytes(path, bad);
  EXPECT_FALSE(open_world_cache(path, key, &why).has_value());
  EXPECT_EQ(why, "written by another cache format version");
  test::write_bytes(path, std::vector<std::uint8_t>(100, 0));
  EXPECT_FALSE(open_world_cache(path, key, &why).has_value());
  EXPECT_EQ(why, "truncated: shorter than its header");
  EXPECT_FALSE(open_world_cache(dir + "/absent.gshworld", key, &why).has_value());
  EXPECT_EQ(why, "no cache file");
  // And the good file still opens after all that.
  test::write_bytes(path, good);
  EXPECT_TRUE(open_world_cache(path, key, &why).has_value()) << why;
}

// The chunked, threaded hash: the same value on 1, 2 or 3 threads, at chunk boundaries and off
// them; every size distinct; one flipped byte anywhere changes it.
TEST(ContentHash, SameValueWhateverTheThreadsAndEveryByteCounts) {
  constexpr std::size_t kMiB = std::size_t(1) << 20;
  std::vector<std::uint8_t> data(20 * kMiB + 3);
  std::uint64_t x = 0x9E3779B97F4A7C15ull;
  for (std::uint8_t& b : data) {
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    b = std::uint8_t(x);
  }
  std::vector<std::uint64_t> seen;
  for (std::size_t n : {std::size_t(0), std::size_t(1), 8 * kMiB - 1, 8 * kMiB, 8 * kMiB + 1, data.size()}) {
    const std::uint64_t h = content_hash(data.data(), n, 1);
    EXPECT_EQ(content_hash(data.data(), n, 2), h) << n;
    EXPECT_EQ(content_hash(data.data(), n, 3), h) << n;
    EXPECT_EQ(content_hash(data.data(), n), h) << n;
    for (std::uint64_t other : seen) EXPECT_NE(other, h) << n;
    seen.push_back(h);
  }
  const std::uint64_t whole = content_hash(data.data(), data.size(), 2);
  for (std::size_t at : {std::size_t(0), 8 * kMiB, data.size() - 1}) {
    data[at] ^= 0x10;
    EXPECT_NE(content_hash(data.data(), data.size(), 2), whole) << at;
    data[at] ^= 0x10;
  }
  EXPECT_EQ(content_hash(data.data(), data.size(), 2), whole);
}

TEST_F(CacheFixture, AnUnwritableFolderIsAnErrorNamingTheFile) {
  // A "folder" that is a regular file cannot be written into, even by root.
  const std::string blocker = dir + "/not-a-folder";
  test::write_bytes(blocker, {1, 2, 3});
  const std::string target = world_cache_file(blocker, scene_path, key);
  try {
    write_world_cache(*world, key, target);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(target), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(target));
  std::string why;
  EXPECT_FALSE(open_world_cache(target, key, &why).has_value());
}

}  // namespace
}  // namespace gshaptics
