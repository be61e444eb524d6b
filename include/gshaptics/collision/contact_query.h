#pragma once
/// @file
/// The per-tick collision query: broad phase (BVH over exact boxes, then the paper's
/// bounding-sphere pre-filter, eq. 4), narrow phase (K_min, eq. 5-6), contact set out.
///
/// Threading: a ContactQuery belongs to one thread (one device). Several ContactQuery objects
/// may share one CollisionWorld. run() never allocates, locks, logs or throws.

#include <Eigen/Core>
#include <cstdint>
#include <algorithm>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include "gshaptics/broadphase/bvh.h"
#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/tool_ellipsoid.h"
#include "gshaptics/narrowphase/k_min.h"
#include "gshaptics/narrowphase/k_min_batch.h"

namespace gshaptics {

/// One Gaussian overlapping the tool.
struct Contact {
  std::uint32_t index = 0;    ///< index into the ORIGINAL scene file (before filtering)
  std::uint32_t slot = 0;     ///< position of its record in CollisionWorld::gaussians()
  float opacity = 0;          ///< alpha_i
  std::uint8_t part = 0;      ///< the compound tool's part that overlaps it (0 for one ellipsoid)
  /// The body it belongs to: 0 the static scene, i + 1 the scene's object i (objects/rigid_object.h).
  std::uint8_t body = 0;
  /// K_min in (0, 1]: larger is deeper (paper eq. 6, Fig. 2). The seen sphere's contacts
  /// (SeenProxy::contacts()) hold the layer's weight T_k alpha_k here instead.
  double k_min = 0;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< c_i, world frame
};

/// The three counts the paper plots (Fig. 5, first row).
struct QueryCounts {
  std::uint32_t candidates = 0;   ///< Gaussians in BVH leaves whose box overlaps the tool's box
  std::uint32_t prefiltered = 0;  ///< of those, passing the bounding-sphere test (eq. 4)
  std::uint32_t contacts = 0;     ///< of those, with K_min > 0
};

/// Outcome of a query; the hot path reports, never throws.
enum class QueryStatus : std::uint8_t {
  kOk,
  kInvalidTool,      ///< NaN/Inf pose or non-positive semi-axes: no contacts reported
  kContactOverflow,  ///< more contacts than the ContactSet's capacity: the first ones are kept
};

/// How a query walks the BVH (the same leaves in the same order either way, so the same
/// contacts to the last bit; only the speed differs).
enum class Traversal : std::uint8_t {
  /// Level order when the BVH's nodes are larger than this core's L2 cache (their loads then
  /// miss the caches, and level order overlaps them), depth first otherwise (fewer
  /// instructions per node when they hit).
  kAuto,
  kDepthFirst,  ///< Bvh::for_each_overlapping_leaf_node
  kLevelOrder,  ///< Bvh::for_each_overlapping_leaf_node_by_level: a level's node loads together
};

/// The L2 cache of one core, in bytes (sysconf; 1 MiB when the system does not say).
[[nodiscard]] std::size_t l2_cache_bytes() noexcept;

/// Options of the query.
struct QueryOptions {
  KMinOptions narrow_phase{Minimiser::kNewton, 30, /*stop_when_separated=*/true};
  /// Contacts one query can report; the capacity reserved up front is the smaller of this and
  /// the world's size (48 bytes each). Past it a query reports kContactOverflow. The densest
  /// poses of the bundled and benchmark scenes reach about 11k contacts.
  std::size_t max_contacts = 1u << 15;
  /// Candidate cache for a servo loop, whose queries are ~1 ms apart and nearly identical.
  /// When > 0 (world units), a broad phase collects the BVH leaves whose boxes overlap the tool's
  /// box grown by this margin on every side; the next queries whose tool box lies inside that
  /// grown box reuse the list, testing each cached leaf's box against their own box exactly as
  /// the traversal would (leaves stay in the traversal's depth-first order). So contacts, K_min,
  /// counts and their order are bit-identical to an uncached query; only the traversal is saved.
  /// A tool whose box leaves the grown box (whatever its shape) refills the cache. 0: no cache.
  double cache_margin = 0;
  /// Leaves the cache holds (32 bytes each, reserved up front); a grown box overlapping more
  /// is not cached (that query traverses as usual).
  std::size_t cache_leaves = 4096;
  /// BVH traversal of run() and of the cache's refills (any_contact() stays depth first: it
  /// stops at its first contact).
  Traversal traversal = Traversal::kAuto;
};

/// What the candidate cache did (QueryOptions::cache_margin).
struct CandidateCacheStats {
  std::uint64_t hits = 0;      ///< queries answered from the cached leaf list
  std::uint64_t refills = 0;   ///< queries that traversed the BVH with the grown box
  std::uint64_t overflows = 0; ///< refills whose grown box overlapped more than cache_leaves leaves
};

/// Contacts of one query, reused tick after tick; clear() keeps the capacity. Storage is
/// allocated once, at construction; nothing after that allocates.
class ContactSet {
 public:
  explicit ContactSet(std::size_t capacity = 1u << 15)
      : data_(new Contact[capacity]), capacity_(capacity) {}
  ContactSet(const ContactSet& o) : ContactSet(o.capacity_) {
    std::copy(o.data_.get(), o.data_.get() + o.size_, data_.get());
    size_ = o.size_;
    counts = o.counts;
  }
  ContactSet& operator=(const ContactSet& o) {
    if (this != &o) *this = ContactSet(o);
    return *this;
  }
  ContactSet(ContactSet&&) noexcept = default;
  ContactSet& operator=(ContactSet&&) noexcept = default;
  void clear() noexcept {
    size_ = 0;
    counts = {};
  }
  [[nodiscard]] std::span<const Contact> contacts() const noexcept { return {data_.get(), size_}; }
  [[nodiscard]] std::size_t capacity() const noexcept { return capacity_; }
  /// Appends without reallocating; returns false when full.
  bool push(const Contact& c) noexcept {
    if (size_ == capacity_) return false;
    data_[size_++] = c;
    return true;
  }
  /// Makes room for up to `n` more contacts at the end and returns where they start; `granted`
  /// (<= n) is how many fit. The caller fills all `granted` of them (their fields are left
  /// as they were).
  Contact* append(std::size_t n, std::size_t& granted) noexcept {
    granted = std::min(n, capacity_ - size_);
    Contact* out = data_.get() + size_;
    size_ += granted;
    return out;
  }
  QueryCounts counts;

 private:
  std::unique_ptr<Contact[]> data_;
  std::size_t size_ = 0;
  std::size_t capacity_ = 0;
};

/// Runs `fn(ctx, t)` once for every task t in [0, tasks) and returns when all are done. The
/// calling thread takes part: tasks are claimed one at a time by whichever thread is free, so a
/// worker that is slow to wake costs nothing (the caller runs its tasks) and the split adapts to
/// how busy each core is. Implemented by servo/query_pool.h's QueryPool (the core has no
/// threads). Must not allocate, lock or throw.
class ParallelExecutor {
 public:
  virtual ~ParallelExecutor() = default;
  /// Threads that may share a run, the caller included (>= 1).
  [[nodiscard]] virtual int threads() const noexcept = 0;
  /// `tasks`: 1..65535.
  virtual void run(void (*fn)(void* ctx, int task), void* ctx, int tasks) noexcept = 0;
};

/// Runs collision queries of one tool against a shared world.
class ContactQuery {
 public:
  ContactQuery(const CollisionWorld& world, const QueryOptions& options = {});

  /// Finds every Gaussian whose ellipsoid overlaps `tool` (K_min > 0). Contacts are in BVH
  /// order (sort by `index` if needed). Allocation-free.
  QueryStatus run(const ToolEllipsoid& tool) noexcept;

  /// Early exit: true as soon as one Gaussian is certified to overlap `tool` (K_min > 0), with
  /// no K_min converged for the rest; false when none overlaps (or the tool is invalid). The
  /// "is this pose free?" of the proxy. Leaves result() untouched. Allocation-free.
  /// `exclude_slot`: a world record to leave out (a Gaussian tested against the others).
  [[nodiscard]] bool any_contact(const ToolEllipsoid& tool, std::uint32_t exclude_slot = UINT32_MAX) noexcept;

  /// Early exit after `slots.size()` contacts: writes the world records (slots) of Gaussians
  /// that overlap `tool` (K_min > 0) into `slots`, in BVH order, and stops once it is full;
  /// returns how many it wrote (so slots.size() means "at least that many"). 0 for an invalid
  /// tool. Leaves result() untouched. Allocation-free. `exclude_slot`: as any_contact().
  [[nodiscard]] std::size_t first_overlaps(const ToolEllipsoid& tool, std::span<std::uint32_t> slots,
                                           std::uint32_t exclude_slot = UINT32_MAX) noexcept;

  [[nodiscard]] const ContactSet& result() const noexcept { return result_; }
  [[nodiscard]] const CandidateCacheStats& cache_stats() const noexcept { return cache_stats_; }
  /// Splits the narrow phase of queries with at least `min_candidates` candidates into
  /// kTasksPerThread tasks per executor thread (contiguous runs of BVH leaves with about equal
  /// candidates, claimed by whichever thread is free, merged back in order: the contacts, K_min
  /// and counts are bit-identical to a single-threaded query, since every lane of the batched
  /// kernel is independent of the others). nullptr: single-threaded. Reserves each task's
  /// scratch here (not on the hot path; max_contacts contacts each). The executor must outlive
  /// this query.
  void set_executor(ParallelExecutor* executor, std::size_t min_candidates = 2048);
  /// Tasks per executor thread: more tasks than threads, so a thread that is late (asleep) or
  /// slow (another job on its core) leaves its share to the others.
  static constexpr int kTasksPerThread = 3;
  /// Queries whose narrow phase was split (for statistics).
  [[nodiscard]] std::uint64_t parallel_queries() const noexcept { return parallel_queries_; }
  /// Forgets the cached candidates (the next run() traverses).
  void invalidate_cache() noexcept { cache_valid_ = false; }
  [[nodiscard]] const CollisionWorld& world() const noexcept { return *world_; }
  [[nodiscard]] const QueryOptions& options() const noexcept { return options_; }
  /// The traversal QueryOptions::traversal resolved to for this world (true: level order).
  [[nodiscard]] bool level_order() const noexcept { return level_order_; }

 private:
  const CollisionWorld* world_;
  QueryOptions options_;
  ContactSet result_;
  PairBatch batch_;  // narrow-phase scratch, reused every query
  std::uint32_t slot_[kBatchCapacity];  // the world record of each lane of batch_
  static constexpr std::size_t kLeafScratch = 4096;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> leaves_;  // overlapping leaves (first, count)
  static constexpr std::size_t kLevelScratch = 2 * 2048;  // two BVH levels of the traversal
  std::vector<std::uint32_t> levels_;
  bool level_order_ = false;  // options_.traversal resolved for this world
  // Calls on_leaf(const BvhNode&) for the leaves overlapping [lo, hi] in depth-first order, by
  // the traversal level_order_ names; on_leaf may return false to stop.
  template <typename OnLeaf>
  void traverse(const float lo[3], const float hi[3], OnLeaf&& on_leaf) noexcept;
  // Candidate cache: the leaves (with their boxes) overlapping the grown box [cache_lo_, cache_hi_].
  std::vector<BvhNode> cache_;
  float cache_lo_[3] = {0, 0, 0}, cache_hi_[3] = {0, 0, 0};
  bool cache_valid_ = false;
  CandidateCacheStats cache_stats_;
  // Parallel narrow phase: one scratch per task.
  struct Part {
    PairBatch batch;
    std::uint32_t slot[kBatchCapacity];
    ContactSet contacts{1};  // max_contacts, set by set_executor
    QueryCounts counts;
    bool overflow = false;
    std::size_t leaf_begin = 0, leaf_end = 0;
  };
  ParallelExecutor* executor_ = nullptr;
  std::size_t min_parallel_candidates_ = 2048;
  std::vector<std::unique_ptr<Part>> parts_;
  std::uint64_t parallel_queries_ = 0;
  // any_contact() and first_overlaps(): the overlapping records, BVH order, until `slots` is full.
  std::size_t early_overlaps(const ToolEllipsoid& tool, std::uint32_t exclude_slot,
                             std::span<std::uint32_t> slots) noexcept;
  void run_parts(std::size_t n_leaves, const ToolEllipsoid& tool, const BatchTool& batch_tool) noexcept;
  // The candidate cache (QueryOptions::cache_margin) for the tool box [lo, hi]: true when cache_
  // holds every leaf that can overlap it (a hit, or a refill that did not overflow).
  bool cached_leaves(const float* lo, const float* hi) noexcept;
  // The narrow phase of the `n_leaves` listed leaves split over the executor, its parts' counts and
  // contacts merged into result_ (status set on overflow). False: the query is too small or
  // spilled, and nothing was done.
  bool run_parallel(std::size_t n_leaves, const ToolEllipsoid& tool, const BatchTool& batch_tool, QueryCounts& counts,
                    QueryStatus& status) noexcept;
  void run_part(Part& part, const ToolEllipsoid& tool, const BatchTool& batch_tool) noexcept;
  friend void contact_query_part(void* ctx, int part);
  const ToolEllipsoid* part_tool_ = nullptr;
  const BatchTool* part_batch_tool_ = nullptr;
};

}  // namespace gshaptics
