#include "gshaptics/force/floater_rule.h"

#include <algorithm>
#include <span>

namespace gshaptics {

FloaterRule::FloaterRule(const CollisionWorld& world, std::size_t max_cluster)
    : world_(&world),
      query_(world,
             [] {
               QueryOptions q;
               q.max_contacts = 1;  // the early-exit queries keep no contact set
               return q;
             }()),
      max_cluster_(std::clamp<std::size_t>(max_cluster, 1, kLargestCluster)) {}

namespace {
// The Gaussian's ellipsoid grown by `grow` (m) on every semi-axis.
ToolEllipsoid grown(const CollisionGaussian& g, double grow) noexcept {
  ToolEllipsoid e;
  e.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
  e.rotation = Eigen::Quaterniond(rotation_matrix(g)).normalized();
  e.semi_axes = Eigen::Vector3d(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]).array() + grow;
  return e;
}
// Grown by the gap, but by no more than its own middle semi-axis: a sparse surface's neighbours
// lie about one Gaussian size away, while a floater a few sizes off a surface stays a floater
// (the fidelity scenes' floaters, 5-30 mm off, did catch a 10 mm tool otherwise).
double own_gap(const CollisionGaussian& g, double gap) noexcept { return std::clamp(gap, 0.0, middle_semi_axis(g)); }
}  // namespace

int FloaterRule::cached(std::uint32_t slot, double gap) noexcept {
  if (gap != gap_) {  // another tool size: the cached answers are for another neighbourhood
    state_.fill(0);
    gap_ = gap;
  }
  for (std::size_t i = 0; i < kCacheSize; ++i)
    if (state_[i] != 0 && slot_[i] == slot) return state_[i];
  return 0;
}

bool FloaterRule::isolated(std::uint32_t slot, double gap) noexcept {
  if (const int known = cached(slot, gap); known != 0) return known == 2;
  const std::span<const CollisionGaussian> gs = world_->gaussians();
  std::array<std::uint32_t, kLargestCluster> members{slot};
  std::size_t n = 1;
  const bool alone = max_cluster_ > 1 ? isolated_cluster(gap, members, n)
                                     : !query_.any_contact(grown(gs[slot], own_gap(gs[slot], gap)), slot);
  for (std::size_t i = 0; i < (alone ? n : 1); ++i) remember(members[i], alone);
  return alone;
}

bool FloaterRule::isolated_cluster(double gap, std::array<std::uint32_t, kLargestCluster>& members,
                                   std::size_t& n) noexcept {
  const std::span<const CollisionGaussian> gs = world_->gaussians();
  const auto member = [&](std::uint32_t s) { return std::find(members.begin(), members.begin() + n, s) != members.begin() + n; };
  // Early-exit listings of the Gaussians other than a member: at most as many as a cluster holds.
  std::array<std::uint32_t, kLargestCluster> listed;
  // The overlap cluster, breadth first (each Gaussian grown by its gap, as above): a Gaussian
  // that overlaps as many others as a cluster holds, or more than max_cluster_ members, is a
  // surface. The first listing is the single-floater test itself: none overlaps it.
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k = query_.first_overlaps(grown(gs[members[i]], own_gap(gs[members[i]], gap)),
                                                {listed.data(), max_cluster_}, members[i]);
    if (i == 0 && k == 0) return true;
    if (k == max_cluster_) return false;
    for (std::size_t j = 0; j < k; ++j) {
      if (member(listed[j])) continue;
      if (n == max_cluster_) return false;
      members[n++] = listed[j];
    }
  }
  // Its surroundings: every member grown by its own largest semi-axis still meets no Gaussian
  // outside the cluster (a clump in free space, not a clump of a surface's discs, whose
  // neighbours lie about one disc size away).
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k = query_.first_overlaps(grown(gs[members[i]], gs[members[i]].bounding_radius()),
                                                {listed.data(), n}, members[i]);
    for (std::size_t j = 0; j < k; ++j)
      if (!member(listed[j])) return false;
  }
  return true;
}

void FloaterRule::remember(std::uint32_t slot, bool alone) noexcept {
  for (std::size_t i = 0; i < kCacheSize; ++i)
    if (state_[i] != 0 && slot_[i] == slot) {
      state_[i] = alone ? 2 : 1;
      return;
    }
  slot_[next_] = slot;
  state_[next_] = alone ? 2 : 1;
  next_ = (next_ + 1) % kCacheSize;
}

bool FloaterRule::Filter::blocks(void* context, std::uint32_t slot) noexcept {
  auto* f = static_cast<Filter*>(context);
  const int known = f->test_->cached(slot, f->gap_);
  if (known != 0) return known == 1;
  if (f->left_ <= 0) return true;
  --f->left_;
  return !f->test_->isolated(slot, f->gap_);
}

bool FloaterRule::Filter::known_to_pass(void* context, std::uint32_t slot) noexcept {
  const auto* f = static_cast<const Filter*>(context);
  return f->test_->cached(slot, f->gap_) == 2;
}

}  // namespace gshaptics
