// Building the world in place: every kept Gaussian becomes exactly one record (its own values,
// registered), the records end up in BVH order (each leaf's records lie inside the leaf's box),
// and the float-box BVH build agrees with the double-box one.

#include "gshaptics/collision/collision_world.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "gshaptics/force/seen_solid.h"
#include "gshaptics/huge_pages.h"
#include "gshaptics/scene/registration.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

TEST(CollisionWorldBuild, EveryKeptGaussianIsOneRecordInsideItsLeaf) {
  const LoadedScene s = load_scene(test::data_path("truck.splat"));
  WorldConfig config;
  config.registration = load_registration_file(test::data_path("truck.registration.json"));
  config.leaf_size = 8;
  const CollisionWorld w = CollisionWorld::build(s.scene, config);
  const SimilarityTransform reg = w.scene_to_world();

  // One record per kept Gaussian, carrying that Gaussian's own values.
  std::vector<int> seen(s.scene.size(), 0);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < s.scene.size(); ++i) kept += s.scene.opacities[i] > config.min_opacity ? 1 : 0;
  ASSERT_EQ(w.size(), kept);
  std::vector<std::size_t> row_of(s.scene.size());
  for (std::size_t i = 0; i < s.scene.size(); ++i) row_of[s.scene.source_index[i]] = i;
  for (const CollisionGaussian& g : w.gaussians()) {
    ASSERT_LT(g.source_index, seen.size());
    ++seen[g.source_index];
    const std::size_t i = row_of[g.source_index];
    EXPECT_EQ(g.opacity, s.scene.opacities[i]);
    const Eigen::Vector3d c = reg.apply(s.scene.means[i].cast<double>());
    for (int k = 0; k < 3; ++k) ASSERT_EQ(g.center[k], c[k]) << "record of Gaussian " << g.source_index;
  }
  for (std::size_t i = 0; i < s.scene.size(); ++i)
    ASSERT_EQ(seen[s.scene.source_index[i]], s.scene.opacities[i] > config.min_opacity ? 1 : 0) << i;

  // Each leaf covers its records' exact boxes: the permutation put every record in its slot.
  std::size_t covered = 0;
  for (const BvhNode& n : w.bvh().nodes()) {
    if (n.count == 0) continue;
    ASSERT_LE(n.count, 8u);
    for (std::uint32_t k = n.first; k < n.first + n.count; ++k) {
      const CollisionGaussian& g = w.gaussians()[k];
      const Eigen::Vector3d h = ellipsoid_half_extent(
          rotation_matrix(g), Eigen::Vector3d(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]));
      for (int a = 0; a < 3; ++a) {
        ASSERT_LE(double(n.lo[a]), g.center[a] - h[a]) << "slot " << k;
        ASSERT_GE(double(n.hi[a]), g.center[a] + h[a]) << "slot " << k;
      }
      ++covered;
    }
  }
  EXPECT_EQ(covered, w.size());
  EXPECT_TRUE(w.bvh().order().empty());  // the permutation was used up and released
}

// The records and the BVH of a built world sit in storage aligned to 2 MiB and advised for
// transparent huge pages (a query's scattered record loads then miss the TLB far less: the
// 10.6M-Gaussian world's p99 fell from ~200 to ~60 us on a VM, bench/RESULTS.md).
TEST(CollisionWorldBuild, BigArraysAreOnHugePageBoundaries) {
  const LoadedScene s = load_scene(test::data_path("truck.splat"));
  WorldConfig config;
  config.leaf_size = 2;  // 107k records (6.8 MB) and over 2 MiB of nodes
  const CollisionWorld w = CollisionWorld::build(s.scene, config);
  ASSERT_GT(w.gaussians().size_bytes(), std::size_t(2) << 20);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(w.gaussians().data()) % (std::uintptr_t(2) << 20), 0u);
  ASSERT_GT(w.bvh().nodes().size_bytes(), std::size_t(2) << 20);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(w.bvh().nodes().data()) % (std::uintptr_t(2) << 20), 0u);
}

// The allocator the seen solid's entries, bounds and wide BVH share with the world: an array
// of 2 MiB or more starts on a huge-page boundary, a smaller one is an ordinary allocation, and
// both hold what was written (a seen probe run's tick reads a few hundred entries scattered over
// the scene; on the biker scene the sphere's render p99 fell from 31-38 to 20 us, RESULTS.md).
TEST(HugePageVector, LargeArraysStartOnAHugePageAndKeepTheirValues) {
  internal::HugePageVector<double> big((std::size_t(3) << 20) / sizeof(double));
  internal::HugePageVector<double> small(100);
  for (std::size_t i = 0; i < big.size(); ++i) big[i] = double(i);
  for (std::size_t i = 0; i < small.size(); ++i) small[i] = -double(i);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(big.data()) % (std::uintptr_t(2) << 20), 0u);
  EXPECT_EQ(big[big.size() - 1], double(big.size() - 1));
  EXPECT_EQ(small[99], -99.0);
  big.push_back(1.5);  // a reallocation keeps the contents and the alignment
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(big.data()) % (std::uintptr_t(2) << 20), 0u);
  EXPECT_EQ(big[12345], 12345.0);
  EXPECT_EQ(big.back(), 1.5);
}

// The seen solid's wide BVH of the bundled scene is over 2 MiB, so in huge pages.
TEST(HugePageVector, TheSeenSolidsTreeIsOnAHugePageBoundary) {
  const LoadedScene s = load_scene(test::data_path("truck.splat"));
  WorldConfig config;
  config.min_opacity = 1.0f / 255.0f;  // every Gaussian the seen solid keeps
  const CollisionWorld w = CollisionWorld::build(s.scene, config);
  const SeenSolid solid(w);
  ASSERT_GT(solid.tree().nodes().size_bytes(), std::size_t(2) << 20);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(solid.tree().nodes().data()) % (std::uintptr_t(2) << 20), 0u);
}

TEST(CollisionWorldBuild, FloatAndDoubleBoxBuildsAgree) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-10, 10), h(1e-4, 0.5);
  std::vector<Eigen::Vector3d> lo(5000), hi(5000);
  std::vector<BvhBox> boxes(lo.size());
  for (std::size_t i = 0; i < lo.size(); ++i) {
    const Eigen::Vector3d c(u(rng), u(rng), u(rng)), e(h(rng), h(rng), h(rng));
    lo[i] = c - e;
    hi[i] = c + e;
    for (int a = 0; a < 3; ++a) {
      boxes[i].lo[a] = round_down_to_float(lo[i][a]);
      boxes[i].hi[a] = round_up_to_float(hi[i][a]);
    }
  }
  const Bvh a = Bvh::build(lo, hi, 8), b = Bvh::build(boxes, 8);
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  ASSERT_EQ(a.order(), b.order());
  for (std::size_t k = 0; k < a.nodes().size(); ++k) {
    ASSERT_EQ(a.nodes()[k].first, b.nodes()[k].first);
    ASSERT_EQ(a.nodes()[k].count, b.nodes()[k].count);
    for (int d = 0; d < 3; ++d) {
      ASSERT_EQ(a.nodes()[k].lo[d], b.nodes()[k].lo[d]);
      ASSERT_EQ(a.nodes()[k].hi[d], b.nodes()[k].hi[d]);
    }
  }
  // Preorder: an inner node's left child follows it, its right child comes after.
  for (std::size_t k = 0; k < b.nodes().size(); ++k) {
    if (b.nodes()[k].count == 0) {
      ASSERT_GT(b.nodes()[k].first, k + 1);
    }
  }
}

}  // namespace
}  // namespace gshaptics
