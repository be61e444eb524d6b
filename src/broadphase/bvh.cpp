#include "gshaptics/broadphase/bvh.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "gshaptics/huge_pages.h"

namespace gshaptics {

Bvh Bvh::from_nodes(std::span<const BvhNode> nodes, int depth, std::shared_ptr<const void> owner) {
  if (depth < 0 || depth >= kMaxDepth) throw std::invalid_argument("Bvh::from_nodes: depth out of range");
  Bvh bvh;
  bvh.nodes_ = nodes;
  bvh.owner_ = std::move(owner);
  bvh.depth_ = depth;
  return bvh;
}

Bvh Bvh::build(std::span<const Eigen::Vector3d> lo, std::span<const Eigen::Vector3d> hi,
               int leaf_size) {
  if (lo.size() != hi.size()) throw std::invalid_argument("Bvh::build: lo/hi size mismatch");
  std::vector<BvhBox> boxes(lo.size());
  for (std::size_t i = 0; i < lo.size(); ++i)
    for (int a = 0; a < 3; ++a) {
      boxes[i].lo[a] = round_down_to_float(lo[i][a]);
      boxes[i].hi[a] = round_up_to_float(hi[i][a]);
    }
  return build(boxes, leaf_size);
}

namespace {

// Half the surface area of a box (the SAH's weight: the chance a random line meets it).
float half_area(const float lo[3], const float hi[3]) noexcept {
  const float dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
  return dx * dy + dy * dz + dz * dx;
}

// The axis along which [clo, chi] is longest.
int longest_axis(const float clo[3], const float chi[3]) noexcept {
  int a = 0;
  for (int k = 1; k < 3; ++k)
    if (chi[k] - clo[k] > chi[a] - clo[a]) a = k;
  return a;
}

// The binned SAH's split of order[begin, end) (Wald 2007), along the longest axis of the
// centroids' bounds [clo, chi] (centroids as lo + hi): the centroids fall in kBins bins, and the
// plane between two bins with the least area(left) n(left) + area(right) n(right) wins (binning
// the other two axes as well cost the build 1.7x for no better tree on the shared scenes).
// Returns the first slot of the right part after partitioning, or `begin` when no plane
// separates the centroids.
std::uint32_t sah_partition(const BvhBox* b, std::uint32_t* order, std::uint32_t begin, std::uint32_t end,
                            const float clo[3], const float chi[3]) noexcept {
  constexpr int kBins = 16;
  struct Bin {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    std::uint32_t count = 0;
    void add(const float xlo[3], const float xhi[3], std::uint32_t n) noexcept {
      count += n;
      for (int c = 0; c < 3; ++c) {
        lo[c] = std::min(lo[c], xlo[c]);
        hi[c] = std::max(hi[c], xhi[c]);
      }
    }
  };
  const int a = longest_axis(clo, chi);
  if (!(chi[a] > clo[a])) return begin;
  const float scale = kBins / (chi[a] - clo[a]);
  const auto bin_of = [&](const BvhBox& x) { return std::min(kBins - 1, int((x.lo[a] + x.hi[a] - clo[a]) * scale)); };
  Bin bins[kBins];
  for (std::uint32_t k = begin; k < end; ++k) {
    const BvhBox& x = b[order[k]];
    bins[bin_of(x)].add(x.lo, x.hi, 1);
  }
  // Each plane's right-hand cost, swept from the right; then the left-hand side from the left.
  float right_cost[kBins] = {};
  Bin acc;
  for (int i = kBins - 1; i > 0; --i) {
    acc.add(bins[i].lo, bins[i].hi, bins[i].count);
    right_cost[i] = acc.count ? half_area(acc.lo, acc.hi) * float(acc.count) : 0.0f;
  }
  acc = Bin{};
  float best_cost = INFINITY;
  int best_plane = -1;
  for (int i = 0; i < kBins - 1; ++i) {
    acc.add(bins[i].lo, bins[i].hi, bins[i].count);
    if (acc.count == 0 || acc.count == end - begin) continue;
    const float cost = half_area(acc.lo, acc.hi) * float(acc.count) + right_cost[i + 1];
    if (cost < best_cost) best_cost = cost, best_plane = i + 1;
  }
  if (best_plane < 0) return begin;
  std::uint32_t* mid =
      std::partition(order + begin, order + end, [&](std::uint32_t p) { return bin_of(b[p]) < best_plane; });
  return std::uint32_t(mid - order);
}

}  // namespace

Bvh Bvh::build(std::span<const BvhBox> boxes, int leaf_size, BvhSplit split) {
  if (boxes.size() >= std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("Bvh::build: too many primitives");
  leaf_size = std::max(1, leaf_size);
  Bvh bvh;
  const std::size_t n = boxes.size();
  bvh.order_.resize(n);
  for (std::size_t i = 0; i < n; ++i) bvh.order_[i] = std::uint32_t(i);
  if (n == 0) return bvh;
  // Nodes are created in depth-first preorder (left subtree before right), so a left child
  // directly follows its parent and the traversal walks mostly forward through memory; a
  // parent learns its right child's index when that child is created.
  auto nodes = std::make_shared<std::vector<BvhNode, internal::HugePageAllocator<BvhNode>>>();
  // (Median leaves hold >= leaf/2; SAH leaves may hold fewer, and the vector then grows.)
  nodes->reserve(2 * (2 * n / std::size_t(leaf_size) + 1));
  struct Task {
    std::uint32_t begin, end;
    std::uint32_t parent;  // node whose right-child index is this node, or ~0 (left or root)
    int depth;
  };
  std::vector<Task> tasks;
  tasks.push_back({0, std::uint32_t(n), ~0u, 1});
  const BvhBox* b = boxes.data();
  std::uint32_t* order = bvh.order_.data();
  while (!tasks.empty()) {
    const Task t = tasks.back();
    tasks.pop_back();
    bvh.depth_ = std::max(bvh.depth_, t.depth);
    const auto index = std::uint32_t(nodes->size());
    if (t.parent != ~0u) (*nodes)[t.parent].first = index;
    BvhNode node{};
    // Node bounds and the bounds of the centroids (as lo + hi: twice the centroid, same order).
    float blo[3], bhi[3], clo[3], chi[3];
    for (int a = 0; a < 3; ++a) {
      blo[a] = clo[a] = INFINITY;
      bhi[a] = chi[a] = -INFINITY;
    }
    for (std::uint32_t k = t.begin; k < t.end; ++k) {
      const BvhBox& x = b[order[k]];
      for (int a = 0; a < 3; ++a) {
        blo[a] = std::min(blo[a], x.lo[a]);
        bhi[a] = std::max(bhi[a], x.hi[a]);
        const float c = x.lo[a] + x.hi[a];
        clo[a] = std::min(clo[a], c);
        chi[a] = std::max(chi[a], c);
      }
    }
    for (int a = 0; a < 3; ++a) {
      node.lo[a] = blo[a];
      node.hi[a] = bhi[a];
    }
    const std::uint32_t count = t.end - t.begin;
    if (count <= std::uint32_t(leaf_size)) {
      node.first = t.begin;
      node.count = count;
      nodes->push_back(node);
      continue;
    }
    // (The SAH's plane, unless the tree nears the traversal stack's depth: then balanced.)
    std::uint32_t mid = t.begin;
    if (split == BvhSplit::kSah && t.depth < kMaxDepth / 2) mid = sah_partition(b, order, t.begin, t.end, clo, chi);
    if (mid == t.begin || mid == t.end) {
      const int axis = longest_axis(clo, chi);
      mid = t.begin + count / 2;
      std::nth_element(order + t.begin, order + mid, order + t.end, [&](std::uint32_t p, std::uint32_t q) {
        return b[p].lo[axis] + b[p].hi[axis] < b[q].lo[axis] + b[q].hi[axis];
      });
    }
    node.count = 0;  // inner: `first` (the right child) is set when that child is made
    nodes->push_back(node);
    tasks.push_back({mid, t.end, index, t.depth + 1});  // right, after the whole left subtree
    tasks.push_back({t.begin, mid, ~0u, t.depth + 1});  // left: next, at index + 1
  }
  if (bvh.depth_ >= kMaxDepth) throw std::logic_error("Bvh::build: depth exceeds traversal stack");
  // No shrink_to_fit: it would copy; the reserved tail past size() was never touched, so it
  // holds address space, not memory.
  bvh.nodes_ = std::span<const BvhNode>(*nodes);
  bvh.owner_ = std::move(nodes);
  return bvh;
}

}  // namespace gshaptics
