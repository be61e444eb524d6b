#include "gshaptics/force/floater_test.h"

#include <algorithm>

namespace gshaptics {

FloaterTest::FloaterTest(const CollisionWorld& world)
    : world_(&world), query_(world, [] {
        QueryOptions q;
        q.max_contacts = 1;  // any_contact() keeps no contact set
        return q;
      }()) {}

int FloaterTest::cached(std::uint32_t slot, double gap) noexcept {
  if (gap != gap_) {  // another tool size: the cached answers are for another neighbourhood
    state_.fill(0);
    gap_ = gap;
  }
  for (std::size_t i = 0; i < kCacheSize; ++i)
    if (state_[i] != 0 && slot_[i] == slot) return state_[i];
  return 0;
}

bool FloaterTest::isolated(std::uint32_t slot, double gap) noexcept {
  if (const int known = cached(slot, gap); known != 0) return known == 2;
  const CollisionGaussian& g = world_->gaussians()[slot];
  ToolEllipsoid self;
  self.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
  self.rotation = Eigen::Quaterniond(rotation_matrix(g)).normalized();
  // Grown by the gap, but by no more than its own middle semi-axis: a sparse surface's
  // neighbours lie about one Gaussian size away, while a floater a few sizes off a surface stays
  // a floater (the fidelity scenes' floaters, 5-30 mm off, did catch a 10 mm tool otherwise).
  const Eigen::Vector3d a(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
  const double a_mid = a.sum() - a.maxCoeff() - a.minCoeff();
  self.semi_axes = a.array() + std::clamp(gap, 0.0, a_mid);
  const bool alone = !query_.any_contact(self, slot);
  slot_[next_] = slot;
  state_[next_] = alone ? 2 : 1;
  next_ = (next_ + 1) % kCacheSize;
  return alone;
}

bool FloaterTest::Filter::blocks(void* context, std::uint32_t slot) noexcept {
  auto* f = static_cast<Filter*>(context);
  const int known = f->test_->cached(slot, f->gap_);
  if (known != 0) return known == 1;
  if (f->left_ <= 0) return true;
  --f->left_;
  return !f->test_->isolated(slot, f->gap_);
}

bool FloaterTest::Filter::known_to_pass(void* context, std::uint32_t slot) noexcept {
  const auto* f = static_cast<const Filter*>(context);
  return f->test_->cached(slot, f->gap_) == 2;
}

}  // namespace gshaptics
