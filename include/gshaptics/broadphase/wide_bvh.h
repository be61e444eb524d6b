#pragma once
/// @file
/// A four-wide BVH for segment queries, collapsed from a binary Bvh (broadphase/bvh.h): each
/// node holds its four children's boxes side by side, axis by axis, so one visit tests all four
/// against a segment in the lanes of one SIMD register. This is the layout of Embree's BVH4
/// (Wald, Woop, Benthin, Johnson and Ernst 2014, "Embree: a kernel framework for efficient CPU ray
/// tracing"); the collapse opens the child of largest surface area first (as there). The leaves
/// are the binary tree's, so a primitive's slot is the same in both trees.
///
/// The test is conservative: a leaf whose box the segment meets in exact arithmetic is always
/// reported (a leaf it misses may be). The float arithmetic's rounding is covered by padding the
/// boxes at query time by 2^-18 of the largest coordinate (the tree's or the segment origin's),
/// which bounds the error of every difference and product the slab test takes (Ize 2013, "Robust
/// BVH ray traversal", makes the same argument with a multiplier on the far distance).

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <type_traits>
#include <vector>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "gshaptics/broadphase/bvh.h"
#include "gshaptics/huge_pages.h"

namespace gshaptics {

/// One node: four children's boxes (float, [axis][child]) and what each child is.
struct alignas(64) WideBvhNode {
  static constexpr std::uint32_t kEmpty = 0xffffffffu;  ///< `child` of an unused lane
  float lo[3][4];
  float hi[3][4];
  std::uint32_t child[4];  ///< inner: the child node's index; leaf: its first primitive slot; unused: kEmpty
  std::uint32_t count[4];  ///< leaf: its number of primitives (> 0); inner or unused: 0
};
static_assert(sizeof(WideBvhNode) == 128);

class WideBvh {
 public:
  /// Collapses a binary tree (its nodes in preorder, as Bvh::build makes them). The binary tree
  /// may be dropped afterwards; the primitive slots are its. O(nodes). Empty in, empty out.
  static WideBvh collapse(const Bvh& binary);

  /// Calls `on_leaf(first, count)` for every leaf whose box the segment {o + t u : t in [ta, tb]}
  /// may meet (never missing one it meets), in no particular order; when `on_leaf` returns bool,
  /// false stops the query. `u` need not be unit (t is in its units). Allocation-free; safe from
  /// several threads at once.
  template <typename OnLeaf>
  void for_each_leaf_on_segment(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double ta, double tb,
                                OnLeaf&& on_leaf) const noexcept;

  [[nodiscard]] std::span<const WideBvhNode> nodes() const noexcept { return nodes_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept { return nodes_.capacity() * sizeof(WideBvhNode); }
  /// Traversal stack entries a query may need (three waiting siblings a level, and the root).
  [[nodiscard]] int stack_need() const noexcept { return 3 * depth_ + 1; }

  /// The largest traversal stack a query takes; collapse() throws std::length_error for a deeper tree.
  static constexpr int kStack = 3 * Bvh::kMaxDepth + 1;

 private:
  // A query's segment in the lanes' terms: per axis the padded origin's two sides and the
  // inverse direction, and the range.
  struct Segment {
    float below[3], above[3], inv[3];
    float ta, tb;
  };
  [[nodiscard]] Segment segment(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double ta,
                                double tb) const noexcept;
  // Which of node n's four children the segment may meet: bit c for child c.
  [[nodiscard]] static unsigned hits(const WideBvhNode& n, const Segment& s) noexcept;

  internal::HugePageVector<WideBvhNode> nodes_;  // (huge pages: gshaptics/huge_pages.h)
  int depth_ = 0;
  double scale_ = 0;  // the largest coordinate magnitude of any box
};

inline unsigned WideBvh::hits(const WideBvhNode& n, const Segment& s) noexcept {
#if defined(__SSE2__)
  __m128 near = _mm_set1_ps(s.ta), far = _mm_set1_ps(s.tb);
  for (int k = 0; k < 3; ++k) {
    const __m128 inv = _mm_set1_ps(s.inv[k]);
    const __m128 a = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.lo[k]), _mm_set1_ps(s.above[k])), inv);
    const __m128 b = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.hi[k]), _mm_set1_ps(s.below[k])), inv);
    near = _mm_max_ps(near, _mm_min_ps(a, b));
    far = _mm_min_ps(far, _mm_max_ps(a, b));
  }
  return unsigned(_mm_movemask_ps(_mm_cmple_ps(near, far)));
#else
  unsigned mask = 0;
  for (int c = 0; c < 4; ++c) {
    float near = s.ta, far = s.tb;
    for (int k = 0; k < 3; ++k) {
      const float a = (n.lo[k][c] - s.above[k]) * s.inv[k], b = (n.hi[k][c] - s.below[k]) * s.inv[k];
      near = std::max(near, std::min(a, b));
      far = std::min(far, std::max(a, b));
    }
    if (near <= far) mask |= 1u << c;
  }
  return mask;
#endif
}

template <typename OnLeaf>
void WideBvh::for_each_leaf_on_segment(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double ta, double tb,
                                       OnLeaf&& on_leaf) const noexcept {
  if (nodes_.empty() || !(ta <= tb)) return;
  const Segment s = segment(o, u, ta, tb);
  std::uint32_t stack[kStack];
  int top = 0;
  const WideBvhNode* nodes = nodes_.data();
  std::uint32_t i = 0;
  for (;;) {
    const WideBvhNode& n = nodes[i];
    for (unsigned mask = hits(n, s); mask != 0; mask &= mask - 1) {
      const int c = __builtin_ctz(mask);
      if (n.count[c] != 0) {
        if constexpr (std::is_same_v<decltype(on_leaf(n.child[c], n.count[c])), bool>) {
          if (!on_leaf(n.child[c], n.count[c])) return;
        } else {
          on_leaf(n.child[c], n.count[c]);
        }
      } else if (n.child[c] != WideBvhNode::kEmpty) {
        __builtin_prefetch(&nodes[n.child[c]]);
        stack[top++] = n.child[c];  // (top < kStack: collapse() bounds the depth)
      }
    }
    if (top == 0) return;
    i = stack[--top];
  }
}

}  // namespace gshaptics
