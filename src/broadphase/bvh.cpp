#include "gshaptics/broadphase/bvh.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "../huge_pages.h"

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

Bvh Bvh::build(std::span<const BvhBox> boxes, int leaf_size) {
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
  nodes->reserve(2 * (2 * n / std::size_t(leaf_size) + 1));  // leaves hold >= leaf/2
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
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (chi[a] - clo[a] > chi[axis] - clo[axis]) axis = a;
    const std::uint32_t mid = t.begin + count / 2;
    std::nth_element(order + t.begin, order + mid, order + t.end, [&](std::uint32_t p, std::uint32_t q) {
      return b[p].lo[axis] + b[p].hi[axis] < b[q].lo[axis] + b[q].hi[axis];
    });
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
