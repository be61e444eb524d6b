// Broad phase for lines: the four-wide BVH reports every leaf a segment meets (against a brute
// force in double over the primitives' boxes), reports little more, and keeps every slot once.

#include "gshaptics/broadphase/wide_bvh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace gshaptics {
namespace {

// The segment o + t u, t in [ta, tb], against the box [lo, hi] grown by `grow` a side (< 0:
// shrunk), in double: the reference. Parallel slabs are decided by the origin alone.
bool meets(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const Eigen::Vector3d& o, const Eigen::Vector3d& u,
           double ta, double tb, double grow) {
  for (int k = 0; k < 3; ++k) {
    const double a = lo[k] - grow, b = hi[k] + grow;
    if (u[k] == 0) {
      if (o[k] < a || o[k] > b) return false;
      continue;
    }
    double t0 = (a - o[k]) / u[k], t1 = (b - o[k]) / u[k];
    if (t0 > t1) std::swap(t0, t1);
    ta = std::max(ta, t0);
    tb = std::min(tb, t1);
  }
  return ta <= tb;
}

struct Boxes {
  std::vector<Eigen::Vector3d> lo, hi;
};

Boxes random_boxes(std::mt19937_64& rng, int n, const Eigen::Vector3d& offset) {
  std::uniform_real_distribution<double> pos(-1, 1), logsize(-4, 0);
  Boxes b;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d c = offset + Eigen::Vector3d(pos(rng), pos(rng), pos(rng));
    Eigen::Vector3d h;
    for (int k = 0; k < 3; ++k) h[k] = std::pow(10.0, logsize(rng));
    b.lo.push_back(c - h);
    b.hi.push_back(c + h);
  }
  return b;
}

// Per primitive (input index): whether a leaf holding it was reported.
std::vector<char> reported(const WideBvh& wide, const Bvh& binary, const Eigen::Vector3d& o, const Eigen::Vector3d& u,
                           double ta, double tb) {
  std::vector<char> seen(binary.order().size(), 0);
  wide.for_each_leaf_on_segment(o, u, ta, tb, [&](std::uint32_t first, std::uint32_t count) {
    for (std::uint32_t s = first; s < first + count; ++s) seen[binary.order()[s]] = 1;
  });
  return seen;
}

TEST(WideBvh, ReportsEveryBoxASegmentMeetsAndLittleMore) {
  std::mt19937_64 rng(3);
  for (const Eigen::Vector3d& offset : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(300, -200, 50)}) {
    const Boxes b = random_boxes(rng, 3000, offset);
    const Bvh binary = Bvh::build(b.lo, b.hi, 4);
    const WideBvh wide = WideBvh::collapse(binary);
    std::uniform_real_distribution<double> pos(-1.2, 1.2), dir(-1, 1), len(0.01, 3);
    // The binary tree's leaves by their first slot: the wide tree reports no leaf whose box the
    // segment misses by more than the query's padding (2^-18 of the largest coordinate).
    const double grow = 1e-5 * (2 + offset.norm());
    std::vector<const BvhNode*> leaf_of(b.lo.size(), nullptr);
    for (const BvhNode& n : binary.nodes())
      if (n.count > 0) leaf_of[n.first] = &n;
    const auto box_of = [](const BvhNode& n, bool hi) {
      return hi ? Eigen::Vector3d(n.hi[0], n.hi[1], n.hi[2]) : Eigen::Vector3d(n.lo[0], n.lo[1], n.lo[2]);
    };
    int met = 0;
    for (int q = 0; q < 400; ++q) {
      const Eigen::Vector3d o = offset + Eigen::Vector3d(pos(rng), pos(rng), pos(rng));
      Eigen::Vector3d u(dir(rng), dir(rng), dir(rng));
      if (q % 4 == 1) u = Eigen::Vector3d::Unit(q % 3) * (q % 8 == 1 ? -2.0 : 0.5);  // parallel to two slabs
      if (q % 4 == 2) u[q % 3] = 0;                                                      // to one
      const double ta = -len(rng), tb = len(rng);
      const std::vector<char> seen = reported(wide, binary, o, u, ta, tb);
      wide.for_each_leaf_on_segment(o, u, ta, tb, [&](std::uint32_t first, std::uint32_t) {
        ASSERT_NE(leaf_of[first], nullptr);
        EXPECT_TRUE(meets(box_of(*leaf_of[first], false), box_of(*leaf_of[first], true), o, u, ta, tb, grow))
            << "query " << q << " reported a leaf it misses";
      });
      for (std::size_t i = 0; i < b.lo.size(); ++i) {
        const bool hit = meets(b.lo[i], b.hi[i], o, u, ta, tb, 0.0);
        met += hit;
        ASSERT_TRUE(!hit || seen[i]) << "query " << q << " box " << i;
      }
    }
    EXPECT_GT(met, 1000);
  }
}

TEST(WideBvh, ALineOnABoxFaceMeetsItAndOneJustOffDoesNot) {
  Boxes b;
  for (int i = 0; i < 9; ++i) {  // a row of unit boxes along x, 2 apart
    b.lo.emplace_back(2.0 * i, 0, 0);
    b.hi.emplace_back(2.0 * i + 1, 1, 1);
  }
  const Bvh binary = Bvh::build(b.lo, b.hi, 1);
  const WideBvh wide = WideBvh::collapse(binary);
  const Eigen::Vector3d x(1, 0, 0), z(0, 0, -1);
  // Along x on the top face (y = 1), through every box.
  std::vector<char> seen = reported(wide, binary, {-1, 1, 0.5}, x, 0, 30);
  for (std::size_t i = 0; i < 9; ++i) EXPECT_TRUE(seen[i]) << i;
  // Down through box 4's edge corner (x = 9, y = 0), a segment ending on its top face.
  seen = reported(wide, binary, {9, 0, 3}, z, 0, 2);
  EXPECT_TRUE(seen[4]);
  // 1e-3 above the face, and a segment stopping 1e-3 short of the top: nothing.
  seen = reported(wide, binary, {-1, 1.001, 0.5}, x, 0, 30);
  for (std::size_t i = 0; i < 9; ++i) EXPECT_FALSE(seen[i]) << i;
  seen = reported(wide, binary, {9, 0.5, 3}, z, 0, 1.999);
  EXPECT_FALSE(seen[4]);
  // A direction with negative zeros is the same line.
  seen = reported(wide, binary, {-1, 1, 0.5}, Eigen::Vector3d(1, -0.0, -0.0), 0, 30);
  for (std::size_t i = 0; i < 9; ++i) EXPECT_TRUE(seen[i]) << i;
}

TEST(WideBvh, EverySlotIsInExactlyOneLeaf) {
  std::mt19937_64 rng(5);
  for (const int n : {1, 3, 4, 5, 17, 1000}) {
    const Boxes b = random_boxes(rng, n, Eigen::Vector3d::Zero());
    const Bvh binary = Bvh::build(b.lo, b.hi, 4);
    const WideBvh wide = WideBvh::collapse(binary);
    std::vector<int> times(std::size_t(n), 0);
    for (const WideBvhNode& node : wide.nodes())
      for (int c = 0; c < 4; ++c)
        for (std::uint32_t s = node.child[c]; node.count[c] > 0 && s < node.child[c] + node.count[c]; ++s)
          ++times[s];
    for (int i = 0; i < n; ++i) EXPECT_EQ(times[std::size_t(i)], 1) << "n " << n << " slot " << i;
    EXPECT_LE(wide.stack_need(), WideBvh::kStack);
  }
  const WideBvh empty = WideBvh::collapse(Bvh::build(std::vector<BvhBox>{}));
  EXPECT_TRUE(empty.nodes().empty());
  int calls = 0;
  empty.for_each_leaf_on_segment({0, 0, 0}, {1, 0, 0}, 0, 1, [&](std::uint32_t, std::uint32_t) { ++calls; });
  EXPECT_EQ(calls, 0);
}

}  // namespace
}  // namespace gshaptics
