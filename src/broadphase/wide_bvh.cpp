#include "gshaptics/broadphase/wide_bvh.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace gshaptics {

namespace {

// A node whose four lanes are unused (kEmpty), their boxes far from any query.
WideBvhNode empty_node() noexcept {
  WideBvhNode node{};
  for (int c = 0; c < 4; ++c) {
    node.child[c] = WideBvhNode::kEmpty;
    for (int k = 0; k < 3; ++k) node.lo[k][c] = node.hi[k][c] = std::numeric_limits<float>::max();
  }
  return node;
}

double half_area(const BvhNode& n) noexcept {
  const double x = double(n.hi[0]) - n.lo[0], y = double(n.hi[1]) - n.lo[1], z = double(n.hi[2]) - n.lo[2];
  return x * y + y * z + z * x;
}

// The binary nodes that become the four children of the wide node made for binary inner node i:
// its two children, then the inner one of largest area opened, until there are four or only
// leaves. Returns how many.
int wide_children(std::span<const BvhNode> b, std::uint32_t i, std::array<std::uint32_t, 4>& kids) noexcept {
  kids = {i + 1, b[i].first, 0, 0};
  int n = 2;
  while (n < 4) {
    int open = -1;
    double largest = -1;
    for (int k = 0; k < n; ++k) {
      const BvhNode& c = b[kids[std::size_t(k)]];
      if (c.count == 0 && half_area(c) > largest) largest = half_area(c), open = k;
    }
    if (open < 0) break;
    const std::uint32_t c = kids[std::size_t(open)];
    kids[std::size_t(open)] = c + 1;  // preorder: the left child follows its parent
    kids[std::size_t(n++)] = b[c].first;
  }
  return n;
}

// How many wide nodes collapse_from(i) makes.
std::size_t wide_count(std::span<const BvhNode> b, std::uint32_t i) noexcept {
  std::array<std::uint32_t, 4> kids;
  const int n = wide_children(b, i, kids);
  std::size_t count = 1;
  for (int c = 0; c < n; ++c)
    if (b[kids[std::size_t(c)]].count == 0) count += wide_count(b, kids[std::size_t(c)]);
  return count;
}

// Builds the wide node for binary inner node `i` (and, recursively, its inner children) at the
// end of `out`; returns its index. `depth` is the wide depth of this node (0: the root).
std::uint32_t collapse_from(std::span<const BvhNode> b, std::uint32_t i, int depth, int& max_depth,
                            internal::HugePageVector<WideBvhNode>& out) {
  if (depth >= Bvh::kMaxDepth) throw std::length_error("WideBvh: the binary tree is deeper than Bvh::kMaxDepth");
  max_depth = std::max(max_depth, depth + 1);
  std::array<std::uint32_t, 4> kids;
  const int n = wide_children(b, i, kids);
  const auto me = std::uint32_t(out.size());
  out.push_back(empty_node());
  for (int c = 0; c < n; ++c) {
    const BvhNode& kid = b[kids[std::size_t(c)]];
    const std::uint32_t child = kid.count != 0 ? kid.first : collapse_from(b, kids[std::size_t(c)], depth + 1, max_depth, out);
    WideBvhNode& w = out[me];  // (out may have grown)
    for (int k = 0; k < 3; ++k) {
      w.lo[k][c] = kid.lo[k];
      w.hi[k][c] = kid.hi[k];
    }
    w.child[c] = child;
    w.count[c] = kid.count;
  }
  return me;
}

}  // namespace

WideBvh WideBvh::collapse(const Bvh& binary) {
  WideBvh w;
  const std::span<const BvhNode> b = binary.nodes();
  if (b.empty()) return w;
  for (const BvhNode& n : b)
    for (int k = 0; k < 3; ++k) w.scale_ = std::max({w.scale_, std::abs(double(n.lo[k])), std::abs(double(n.hi[k]))});
  if (b[0].count != 0) {
    // A root that is a leaf: one wide node with that leaf in its first lane.
    WideBvhNode node = empty_node();
    for (int k = 0; k < 3; ++k) node.lo[k][0] = b[0].lo[k], node.hi[k][0] = b[0].hi[k];
    node.child[0] = b[0].first;
    node.count[0] = b[0].count;
    w.nodes_.push_back(node);
    w.depth_ = 1;
  } else {
    w.nodes_.reserve(wide_count(b, 0));
    collapse_from(b, 0, 0, w.depth_, w.nodes_);
  }
  return w;
}

WideBvh::Segment WideBvh::segment(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double ta,
                                  double tb) const noexcept {
  // The pad covers, for every difference and product the lanes take, the rounding of a float
  // of magnitude up to twice the largest coordinate (the slab distances are at most that), and
  // the direction's zero components, stood in for by 1e-20 (a line that moves 1e-14 over a
  // million of its units, far under the pad).
  const double scale = std::max(scale_, o.cwiseAbs().maxCoeff());
  const double pad = std::ldexp(scale, -18) + std::numeric_limits<float>::min();
  Segment s;
  for (int k = 0; k < 3; ++k) {
    double d = u[k];
    if (!(std::abs(d) >= 1e-20)) d = std::signbit(d) ? -1e-20 : 1e-20;
    s.inv[k] = static_cast<float>(1.0 / d);
    s.below[k] = round_down_to_float(o[k] - pad);
    s.above[k] = round_up_to_float(o[k] + pad);
  }
  s.ta = round_down_to_float(ta);
  s.tb = round_up_to_float(tb);
  return s;
}

}  // namespace gshaptics
