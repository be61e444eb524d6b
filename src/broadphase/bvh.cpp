#include "gshaptics/broadphase/bvh.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace gshaptics {

float round_down_to_float(double x) noexcept {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

float round_up_to_float(double x) noexcept {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

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
  if (lo.size() >= std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("Bvh::build: too many primitives");
  leaf_size = std::max(1, leaf_size);
  Bvh bvh;
  std::vector<BvhNode> nodes;  // built here, then laid out in preorder into shared storage
  const std::size_t n = lo.size();
  bvh.order_.resize(n);
  for (std::size_t i = 0; i < n; ++i) bvh.order_[i] = std::uint32_t(i);
  if (n == 0) return bvh;
  std::vector<Eigen::Vector3d> centroid(n);
  for (std::size_t i = 0; i < n; ++i) centroid[i] = 0.5 * (lo[i] + hi[i]);
  nodes.reserve(2 * (2 * n / std::size_t(leaf_size) + 1));  // leaves hold >= leaf/2

  struct Task {
    std::uint32_t node, begin, end;
    int depth;
  };
  std::vector<Task> tasks;
  nodes.push_back({});
  tasks.push_back({0, 0, std::uint32_t(n), 1});
  while (!tasks.empty()) {
    const Task t = tasks.back();
    tasks.pop_back();
    bvh.depth_ = std::max(bvh.depth_, t.depth);
    Eigen::Vector3d blo = Eigen::Vector3d::Constant(INFINITY), bhi = -blo;
    Eigen::Vector3d clo = blo, chi = bhi;
    for (std::uint32_t k = t.begin; k < t.end; ++k) {
      const std::uint32_t p = bvh.order_[k];
      blo = blo.cwiseMin(lo[p]);
      bhi = bhi.cwiseMax(hi[p]);
      clo = clo.cwiseMin(centroid[p]);
      chi = chi.cwiseMax(centroid[p]);
    }
    BvhNode& node = nodes[t.node];
    for (int a = 0; a < 3; ++a) {
      node.lo[a] = round_down_to_float(blo[a]);
      node.hi[a] = round_up_to_float(bhi[a]);
    }
    const std::uint32_t count = t.end - t.begin;
    if (count <= std::uint32_t(leaf_size)) {
      node.first = t.begin;
      node.count = count;
      continue;
    }
    int axis = 0;
    (chi - clo).maxCoeff(&axis);
    const std::uint32_t mid = t.begin + count / 2;
    std::nth_element(bvh.order_.begin() + t.begin, bvh.order_.begin() + mid,
                     bvh.order_.begin() + t.end, [&](std::uint32_t a, std::uint32_t b) {
                       return centroid[a][axis] < centroid[b][axis];
                     });
    const auto left = std::uint32_t(nodes.size());
    node.first = left;
    node.count = 0;
    nodes.push_back({});  // may reallocate: `node` is not used after this point
    nodes.push_back({});
    tasks.push_back({left, t.begin, mid, t.depth + 1});
    tasks.push_back({left + 1, mid, t.end, t.depth + 1});
  }
  if (bvh.depth_ >= kMaxDepth) throw std::logic_error("Bvh::build: depth exceeds traversal stack");

  // Re-lay the nodes out in depth-first preorder: a left child directly follows its parent,
  // so the traversal walks mostly forward through memory; inner nodes keep only the right
  // child's index.
  std::vector<BvhNode> ordered;
  ordered.reserve(nodes.size());
  struct Item {
    std::uint32_t old_index;
    std::uint32_t parent_slot;  // slot of the parent whose right-child index to fill, or ~0
  };
  std::vector<Item> todo{{0, ~0u}};
  while (!todo.empty()) {
    const Item item = todo.back();
    todo.pop_back();
    const auto slot = std::uint32_t(ordered.size());
    if (item.parent_slot != ~0u) ordered[item.parent_slot].first = slot;
    const BvhNode node = nodes[item.old_index];
    ordered.push_back(node);
    if (node.count == 0) {
      todo.push_back({node.first + 1, slot});  // right: index patched when it is emitted
      todo.push_back({node.first, ~0u});       // left: emitted next, at slot + 1
    }
  }
  auto storage = std::make_shared<const std::vector<BvhNode>>(std::move(ordered));
  bvh.nodes_ = std::span<const BvhNode>(*storage);
  bvh.owner_ = std::move(storage);
  return bvh;
}

}  // namespace gshaptics
