#include "gshaptics/net/contact_snapshot.h"

#include <algorithm>

namespace gshaptics {

ContactSnapshotObserver::ContactSnapshotObserver(double display_hz, Clock& clock)
    : min_interval_(display_hz > 0 ? to_nanos(1.0 / display_hz) : 0), clock_(clock) {}

void ContactSnapshotObserver::on_result(const PoseCommand& pose, std::span<const Contact> contacts,
                                        const CollisionResult& result) noexcept {
  const Nanos now = clock_.now();
  if (last_copy_ >= 0 && now - last_copy_ < min_interval_) return;
  last_copy_ = now;
  scratch_.pose_sequence = result.pose_sequence;
  scratch_.pose = pose;
  scratch_.counts = result.counts;
  scratch_.force = result.force;
  scratch_.proxy = result.proxy;
  scratch_.query_us = result.query_us;
  const std::size_t n = std::min(contacts.size(), ContactSnapshot::kMaxShown);
  for (std::size_t i = 0; i < n; ++i) scratch_.record[i] = contacts[i].slot;
  scratch_.shown = std::uint32_t(n);
  buffer_.write(scratch_);
}

}  // namespace gshaptics
