#pragma once
/// @file
/// Bounding-volume hierarchy over axis-aligned boxes, built once, queried without allocation.
/// Node layout follows the compact "two children adjacent" scheme common to CPU BVHs
/// (e.g. madmann91/bvh): inner nodes store the index of their first child, leaves a primitive range.

#include <Eigen/Core>
#include <bit>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace gshaptics {

/// Axis-aligned box in single precision. Built from double bounds by rounding outward, so a
/// float box always contains the double box it came from (no false negatives).
struct BvhNode {
  float lo[3];
  std::uint32_t first;  ///< leaf: first primitive slot; inner: index of the right child (left = this + 1)
  float hi[3];
  std::uint32_t count;  ///< leaf: number of primitives (> 0); inner: 0
};
static_assert(sizeof(BvhNode) == 32);

/// Rounds a double bound outward to float: the largest float <= x (down) or the smallest >= x
/// (up); NaN stays NaN. Stepped by the float's bits (IEEE 754 binary32 orders like
/// sign-magnitude integers): std::nextafter's answer, inline, as the sweeps' boxes call it several
/// times a sweep.
[[nodiscard]] inline float round_down_to_float(double x) noexcept {
  const float f = static_cast<float>(x);
  if (!(static_cast<double>(f) > x)) return f;
  if (f == 0.0f) return -std::numeric_limits<float>::denorm_min();
  const auto bits = std::bit_cast<std::uint32_t>(f);  // (f > x: f is not -infinity)
  return std::bit_cast<float>(f > 0 ? bits - 1 : bits + 1);
}
[[nodiscard]] inline float round_up_to_float(double x) noexcept {
  const float f = static_cast<float>(x);
  if (!(static_cast<double>(f) < x)) return f;
  if (f == 0.0f) return std::numeric_limits<float>::denorm_min();
  const auto bits = std::bit_cast<std::uint32_t>(f);  // (f < x: f is not +infinity)
  return std::bit_cast<float>(f > 0 ? bits + 1 : bits - 1);
}

/// A primitive's box for the build: the double box rounded outward to float (the nodes'
/// precision; since rounding is monotone, a node's box is the same whether its children's
/// boxes are rounded first or not).
struct BvhBox {
  float lo[3], hi[3];
};
static_assert(sizeof(BvhBox) == 24);

/// How build() splits a node's primitives in two.
enum class BvhSplit {
  /// At the median along the longest axis of the centroids' bounds: a balanced tree, the one
  /// the box queries (sweeps) were tuned on.
  kMedian,
  /// At the binned surface area heuristic's best plane (16 bins along the longest axis; Wald 2007,
  /// "On fast construction of SAH-based bounding volume hierarchies"), the median where the
  /// centroids do not spread: fewer nodes and primitives a ray meets where large and small boxes
  /// mix (SeenSolid's lines through a capture).
  kSah,
};

/// A BVH over N boxes. `order[k]` is the input index of the primitive in slot k; a leaf covers
/// slots [first, first + count). Nodes are stored in depth-first preorder. Built by splitting
/// (BvhSplit) until a node holds at most `leaf_size` primitives (O(N log N)).
class Bvh {
 public:
  /// Builds over boxes [lo[i], hi[i]] (world frame). Throws std::invalid_argument on size mismatch.
  static Bvh build(std::span<const Eigen::Vector3d> lo, std::span<const Eigen::Vector3d> hi,
                   int leaf_size = 4);
  /// Builds over float boxes (already rounded outward), straight into preorder: the build's
  /// memory is the boxes (24 B), the order (4 B) and the nodes (32 B per node, about a third of
  /// a node per primitive at leaf size 8). Throws std::invalid_argument for more than 2^32 - 2
  /// boxes.
  static Bvh build(std::span<const BvhBox> boxes, int leaf_size = 4, BvhSplit split = BvhSplit::kMedian);

  /// A BVH over nodes stored elsewhere (a memory-mapped world cache), kept alive by `owner`.
  /// The nodes must be a valid preorder layout of depth `depth` (as build() makes).
  static Bvh from_nodes(std::span<const BvhNode> nodes, int depth, std::shared_ptr<const void> owner);

  /// The nodes (immutable, shared by copies of this BVH).
  [[nodiscard]] std::span<const BvhNode> nodes() const { return nodes_; }
  [[nodiscard]] const std::vector<std::uint32_t>& order() const { return order_; }
  [[nodiscard]] int depth() const { return depth_; }
  /// Frees `order()` once the caller has permuted its primitives into slot order.
  void release_order() { std::vector<std::uint32_t>().swap(order_); }
  /// The order, for a caller that permutes its primitives in place using it as scratch (then
  /// calls release_order()).
  [[nodiscard]] std::vector<std::uint32_t>& mutable_order() { return order_; }

  /// Calls `on_leaf(first, count)` for every leaf whose box overlaps [box_lo, box_hi]. When
  /// `on_leaf` returns bool, returning false stops the traversal (early exit).
  /// Allocation-free (fixed traversal stack); safe to call from several threads at once.
  template <typename OnLeaf>
  void for_each_overlapping_leaf(const float box_lo[3], const float box_hi[3],
                                 OnLeaf&& on_leaf) const noexcept {
    for_each_overlapping_leaf_node(box_lo, box_hi, [&](const BvhNode& n) {
      if constexpr (std::is_same_v<decltype(on_leaf(n.first, n.count)), bool>) {
        return on_leaf(n.first, n.count);
      } else {
        on_leaf(n.first, n.count);
        return true;
      }
    });
  }

  /// As for_each_overlapping_leaf, calling `on_leaf(const BvhNode& leaf)` with the leaf node
  /// itself (its box and slot range), in the same depth-first order; returning false stops.
  template <typename OnLeaf>
  void for_each_overlapping_leaf_node(const float box_lo[3], const float box_hi[3],
                                      OnLeaf&& on_leaf) const noexcept {
    if (nodes_.empty()) return;
    depth_first_from(0, box_lo, box_hi, on_leaf);
  }

  /// As for_each_overlapping_leaf_node (the same leaves, in the same depth-first order, the same
  /// early stop), but the tree is loaded level by level: the children of all of a level's
  /// overlapping nodes are fetched together before any of them is read, so a traversal over
  /// nodes that are not in the caches waits about one memory latency per level instead of about
  /// one per node visited (breadth-first traversal for memory-level parallelism). The leaves are
  /// reported after the last level. Preorder makes the depth-first order free: each level's
  /// list is kept sorted by node index, since a node's children (or a leaf itself) replace it in
  /// place. `scratch` holds two levels (its halves); a level that could outgrow a half is
  /// finished depth first from each of its nodes, which keeps the order. Allocation-free.
  template <typename OnLeaf>
  void for_each_overlapping_leaf_node_by_level(const float box_lo[3], const float box_hi[3],
                                               std::span<std::uint32_t> scratch,
                                               OnLeaf&& on_leaf) const noexcept {
    if (nodes_.empty()) return;
    const std::size_t cap = scratch.size() / 2;
    if (cap < 2 || nodes_.size() > kLeafTag) {
      depth_first_from(0, box_lo, box_hi, on_leaf);
      return;
    }
    const BvhNode* nodes = nodes_.data();
    std::uint32_t* level = scratch.data();
    std::uint32_t* next = level + cap;
    std::size_t n_level = 1;
    level[0] = 0;
    // Entries tagged kLeafTag are leaves already known to overlap; the others are still to test.
    for (std::size_t untested = 1; untested > 0;) {
      if (n_level + untested > cap) {  // the next level might not fit: finish depth first
        for (std::size_t k = 0; k < n_level; ++k) {
          const std::uint32_t i = level[k];
          if (i & kLeafTag) {
            if (!call_on_leaf(on_leaf, nodes[i & ~kLeafTag])) return;
          } else if (!depth_first_from(i, box_lo, box_hi, on_leaf)) {
            return;
          }
        }
        return;
      }
      std::size_t n_next = 0;
      const bool carries_leaves = untested != n_level;
      untested = 0;
      for (std::size_t k = 0; k < n_level; ++k) {
        const std::uint32_t i = level[k];
        if (carries_leaves && (i & kLeafTag)) {
          next[n_next++] = i;
          continue;
        }
        const BvhNode& n = nodes[i];
        if (!overlaps(n, box_lo, box_hi)) continue;
        if (n.count != 0) {
          next[n_next++] = i | kLeafTag;
          continue;
        }
        __builtin_prefetch(&nodes[i + 1]);
        __builtin_prefetch(&nodes[n.first]);
        next[n_next++] = i + 1;  // preorder: the left child follows its parent
        next[n_next++] = n.first;
        untested += 2;
      }
      std::swap(level, next);
      n_level = n_next;
    }
    for (std::size_t k = 0; k < n_level; ++k)
      if (!call_on_leaf(on_leaf, nodes[level[k] & ~kLeafTag])) return;
  }

  /// The slots [first, end) under node `i`: in preorder a subtree's leaves are consecutive
  /// and cover consecutive slots, from its leftmost leaf (left children down) to its rightmost
  /// (right children down). O(depth of the subtree).
  [[nodiscard]] std::pair<std::uint32_t, std::uint32_t> subtree_slots(std::uint32_t i) const noexcept {
    const BvhNode* nodes = nodes_.data();
    std::uint32_t l = i, r = i;
    while (nodes[l].count == 0) l = l + 1;
    while (nodes[r].count == 0) r = nodes[r].first;
    return {nodes[l].first, nodes[r].first + nodes[r].count};
  }

  /// Calls `on_range(first, count)` for slot ranges, in slot order: an inner node whose box
  /// overlaps [box_lo, box_hi] and for which `within(node)` holds is reported whole, its
  /// subtree's slots (subtree_slots) as one range, and not descended; an overlapping leaf is
  /// reported when `within` or `near(leaf)` holds. Where `within(node)` implies `near` of
  /// every leaf under it (a region's inside and what touches it), the slots reported are those
  /// of the overlapping leaves that are near, in the same order, for fewer node visits where
  /// the region holds whole subtrees. Allocation-free.
  template <typename Within, typename Near, typename OnRange>
  void for_each_overlapping_range(const float box_lo[3], const float box_hi[3], const Within& within,
                                  const Near& near, const OnRange& on_range) const noexcept {
    if (nodes_.empty()) return;
    std::uint32_t stack[kMaxDepth];
    int top = 0;
    std::uint32_t i = 0;
    const BvhNode* nodes = nodes_.data();
    for (;;) {
      const BvhNode& n = nodes[i];
      if (overlaps(n, box_lo, box_hi)) {
        if (n.count != 0) {
          if (within(n) || near(n)) on_range(n.first, n.count);
        } else if (within(n)) {
          const auto [first, end] = subtree_slots(i);
          on_range(first, end - first);
        } else {
          __builtin_prefetch(&nodes[n.first]);
          stack[top++] = n.first;
          i = i + 1;
          continue;
        }
      }
      if (top == 0) return;
      i = stack[--top];
    }
  }

  /// Traversal stack size; the median split bounds the depth by log2(N) + 2 < kMaxDepth.
  static constexpr int kMaxDepth = 96;

 private:
  static constexpr std::uint32_t kLeafTag = 0x80000000u;  // level-order traversal: a known leaf

  static bool overlaps(const BvhNode& n, const float box_lo[3], const float box_hi[3]) noexcept {
    return !(n.lo[0] > box_hi[0] || n.hi[0] < box_lo[0] || n.lo[1] > box_hi[1] || n.hi[1] < box_lo[1] ||
             n.lo[2] > box_hi[2] || n.hi[2] < box_lo[2]);
  }

  template <typename OnLeaf>
  static bool call_on_leaf(OnLeaf& on_leaf, const BvhNode& n) noexcept {
    if constexpr (std::is_same_v<decltype(on_leaf(n)), bool>) {
      return on_leaf(n);
    } else {
      on_leaf(n);
      return true;
    }
  }

  // Depth-first over the subtree rooted at `root`; false when on_leaf stopped it.
  template <typename OnLeaf>
  bool depth_first_from(std::uint32_t root, const float box_lo[3], const float box_hi[3],
                        const OnLeaf& on_leaf) const noexcept {
    std::uint32_t stack[kMaxDepth];
    int top = 0;
    std::uint32_t i = root;
    const BvhNode* nodes = nodes_.data();
    for (;;) {
      const BvhNode& n = nodes[i];
      const bool overlap = overlaps(n, box_lo, box_hi);
      if (overlap && n.count == 0) {
        // Preorder layout: the left child is next in memory; the right one waits on the stack
        // and is fetched early, since traversal is bound by the latency of node loads.
        __builtin_prefetch(&nodes[n.first]);
        stack[top++] = n.first;
        i = i + 1;
        continue;
      }
      if (overlap && !call_on_leaf(on_leaf, n)) return false;
      if (top == 0) return true;
      i = stack[--top];
    }
  }

  std::span<const BvhNode> nodes_;
  std::shared_ptr<const void> owner_;  // keeps nodes_ alive: a vector, or a mapped file
  std::vector<std::uint32_t> order_;
  int depth_ = 0;
};

/// Puts arrays of primitives into a Bvh's slot order in place: slot k of each takes what was at
/// order[k] (Bvh::mutable_order()). Each cycle of the permutation is followed once, a slot done
/// marked by order[k] = k, so no copy of the arrays is made and `order` is left the identity
/// (release it after). All arrays must be order.size() long.
template <class... Items>
void permute_to_order(std::span<std::uint32_t> order, std::span<Items>... items) {
  for (std::size_t start = 0; start < order.size(); ++start) {
    if (order[start] == start) continue;
    const std::tuple<Items...> first{items[start]...};
    std::size_t k = start;
    while (order[k] != start) {
      const std::size_t from = order[k];
      ((items[k] = items[from]), ...);
      order[k] = std::uint32_t(k);
      k = from;
    }
    std::apply([&](const Items&... held) { ((items[k] = held), ...); }, first);
    order[k] = std::uint32_t(k);
  }
}

}  // namespace gshaptics
