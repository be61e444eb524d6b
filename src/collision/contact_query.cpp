#include "gshaptics/collision/contact_query.h"

#include <unistd.h>

#include <algorithm>

#include "gshaptics/broadphase/bvh.h"
#include "gshaptics/narrowphase/k_min_batch.h"

namespace gshaptics {

ContactQuery::ContactQuery(const CollisionWorld& world, const QueryOptions& options)
    : world_(&world),
      options_(options),
      result_(std::max<std::size_t>(1, std::min(options.max_contacts, world.size()))),
      leaves_(kLeafScratch),
      levels_(kLevelScratch) {
  if (options.cache_margin > 0) cache_.reserve(options.cache_leaves);
  switch (options.traversal) {
    case Traversal::kDepthFirst: level_order_ = false; break;
    case Traversal::kLevelOrder: level_order_ = true; break;
    case Traversal::kAuto: level_order_ = world.bvh().nodes().size_bytes() > l2_cache_bytes(); break;
  }
}

std::size_t l2_cache_bytes() noexcept {
  static const std::size_t bytes = [] {
    const long n = sysconf(_SC_LEVEL2_CACHE_SIZE);
    return n > 0 ? std::size_t(n) : std::size_t(1) << 20;
  }();
  return bytes;
}

template <typename OnLeaf>
void ContactQuery::traverse(const float lo[3], const float hi[3], OnLeaf&& on_leaf) noexcept {
  if (level_order_) world_->bvh().for_each_overlapping_leaf_node_by_level(lo, hi, levels_, on_leaf);
  else world_->bvh().for_each_overlapping_leaf_node(lo, hi, on_leaf);
}

namespace {

// Fills the rotation and semi-axes of lanes [0, count) of a batch from the stored Gaussians
// named by `slot` (the offsets are written by the pre-filter). Done per batch, after the
// pre-filter, so only the Gaussians that passed it are copied.
inline void gather_lanes(PairBatch& b, const CollisionGaussian* gs, const std::uint32_t* slot) noexcept {
  for (int l = 0; l < b.count; ++l) {
    const CollisionGaussian& g = gs[slot[l]];
    for (int k = 0; k < 4; ++k) b.q[k][l] = g.quaternion[k];
    b.sx[l] = g.semi_axes[0];
    b.sy[l] = g.semi_axes[1];
    b.sz[l] = g.semi_axes[2];
  }
}

// The bounding-sphere pre-filter (paper eq. 4) over the candidates [first, first + count):
// those passing are appended to lanes [n, ...) of `b` (offset and world record); returns the new
// lane count. The caller guarantees n + count <= kBatchCapacity. Branch-free compaction (a lane
// is always written and kept only if it passed: about half do, which a branch would mispredict),
// with every running value in a register.
inline int prefilter(const CollisionGaussian* __restrict gs, std::uint32_t first, std::uint32_t count,
                     const double c[3], double r_tool, std::uint32_t exclude_slot, PairBatch& b,
                     std::uint32_t* __restrict slot, int n) noexcept {
  const double cx = c[0], cy = c[1], cz = c[2];
  double* __restrict dx = b.dx;
  double* __restrict dy = b.dy;
  double* __restrict dz = b.dz;
  for (std::uint32_t k = first; k < first + count; ++k) {
    const CollisionGaussian& g = gs[k];
    const double x = g.center[0] - cx, y = g.center[1] - cy, z = g.center[2] - cz;
    const double reach = double(g.bounding_radius()) + r_tool;
    slot[n] = k;
    dx[n] = x;
    dy[n] = y;
    dz[n] = z;
    n += (x * x + y * y + z * z <= reach * reach) & (k != exclude_slot) ? 1 : 0;
  }
  return n;
}

using LeafRange = std::pair<std::uint32_t, std::uint32_t>;  // (first record, count)

// Starts fetching the records of leaves [0, n) into this core's caches.
inline void prefetch_leaves(const CollisionGaussian* gs, const LeafRange* leaves, std::size_t n) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    const char* p = reinterpret_cast<const char*>(gs + leaves[i].first);
    const char* end = reinterpret_cast<const char*>(gs + leaves[i].first + leaves[i].second);
    for (; p < end; p += 64) __builtin_prefetch(p);
  }
}

// The contact a world record with K_min `k` reports.
inline Contact make_contact(const CollisionGaussian* gs, std::uint32_t record, double k) noexcept {
  const CollisionGaussian& g = gs[record];
  Contact contact;
  contact.index = g.source_index;
  contact.slot = record;
  contact.opacity = g.opacity;
  contact.k_min = k;
  contact.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
  return contact;
}

// Appends a batch's m contacts (lanes[j]: the batch lane of contact j) to `out`, claiming the
// room once so the set's size is not reloaded and stored per contact; returns false when they
// did not all fit (the first ones are kept).
inline bool append_contacts(ContactSet& out, const CollisionGaussian* gs, const std::uint32_t* slot,
                            const double* k, const int* lanes, int m) noexcept {
  std::size_t granted;
  Contact* dst = out.append(std::size_t(m), granted);
  for (std::size_t j = 0; j < granted; ++j) dst[j] = make_contact(gs, slot[lanes[j]], k[lanes[j]]);
  return granted == std::size_t(m);
}

// The batched narrow phase over a list of BVH leaves: pre-filter, gather, K_min, in batches of
// up to kBatchCapacity; emit(slot, k_min, lanes, m) for each batch's m contacts (lanes[j] is the
// batch lane of contact j), in leaf order. Shared by run()
// and the parallel parts, so a part computes exactly what the single-threaded query does.
template <typename Emit>
void narrow_phase(const CollisionGaussian* gs, const LeafRange* leaves, std::size_t n_leaves,
                  const double c[3], double r_tool, const BatchTool& tool, bool stop_when_separated,
                  PairBatch& batch, std::uint32_t* slot, QueryCounts& counts, Emit&& emit) noexcept {
  int n = 0;
  std::uint32_t candidates = 0, prefiltered = 0;
  const auto flush = [&] {
    batch.count = n;
    gather_lanes(batch, gs, slot);
    k_min_batch(batch, tool, stop_when_separated);
    // The contact lanes first (branch-free: contacts and separated pairs mix unpredictably),
    // then one straight loop over them, whose record loads overlap.
    int hit[kBatchCapacity];
    int m = 0;
    for (int l = 0; l < n; ++l) {
      hit[m] = l;
      m += (batch.separated[l] == 0) & (batch.k_min[l] > 0) ? 1 : 0;
    }
    emit(static_cast<const std::uint32_t*>(slot), static_cast<const double*>(batch.k_min),
         static_cast<const int*>(hit), m);
    prefiltered += std::uint32_t(n);
    n = 0;
  };
  for (std::size_t i = 0; i < n_leaves; ++i) {
    std::uint32_t first = leaves[i].first, count = leaves[i].second;
    candidates += count;
    while (count > 0) {  // a leaf larger than a batch (a big WorldConfig::leaf_size) in pieces
      const std::uint32_t take = count < std::uint32_t(kBatchCapacity) ? count : std::uint32_t(kBatchCapacity);
      if (n + int(take) > kBatchCapacity) flush();
      n = prefilter(gs, first, take, c, r_tool, UINT32_MAX, batch, slot, n);
      first += take;
      count -= take;
    }
  }
  if (n > 0) flush();
  counts.candidates += candidates;
  counts.prefiltered += prefiltered;
}

// The tool's rotation and its exact axis-aligned box, rounded outward to float (the BVH's
// precision), shared by every query of a tool.
struct ToolBox {
  explicit ToolBox(const ToolEllipsoid& tool) noexcept
      : rotation(tool.rotation.normalized().toRotationMatrix()) {
    const Eigen::Vector3d half = ellipsoid_half_extent(rotation, tool.semi_axes);
    for (int k = 0; k < 3; ++k) {
      lo[k] = round_down_to_float(tool.center[k] - half[k]);
      hi[k] = round_up_to_float(tool.center[k] + half[k]);
    }
  }
  Eigen::Matrix3d rotation;
  float lo[3], hi[3];
};

}  // namespace

bool ContactQuery::any_contact(const ToolEllipsoid& tool, std::uint32_t exclude_slot) noexcept {
  std::uint32_t first = 0;
  return early_overlaps(tool, exclude_slot, {&first, 1}) > 0;
}

std::size_t ContactQuery::first_overlaps(const ToolEllipsoid& tool, std::span<std::uint32_t> slots,
                                         std::uint32_t exclude_slot) noexcept {
  return early_overlaps(tool, exclude_slot, slots);
}

std::size_t ContactQuery::early_overlaps(const ToolEllipsoid& tool, std::uint32_t exclude_slot,
                                         std::span<std::uint32_t> slots) noexcept {
  if (!tool.valid() || slots.empty()) return 0;
  const ToolBox box(tool);
  const double r_tool = tool.bounding_radius();
  const double c_tool[3] = {tool.center.x(), tool.center.y(), tool.center.z()};
  const CollisionGaussian* gs = world_->gaussians().data();
  const BatchTool batch_tool = make_batch_tool(box.rotation, tool.semi_axes);
  PairBatch& batch = batch_;
  std::uint32_t* slot = slot_;
  // Small batches: the answer is wanted at the first contacts, not after a full batch.
  constexpr int kEarly = 2 * kBatchLanes;
  int n = 0;
  std::size_t found = 0;
  const auto flush = [&] {
    batch.count = n;
    gather_lanes(batch, gs, slot);
    k_min_batch(batch, batch_tool, /*stop_when_separated=*/true);
    for (int l = 0; l < n && found < slots.size(); ++l)
      if (!batch.separated[l] && batch.k_min[l] > 0) slots[found++] = slot[l];
    n = 0;
  };
  world_->bvh().for_each_overlapping_leaf(box.lo, box.hi, [&](std::uint32_t first, std::uint32_t count) {
    while (count > 0 && found < slots.size()) {
      const std::uint32_t take = count < std::uint32_t(kEarly) ? count : std::uint32_t(kEarly);
      n = prefilter(gs, first, take, c_tool, r_tool, exclude_slot, batch, slot, n);
      if (n >= kEarly - int(take)) flush();  // the next piece may not fit: test now
      first += take;
      count -= take;
    }
    return found < slots.size();
  });
  if (found < slots.size() && n > 0) flush();
  return found;
}

QueryStatus ContactQuery::run(const ToolEllipsoid& tool) noexcept {
  result_.clear();
  if (!tool.valid()) return QueryStatus::kInvalidTool;
  const ToolBox box(tool);
  const Eigen::Matrix3d& R_tool = box.rotation;
  const float* box_lo = box.lo;
  const float* box_hi = box.hi;
  const double r_tool = tool.bounding_radius();
  const double c_tool[3] = {tool.center.x(), tool.center.y(), tool.center.z()};
  const CollisionGaussian* gs = world_->gaussians().data();
  const bool golden = options_.narrow_phase.minimiser == Minimiser::kGoldenSection;
  const BatchTool batch_tool = make_batch_tool(R_tool, tool.semi_axes);
  QueryStatus status = QueryStatus::kOk;
  QueryCounts counts;

  const auto emit = [&](std::uint32_t record, double k) {
    ++counts.contacts;
    if (!result_.push(make_contact(gs, record, k))) status = QueryStatus::kContactOverflow;
  };
  // A batch's contacts at once (append_contacts).
  const auto emit_batch = [&](const std::uint32_t* slot, const double* k, const int* lanes, int m) {
    counts.contacts += std::uint32_t(m);
    if (!append_contacts(result_, gs, slot, k, lanes, m)) status = QueryStatus::kContactOverflow;
  };
  // The paper's method: the sphere test, then one golden-section search per pair.
  // (Its tool frame is only built for that method: the batched path has BatchTool.)
  const ToolFrame frame = golden ? ToolFrame::from(R_tool, tool.semi_axes) : ToolFrame{};
  const auto golden_leaves = [&](const LeafRange* leaves, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      counts.candidates += leaves[i].second;
      for (std::uint32_t k = leaves[i].first; k < leaves[i].first + leaves[i].second; ++k) {
        const CollisionGaussian& g = gs[k];
        const double d[3] = {g.center[0] - c_tool[0], g.center[1] - c_tool[1], g.center[2] - c_tool[2]};
        const double reach = double(g.bounding_radius()) + r_tool;
        if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > reach * reach) continue;  // eq. 4
        ++counts.prefiltered;
        const Eigen::Vector3d s(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
        const KMinResult r = k_min(pair_coefficients(frame, Eigen::Vector3d(d[0], d[1], d[2]),
                                                     rotation_matrix(g), s),
                                   options_.narrow_phase);
        if (r.k_min > 0) emit(k, r.k_min);
      }
    }
  };
  const auto test_leaves = [&](const LeafRange* leaves, std::size_t n) {
    if (golden) golden_leaves(leaves, n);
    else
      narrow_phase(gs, leaves, n, c_tool, r_tool, batch_tool, options_.narrow_phase.stop_when_separated,
                   batch_, slot_, counts, emit_batch);
  };

  // Two passes: the traversal collects the overlapping leaves and starts fetching their
  // records, then the leaves are tested, so the record loads overlap instead of queuing
  // behind each other. When the list is full, the leaves in it are tested at once.
  // With a parallel executor, the traversal fetches only the parallel threshold's candidates
  // divided by the tasks (at most the first task's share of any query that goes parallel): the
  // rest is fetched by the thread that tests it, into its own core's caches, not the caller's.
  std::size_t n_leaves = 0;
  bool spilled = false;
  const std::size_t max_leaves = leaves_.size();
  const std::uint64_t prefetch_limit =
      executor_ != nullptr && !golden ? min_parallel_candidates_ / parts_.size() : std::uint64_t(-1);
  std::uint64_t fetched = 0;      // candidates whose records the traversal fetched
  std::size_t fetched_leaves = 0;  // leaves [0, fetched_leaves) of the list were fetched
  const auto on_leaf = [&](std::uint32_t first, std::uint32_t count) {
    if (n_leaves == max_leaves) {
      prefetch_leaves(gs, leaves_.data() + fetched_leaves, n_leaves - fetched_leaves);
      test_leaves(leaves_.data(), n_leaves);
      n_leaves = 0;
      fetched_leaves = 0;
      spilled = true;
    }
    leaves_[n_leaves++] = {first, count};
    if (fetched < prefetch_limit) {
      prefetch_leaves(gs, &leaves_[n_leaves - 1], 1);
      fetched += count;
      fetched_leaves = n_leaves;
    }
  };
  const bool cached = options_.cache_margin > 0 && cached_leaves(box_lo, box_hi);
  if (cached) {
    // The traversal's own box test, on the cached leaves, in the same order.
    for (const BvhNode& n : cache_) {
      const bool overlap = !(n.lo[0] > box_hi[0] || n.hi[0] < box_lo[0] || n.lo[1] > box_hi[1] ||
                             n.hi[1] < box_lo[1] || n.lo[2] > box_hi[2] || n.hi[2] < box_lo[2]);
      if (overlap) on_leaf(n.first, n.count);
    }
  } else {
    traverse(box_lo, box_hi, [&](const BvhNode& n) { on_leaf(n.first, n.count); });
  }
  // Parallel narrow phase: every overlapping leaf is in the list (none was tested early), the
  // query is large enough, and the method is the batched one.
  if (executor_ != nullptr && !golden && !spilled && run_parallel(n_leaves, tool, batch_tool, counts, status)) {
    result_.counts = counts;
    return status;
  }
  prefetch_leaves(gs, leaves_.data() + fetched_leaves, n_leaves - fetched_leaves);
  test_leaves(leaves_.data(), n_leaves);
  result_.counts = counts;
  return status;
}

bool ContactQuery::cached_leaves(const float* box_lo, const float* box_hi) noexcept {
  const bool inside = cache_valid_ && box_lo[0] >= cache_lo_[0] && box_lo[1] >= cache_lo_[1] &&
                      box_lo[2] >= cache_lo_[2] && box_hi[0] <= cache_hi_[0] && box_hi[1] <= cache_hi_[1] &&
                      box_hi[2] <= cache_hi_[2];
  if (inside) {
    ++cache_stats_.hits;
    return true;
  }
  // Refill: every leaf overlapping the grown box, in traversal (depth-first) order. Any leaf
  // overlapping a tool box inside the grown box overlaps the grown box, so it is in the list.
  ++cache_stats_.refills;
  const double m = options_.cache_margin;
  for (int k = 0; k < 3; ++k) {
    cache_lo_[k] = round_down_to_float(double(box_lo[k]) - m);
    cache_hi_[k] = round_up_to_float(double(box_hi[k]) + m);
  }
  cache_.clear();
  bool overflow = false;
  const std::size_t cap = cache_.capacity();
  traverse(cache_lo_, cache_hi_, [&](const BvhNode& leaf) {
    if (cache_.size() == cap) {
      overflow = true;
      return false;
    }
    cache_.push_back(leaf);
    return true;
  });
  cache_valid_ = !overflow;
  if (overflow) ++cache_stats_.overflows;
  return cache_valid_;
}

bool ContactQuery::run_parallel(std::size_t n_leaves, const ToolEllipsoid& tool, const BatchTool& batch_tool,
                                QueryCounts& counts, QueryStatus& status) noexcept {
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < n_leaves; ++i) total += leaves_[i].second;
  if (total < min_parallel_candidates_ || n_leaves < parts_.size()) return false;
  ++parallel_queries_;
  run_parts(n_leaves, tool, batch_tool);
  for (const auto& part : parts_) {
    counts.candidates += part->counts.candidates;
    counts.prefiltered += part->counts.prefiltered;
    counts.contacts += part->counts.contacts;
    const std::span<const Contact> from = part->contacts.contacts();
    std::size_t granted;
    Contact* dst = result_.append(from.size(), granted);
    std::copy(from.begin(), from.begin() + std::ptrdiff_t(granted), dst);
    if (granted < from.size()) status = QueryStatus::kContactOverflow;
    if (part->overflow) status = QueryStatus::kContactOverflow;
  }
  return true;
}

void ContactQuery::set_executor(ParallelExecutor* executor, std::size_t min_candidates) {
  executor_ = executor;
  min_parallel_candidates_ = min_candidates;
  parts_.clear();
  if (executor == nullptr) return;
  const std::size_t cap = std::max<std::size_t>(1, std::min(options_.max_contacts, world_->size()));
  for (int i = 0; i < executor->threads() * kTasksPerThread; ++i) {
    auto part = std::make_unique<Part>();
    part->contacts = ContactSet(cap);
    parts_.push_back(std::move(part));
  }
}

void contact_query_part(void* ctx, int part) {
  auto* q = static_cast<ContactQuery*>(ctx);
  q->run_part(*q->parts_[std::size_t(part)], *q->part_tool_, *q->part_batch_tool_);
}

void ContactQuery::run_parts(std::size_t n_leaves, const ToolEllipsoid& tool, const BatchTool& batch_tool) noexcept {
  // Contiguous runs of leaves with about equal numbers of candidates.
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < n_leaves; ++i) total += leaves_[i].second;
  const std::size_t n_parts = parts_.size();
  std::size_t leaf = 0;
  std::uint64_t seen = 0;
  for (std::size_t p = 0; p < n_parts; ++p) {
    Part& part = *parts_[p];
    part.leaf_begin = leaf;
    const std::uint64_t until = total * (p + 1) / n_parts;
    while (leaf < n_leaves && (seen < until || p + 1 == n_parts)) seen += leaves_[leaf++].second;
    part.leaf_end = leaf;
  }
  part_tool_ = &tool;
  part_batch_tool_ = &batch_tool;
  executor_->run(&contact_query_part, this, int(n_parts));
}

// One part's narrow phase: the shared leaf loop over its leaves, into its own scratch.
void ContactQuery::run_part(Part& part, const ToolEllipsoid& tool, const BatchTool& batch_tool) noexcept {
  part.contacts.clear();
  part.counts = {};
  part.overflow = false;
  const double c_tool[3] = {tool.center.x(), tool.center.y(), tool.center.z()};
  const CollisionGaussian* gs = world_->gaussians().data();
  const auto emit = [&](const std::uint32_t* slot, const double* k, const int* lanes, int m) {
    part.counts.contacts += std::uint32_t(m);
    if (!append_contacts(part.contacts, gs, slot, k, lanes, m)) part.overflow = true;
  };
  prefetch_leaves(gs, leaves_.data() + part.leaf_begin, part.leaf_end - part.leaf_begin);
  narrow_phase(gs, leaves_.data() + part.leaf_begin, part.leaf_end - part.leaf_begin, c_tool,
               tool.bounding_radius(), batch_tool, options_.narrow_phase.stop_when_separated, part.batch,
               part.slot, part.counts, emit);
}

}  // namespace gshaptics
