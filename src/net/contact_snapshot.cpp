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
  for (std::size_t i = 0; i < n; ++i) {
    scratch_.record[i] = contacts[i].slot;
    scratch_.body[i] = contacts[i].body;
  }
  scratch_.shown = std::uint32_t(n);
  buffer_.write(scratch_);
}

std::optional<ShownGaussian> shown_gaussian(const ContactSnapshot& snap, std::size_t i,
                                            const SnapshotWorlds& worlds) noexcept {
  if (i >= snap.shown) return std::nullopt;
  const std::uint8_t body = snap.body[i];
  const CollisionWorld* world = body == 0 ? worlds.scene
                                : std::size_t(body) <= worlds.bodies.size() ? worlds.bodies[body - 1u].get()
                                                                            : nullptr;
  if (world == nullptr || snap.record[i] >= world->size()) return std::nullopt;
  if (body > 0 && (worlds.poses == nullptr || body > worlds.poses->count)) return std::nullopt;
  const CollisionGaussian& g = world->gaussians()[snap.record[i]];
  ShownGaussian out;
  out.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
  out.rotation = Eigen::Quaterniond(rotation_matrix(g)).normalized();
  out.semi_axes = Eigen::Vector3f(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
  out.source_index = g.source_index;
  if (body > 0) {
    const BodyPose& p = worlds.poses->poses[body - 1u];
    out.center = p.rotation * out.center + p.position;
    out.rotation = p.rotation * out.rotation;
  }
  return out;
}

}  // namespace gshaptics
