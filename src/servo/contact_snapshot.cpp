#include "gshaptics/servo/contact_snapshot.h"

#include <algorithm>

namespace gshaptics {

ContactSnapshotObserver::ContactSnapshotObserver(const CollisionWorld& world, double display_hz, Clock& clock)
    : world_(world), min_interval_(display_hz > 0 ? to_nanos(1.0 / display_hz) : 0), clock_(clock) {
  std::uint32_t max_source = 0;
  for (const auto& g : world.gaussians()) max_source = std::max(max_source, g.source_index);
  record_of_source_.assign(std::size_t(max_source) + 1, 0);
  for (std::size_t r = 0; r < world.size(); ++r)
    record_of_source_[world.gaussians()[r].source_index] = std::uint32_t(r);
}

void ContactSnapshotObserver::on_result(const PoseCommand& pose, std::span<const Contact> contacts,
                                        const CollisionResult& result) noexcept {
  const Nanos now = clock_.now();
  if (last_copy_ >= 0 && now - last_copy_ < min_interval_) return;
  last_copy_ = now;
  scratch_.pose_sequence = result.pose_sequence;
  scratch_.pose = pose;
  scratch_.counts = result.counts;
  scratch_.force = result.force;
  scratch_.query_us = result.query_us;
  const std::size_t n = std::min(contacts.size(), ContactSnapshot::kMaxShown);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t src = contacts[i].index;
    scratch_.record[i] = src < record_of_source_.size() ? record_of_source_[src] : 0;
  }
  scratch_.shown = std::uint32_t(n);
  buffer_.write(scratch_);
}

}  // namespace gshaptics
