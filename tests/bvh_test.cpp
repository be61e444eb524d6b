// Broad phase: the BVH never misses a box that overlaps the query, whatever the size spread.

#include "gshaptics/broadphase/bvh.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <random>

namespace gshaptics {
namespace {

bool overlaps(const Eigen::Vector3d& alo, const Eigen::Vector3d& ahi, const Eigen::Vector3d& blo,
              const Eigen::Vector3d& bhi) {
  return (alo.array() <= bhi.array()).all() && (blo.array() <= ahi.array()).all();
}

// The first box overlapping the query box c +- h that the BVH's leaves do not report (-1: none);
// adds the overlapping boxes to `hits`.
int missed(const Bvh& bvh, const std::vector<Eigen::Vector3d>& lo, const std::vector<Eigen::Vector3d>& hi,
           const Eigen::Vector3d& c, const Eigen::Vector3d& h, int* hits = nullptr) {
  float qlo[3], qhi[3];
  for (int k = 0; k < 3; ++k) {
    qlo[k] = round_down_to_float(c[k] - h[k]);
    qhi[k] = round_up_to_float(c[k] + h[k]);
  }
  std::vector<int> seen(lo.size());
  bvh.for_each_overlapping_leaf(qlo, qhi, [&](std::uint32_t first, std::uint32_t count) {
    for (std::uint32_t s = first; s < first + count; ++s) seen[bvh.order()[s]] = 1;
  });
  for (std::size_t i = 0; i < lo.size(); ++i)
    if (overlaps(lo[i], hi[i], c - h, c + h)) {
      if (hits) ++*hits;
      if (!seen[i]) return int(i);
    }
  return -1;
}

TEST(Bvh, NoFalseNegativesAgainstBruteForceWithHugeSizeSpread) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> pos(-100, 100), logsize(-6, 1.3);
  const int n = 20000;
  std::vector<Eigen::Vector3d> lo(n), hi(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d c(pos(rng), pos(rng), pos(rng) * 0.01);  // flat-ish world
    Eigen::Vector3d h;
    for (int k = 0; k < 3; ++k) h[k] = std::pow(10.0, logsize(rng));
    if (i % 1000 == 0) h *= 1000;  // huge floaters
    lo[std::size_t(i)] = c - h;
    hi[std::size_t(i)] = c + h;
  }
  const Bvh bvh = Bvh::build(lo, hi, 4);
  EXPECT_LT(bvh.depth(), Bvh::kMaxDepth);
  for (int q = 0; q < 300; ++q) {
    const Eigen::Vector3d c(pos(rng), pos(rng), pos(rng) * 0.01);
    const Eigen::Vector3d h = Eigen::Vector3d::Constant(std::pow(10.0, logsize(rng)));
    ASSERT_EQ(missed(bvh, lo, hi, c, h), -1) << "query " << q;
  }
}

// The level-order traversal reports exactly the depth-first traversal's leaves, in its order,
// whatever the scratch (small scratch forces the depth-first finish at various levels), and stops
// where it does.
TEST(Bvh, LevelOrderReportsTheDepthFirstLeavesInOrder) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> pos(-100, 100), logsize(-3, 1.5);
  const int n = 30000;
  std::vector<Eigen::Vector3d> lo(n), hi(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d c(pos(rng), pos(rng), pos(rng) * 0.1);
    Eigen::Vector3d h;
    for (int k = 0; k < 3; ++k) h[k] = std::pow(10.0, logsize(rng) - 1);
    lo[std::size_t(i)] = c - h;
    hi[std::size_t(i)] = c + h;
  }
  const Bvh bvh = Bvh::build(lo, hi, 8);
  std::vector<std::uint32_t> scratch(2 * 4096);
  int fallbacks_exercised = 0, reported = 0;
  for (int q = 0; q < 400; ++q) {
    const Eigen::Vector3d c(pos(rng), pos(rng), pos(rng) * 0.1);
    const Eigen::Vector3d h = Eigen::Vector3d::Constant(std::pow(10.0, logsize(rng)));
    float qlo[3], qhi[3];
    for (int k = 0; k < 3; ++k) {
      qlo[k] = round_down_to_float(c[k] - h[k]);
      qhi[k] = round_up_to_float(c[k] + h[k]);
    }
    std::vector<const BvhNode*> dfs;
    bvh.for_each_overlapping_leaf_node(qlo, qhi, [&](const BvhNode& leaf) { dfs.push_back(&leaf); });
    for (std::size_t half : {std::size_t(1), std::size_t(2), std::size_t(5), std::size_t(64), std::size_t(4096)}) {
      std::vector<const BvhNode*> level;
      bvh.for_each_overlapping_leaf_node_by_level(qlo, qhi, std::span(scratch.data(), 2 * half),
                                                  [&](const BvhNode& leaf) { level.push_back(&leaf); });
      ASSERT_EQ(level, dfs) << "query " << q << ", scratch 2 x " << half;
      if (half < dfs.size()) ++fallbacks_exercised;
    }
    reported += int(dfs.size());
    // Early stop after the first `stop` leaves: the same prefix.
    const std::size_t stop = dfs.size() / 2 + 1;
    std::vector<const BvhNode*> prefix;
    bvh.for_each_overlapping_leaf_node_by_level(qlo, qhi, scratch, [&](const BvhNode& leaf) {
      prefix.push_back(&leaf);
      return prefix.size() < stop;
    });
    ASSERT_EQ(prefix, std::vector<const BvhNode*>(dfs.begin(), dfs.begin() + std::ptrdiff_t(std::min(stop, dfs.size()))));
  }
  EXPECT_GT(fallbacks_exercised, 100);
  EXPECT_GT(reported, 4000);  // the queries reach leaves: not a comparison of empty lists
}

// A ball query reported by ranges (for_each_overlapping_range: a node wholly inside the ball as
// its subtree's slots, in one call) reports the same slots, in the same order, as the leaves that
// come within the ball, one by one; and it does so in fewer calls where the ball holds whole
// subtrees. Both split rules.
TEST(Bvh, RangesReportTheNearLeavesSlotsInOrderWithFewerCalls) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> pos(-100, 100), logsize(-2, 0.5), radius(1, 40);
  const int n = 20000;
  std::vector<BvhBox> boxes(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d c(pos(rng), pos(rng), pos(rng) * 0.2);
    for (int k = 0; k < 3; ++k) {
      const double h = std::pow(10.0, logsize(rng));
      boxes[std::size_t(i)].lo[k] = round_down_to_float(c[k] - h);
      boxes[std::size_t(i)].hi[k] = round_up_to_float(c[k] + h);
    }
  }
  for (BvhSplit split : {BvhSplit::kMedian, BvhSplit::kSah}) {
    const Bvh bvh = Bvh::build(boxes, 8, split);
    std::size_t leaves = 0, calls = 0, slots = 0;
    for (int q = 0; q < 200; ++q) {
      const Eigen::Vector3d c(pos(rng), pos(rng), pos(rng) * 0.2);
      const double rho = radius(rng), reach = rho * rho;
      float lo[3], hi[3];
      for (int k = 0; k < 3; ++k) lo[k] = round_down_to_float(c[k] - rho), hi[k] = round_up_to_float(c[k] + rho);
      const auto d2 = [&](const BvhNode& node, bool farthest) {
        double sum = 0;
        for (int k = 0; k < 3; ++k) {
          const double a = double(node.lo[k]) - c[k], b = c[k] - double(node.hi[k]);
          const double e = farthest ? std::max(-a, -b) : std::max({a, b, 0.0});
          sum += e * e;
        }
        return sum;
      };
      const auto within = [&](const BvhNode& node) { return d2(node, true) <= reach; };
      const auto near = [&](const BvhNode& node) { return d2(node, false) <= reach; };
      std::vector<std::uint32_t> by_leaf, by_range;
      bvh.for_each_overlapping_leaf_node(lo, hi, [&](const BvhNode& leaf) {
        if (!near(leaf)) return;
        ++leaves;
        for (std::uint32_t k = leaf.first; k < leaf.first + leaf.count; ++k) by_leaf.push_back(k);
      });
      bvh.for_each_overlapping_range(lo, hi, within, near, [&](std::uint32_t first, std::uint32_t count) {
        ++calls;
        for (std::uint32_t k = first; k < first + count; ++k) by_range.push_back(k);
      });
      ASSERT_EQ(by_range, by_leaf) << "query " << q;
      slots += by_leaf.size();
    }
    EXPECT_GT(slots, 10000u);        // (the balls hold slots: not a comparison of empty lists)
    EXPECT_LT(10 * calls, 9 * leaves);  // whole subtrees in one call
  }
}

TEST(Bvh, EveryPrimitiveInExactlyOneLeaf) {
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Eigen::Vector3d> lo(1001), hi(1001);
  for (std::size_t i = 0; i < lo.size(); ++i) {
    lo[i] = Eigen::Vector3d(u(rng), u(rng), u(rng));
    hi[i] = lo[i] + Eigen::Vector3d::Constant(0.01);
  }
  const Bvh bvh = Bvh::build(lo, hi, 3);
  std::vector<int> count(lo.size());
  for (const BvhNode& node : bvh.nodes())
    for (std::uint32_t s = node.first; node.count > 0 && s < node.first + node.count; ++s)
      ++count[bvh.order()[s]];
  for (int c : count) EXPECT_EQ(c, 1);
}

// The SAH split (SeenSolid's tree): every box in exactly one leaf and no overlap missed, with a
// huge size spread and with boxes whose centroids coincide (no plane separates them: median).
TEST(Bvh, TheSahTreeMissesNoOverlapAndKeepsEveryBoxOnce) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> pos(-100, 100), logsize(-5, 1.3);
  const int n = 12000;
  std::vector<BvhBox> boxes(n);
  std::vector<Eigen::Vector3d> lo(n), hi(n);
  for (int i = 0; i < n; ++i) {
    // A tenth of the boxes share one centroid; the rest spread over a flat-ish world.
    const Eigen::Vector3d c = i % 10 == 0 ? Eigen::Vector3d(3, -2, 0.5) : Eigen::Vector3d(pos(rng), pos(rng), pos(rng) * 0.02);
    Eigen::Vector3d h;
    for (int k = 0; k < 3; ++k) h[k] = std::pow(10.0, logsize(rng));
    if (i % 997 == 0) h *= 300;  // huge floaters
    lo[std::size_t(i)] = c - h;
    hi[std::size_t(i)] = c + h;
    for (int k = 0; k < 3; ++k) {
      boxes[std::size_t(i)].lo[k] = round_down_to_float(lo[std::size_t(i)][k]);
      boxes[std::size_t(i)].hi[k] = round_up_to_float(hi[std::size_t(i)][k]);
    }
  }
  const Bvh bvh = Bvh::build(boxes, 4, BvhSplit::kSah);
  EXPECT_LT(bvh.depth(), Bvh::kMaxDepth);
  std::vector<int> count(n);
  for (const BvhNode& node : bvh.nodes()) {
    EXPECT_LE(node.count, 4u);
    for (std::uint32_t s = node.first; node.count > 0 && s < node.first + node.count; ++s) ++count[bvh.order()[s]];
  }
  for (int c : count) ASSERT_EQ(c, 1);
  int hits = 0;
  for (int q = 0; q < 200; ++q) {
    const Eigen::Vector3d c = q % 20 == 0 ? Eigen::Vector3d(3, -2, 0.5) : Eigen::Vector3d(pos(rng), pos(rng), pos(rng) * 0.02);
    const Eigen::Vector3d h = Eigen::Vector3d::Constant(std::pow(10.0, logsize(rng)));
    ASSERT_EQ(missed(bvh, lo, hi, c, h, &hits), -1) << "query " << q;
  }
  EXPECT_GT(hits, 1000);  // the queries do overlap boxes
}

TEST(Bvh, OutwardRoundingContainsTheDoubleValue) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1e5, 1e5);
  for (int i = 0; i < 100000; ++i) {
    const double x = u(rng);
    EXPECT_LE(double(round_down_to_float(x)), x);
    EXPECT_GE(double(round_up_to_float(x)), x);
  }
}

TEST(Bvh, OutwardRoundingIsTheNearestFloatOutward) {
  // Against std::nextafter: the float nearest to x on its outer side, across signs, zero,
  // subnormals and past the largest float.
  const auto down = [](double x) {
    float f = float(x);
    return double(f) > x ? std::nextafter(f, -std::numeric_limits<float>::infinity()) : f;
  };
  const auto up = [](double x) {
    float f = float(x);
    return double(f) < x ? std::nextafter(f, std::numeric_limits<float>::infinity()) : f;
  };
  std::vector<double> xs = {0.0, -0.0, 1e-46, -1e-46, 1e-40, -1e-40, 0.1, -0.1, 1.0, -1.0, 3.4028235e38, -3.4028235e38,
                            3.5e38, -3.5e38, 1e300, -1e300};
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0), e(-45.0, 38.0);
  for (int i = 0; i < 20000; ++i) xs.push_back(u(rng) * std::pow(10.0, e(rng)));
  for (double x : xs) {
    SCOPED_TRACE(x);
    EXPECT_EQ(std::bit_cast<std::uint32_t>(round_down_to_float(x)), std::bit_cast<std::uint32_t>(down(x)));
    EXPECT_EQ(std::bit_cast<std::uint32_t>(round_up_to_float(x)), std::bit_cast<std::uint32_t>(up(x)));
  }
}

TEST(Bvh, EmptyInputIsAValidEmptyTree) {
  const Bvh bvh = Bvh::build({}, {}, 4);
  const float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
  int leaves = 0;
  bvh.for_each_overlapping_leaf(lo, hi, [&](std::uint32_t, std::uint32_t) { ++leaves; });
  std::vector<std::uint32_t> scratch(8);
  bvh.for_each_overlapping_leaf_node_by_level(lo, hi, scratch, [&](const BvhNode&) { ++leaves; });
  EXPECT_EQ(leaves, 0);
}

}  // namespace
}  // namespace gshaptics
