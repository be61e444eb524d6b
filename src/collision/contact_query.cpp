#include "gshaptics/collision/contact_query.h"

#include <algorithm>

#include "gshaptics/broadphase/bvh.h"
#include "gshaptics/narrowphase/k_min_batch.h"

namespace gshaptics {

ContactQuery::ContactQuery(const CollisionWorld& world, const QueryOptions& options)
    : world_(&world),
      options_(options),
      result_(std::max<std::size_t>(1, std::min(options.max_contacts, world.size()))),
      leaves_(kLeafScratch) {
  if (options.cache_margin > 0) cache_.reserve(options.cache_leaves);
}

namespace {

// Fills lane `l` of a batch from a stored Gaussian.
inline void load_lane(PairBatch& b, int l, const CollisionGaussian& g, const double d[3]) noexcept {
  b.dx[l] = d[0];
  b.dy[l] = d[1];
  b.dz[l] = d[2];
  for (int k = 0; k < 9; ++k) b.r[k][l] = g.rotation[k];
  b.sx[l] = g.semi_axes[0];
  b.sy[l] = g.semi_axes[1];
  b.sz[l] = g.semi_axes[2];
}

// Pads unused lanes with coincident, unit Gaussians (inactive in the kernel, no NaN/denormals).
inline void pad_lanes(PairBatch& b) noexcept {
  for (int l = b.count; l < kBatchLanes; ++l) {
    b.dx[l] = b.dy[l] = b.dz[l] = 0;
    for (int k = 0; k < 9; ++k) b.r[k][l] = (k % 4 == 0) ? 1.f : 0.f;
    b.sx[l] = b.sy[l] = b.sz[l] = 1;
  }
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
  if (!tool.valid()) return false;
  const ToolBox box(tool);
  const Eigen::Matrix3d& R_tool = box.rotation;
  const float* box_lo = box.lo;
  const float* box_hi = box.hi;
  const double r_tool = tool.bounding_radius();
  const CollisionGaussian* gs = world_->gaussians().data();
  const BatchTool batch_tool = make_batch_tool(R_tool, tool.semi_axes);
  PairBatch& batch = batch_;
  batch.count = 0;
  bool found = false;
  const auto flush = [&] {
    pad_lanes(batch);
    k_min_batch(batch, batch_tool, /*stop_when_separated=*/true);
    for (int l = 0; l < batch.count; ++l) found = found || (!batch.separated[l] && batch.k_min[l] > 0);
    batch.count = 0;
  };
  world_->bvh().for_each_overlapping_leaf(box_lo, box_hi, [&](std::uint32_t first, std::uint32_t count) {
    for (std::uint32_t k = first; k < first + count; ++k) {
      const CollisionGaussian& g = gs[k];
      const double d[3] = {g.center[0] - tool.center[0], g.center[1] - tool.center[1], g.center[2] - tool.center[2]};
      const double reach = double(g.bounding_radius()) + r_tool;
      load_lane(batch, batch.count, g, d);
      batch.count += d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= reach * reach && k != exclude_slot ? 1 : 0;  // eq. 4
      if (batch.count == kBatchLanes) flush();
      if (found) return false;
    }
    return true;
  });
  if (!found && batch.count > 0) flush();
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
  const ToolFrame frame = ToolFrame::from(R_tool, tool.semi_axes);
  const BatchTool batch_tool = make_batch_tool(R_tool, tool.semi_axes);
  QueryStatus status = QueryStatus::kOk;
  QueryCounts counts;
  PairBatch& batch = batch_;
  std::uint32_t slot[kBatchLanes];
  batch.count = 0;

  const auto emit = [&](std::uint32_t record, double k) {
    const CollisionGaussian& g = gs[record];
    ++counts.contacts;
    Contact contact;
    contact.index = g.source_index;
    contact.slot = record;
    contact.opacity = g.opacity;
    contact.k_min = k;
    contact.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
    if (!result_.push(contact)) status = QueryStatus::kContactOverflow;
  };
  const auto flush = [&] {
    pad_lanes(batch);
    k_min_batch(batch, batch_tool, options_.narrow_phase.stop_when_separated);
    for (int l = 0; l < batch.count; ++l)
      if (!batch.separated[l] && batch.k_min[l] > 0) emit(slot[l], batch.k_min[l]);
    batch.count = 0;
  };

  // Two passes: the traversal collects the overlapping leaves and starts fetching their
  // records, then the leaves are tested, so the record loads overlap instead of queuing
  // behind each other. A leaf that does not fit the scratch list is tested at once.
  const auto test_leaf = [&](std::uint32_t first, std::uint32_t count) {
    counts.candidates += count;
    for (std::uint32_t k = first; k < first + count; ++k) {
      const CollisionGaussian& g = gs[k];
      const double d[3] = {g.center[0] - c_tool[0], g.center[1] - c_tool[1], g.center[2] - c_tool[2]};
      const double reach = double(g.bounding_radius()) + r_tool;
      const bool pass = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= reach * reach;  // eq. 4
      counts.prefiltered += pass ? 1 : 0;
      if (golden) {  // the paper's method, one pair at a time
        if (!pass) continue;
        const Eigen::Vector3d s(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
        const KMinResult r = k_min(pair_coefficients(frame, Eigen::Vector3d(d[0], d[1], d[2]),
                                                     rotation_matrix(g), s),
                                   options_.narrow_phase);
        if (r.k_min > 0) emit(k, r.k_min);
        continue;
      }
      // Branch-free compaction: the lane is always written and kept only if it passed (about
      // half do, which a branch would mispredict).
      slot[batch.count] = k;
      load_lane(batch, batch.count, g, d);
      batch.count += pass ? 1 : 0;
      if (batch.count == kBatchLanes) flush();
    }
  };
  std::size_t n_leaves = 0;
  const std::size_t max_leaves = leaves_.size();
  const auto on_leaf = [&](std::uint32_t first, std::uint32_t count) {
    if (n_leaves == max_leaves) {
      test_leaf(first, count);
      return;
    }
    const char* p = reinterpret_cast<const char*>(gs + first);
    const char* end = reinterpret_cast<const char*>(gs + first + count);
    for (; p < end; p += 64) __builtin_prefetch(p);
    leaves_[n_leaves++] = {first, count};
  };
  bool cached = false;
  if (options_.cache_margin > 0) {
    const bool inside = cache_valid_ && box_lo[0] >= cache_lo_[0] && box_lo[1] >= cache_lo_[1] &&
                        box_lo[2] >= cache_lo_[2] && box_hi[0] <= cache_hi_[0] && box_hi[1] <= cache_hi_[1] &&
                        box_hi[2] <= cache_hi_[2];
    if (inside) {
      ++cache_stats_.hits;
      cached = true;
    } else {
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
      world_->bvh().for_each_overlapping_leaf_node(cache_lo_, cache_hi_, [&](const BvhNode& leaf) {
        if (cache_.size() == cap) {
          overflow = true;
          return false;
        }
        cache_.push_back(leaf);
        return true;
      });
      cache_valid_ = !overflow;
      cached = cache_valid_;
      if (overflow) ++cache_stats_.overflows;
    }
  }
  if (cached) {
    // The traversal's own box test, on the cached leaves, in the same order.
    for (const BvhNode& n : cache_) {
      const bool overlap = !(n.lo[0] > box_hi[0] || n.hi[0] < box_lo[0] || n.lo[1] > box_hi[1] ||
                             n.hi[1] < box_lo[1] || n.lo[2] > box_hi[2] || n.hi[2] < box_lo[2]);
      if (overlap) on_leaf(n.first, n.count);
    }
  } else {
    world_->bvh().for_each_overlapping_leaf(box_lo, box_hi, on_leaf);
  }
  // Parallel narrow phase: every overlapping leaf is in the list (none was tested early), the
  // query is large enough, and the method is the batched one.
  if (executor_ != nullptr && !golden && batch.count == 0 && counts.candidates == 0) {
    std::uint64_t total = 0;
    for (std::size_t i = 0; i < n_leaves; ++i) total += leaves_[i].second;
    if (total >= min_parallel_candidates_ && n_leaves >= parts_.size()) {
      ++parallel_queries_;
      run_parts(n_leaves, tool, batch_tool);
      for (const auto& part : parts_) {
        counts.candidates += part->counts.candidates;
        counts.prefiltered += part->counts.prefiltered;
        counts.contacts += part->counts.contacts;
        for (const Contact& c : part->contacts)
          if (!result_.push(c)) status = QueryStatus::kContactOverflow;
        if (part->overflow) status = QueryStatus::kContactOverflow;
      }
      result_.counts = counts;
      return status;
    }
  }
  for (std::size_t i = 0; i < n_leaves; ++i) test_leaf(leaves_[i].first, leaves_[i].second);
  if (batch.count > 0) flush();
  result_.counts = counts;
  return status;
}

void ContactQuery::set_executor(ParallelExecutor* executor, std::size_t min_candidates) {
  executor_ = executor;
  min_parallel_candidates_ = min_candidates;
  parts_.clear();
  if (executor == nullptr) return;
  const std::size_t cap = std::max<std::size_t>(1, std::min(options_.max_contacts, world_->size()));
  for (int i = 0; i < executor->parts(); ++i) {
    auto part = std::make_unique<Part>();
    part->contacts.reserve(cap);
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
  executor_->run(&contact_query_part, this);
}

// One part's narrow phase: the sequential loop of run() over its leaves, into its own scratch.
void ContactQuery::run_part(Part& part, const ToolEllipsoid& tool, const BatchTool& batch_tool) noexcept {
  part.contacts.clear();
  part.counts = {};
  part.overflow = false;
  const double r_tool = tool.bounding_radius();
  const double c_tool[3] = {tool.center.x(), tool.center.y(), tool.center.z()};
  const CollisionGaussian* gs = world_->gaussians().data();
  PairBatch& batch = part.batch;
  std::uint32_t slot[kBatchLanes];
  batch.count = 0;
  const auto flush = [&] {
    pad_lanes(batch);
    k_min_batch(batch, batch_tool, options_.narrow_phase.stop_when_separated);
    for (int l = 0; l < batch.count; ++l)
      if (!batch.separated[l] && batch.k_min[l] > 0) {
        const CollisionGaussian& g = gs[slot[l]];
        ++part.counts.contacts;
        Contact contact;
        contact.index = g.source_index;
        contact.slot = slot[l];
        contact.opacity = g.opacity;
        contact.k_min = batch.k_min[l];
        contact.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
        if (part.contacts.size() < part.contacts.capacity()) part.contacts.push_back(contact);
        else part.overflow = true;
      }
    batch.count = 0;
  };
  for (std::size_t i = part.leaf_begin; i < part.leaf_end; ++i) {
    const std::uint32_t first = leaves_[i].first, count = leaves_[i].second;
    part.counts.candidates += count;
    for (std::uint32_t k = first; k < first + count; ++k) {
      const CollisionGaussian& g = gs[k];
      const double d[3] = {g.center[0] - c_tool[0], g.center[1] - c_tool[1], g.center[2] - c_tool[2]};
      const double reach = double(g.bounding_radius()) + r_tool;
      const bool pass = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= reach * reach;  // eq. 4
      part.counts.prefiltered += pass ? 1 : 0;
      slot[batch.count] = k;
      load_lane(batch, batch.count, g, d);
      batch.count += pass ? 1 : 0;
      if (batch.count == kBatchLanes) flush();
    }
  }
  if (batch.count > 0) flush();
}

}  // namespace gshaptics
