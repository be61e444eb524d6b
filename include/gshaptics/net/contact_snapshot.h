#pragma once
/// @file
/// Contacts for display (viewer, ROS markers): the collision worker's newest contact set, sampled at a display rate
/// and handed to a display thread without locks (paper Sec. IV: the collision node sends the
/// colliding Gaussians to the renderer).
///
/// Threading contract: on_result() runs on the collision worker's thread (it is a
/// ResultObserver) and copies at most `kMaxShown` contacts, and only when 1 / display_hz has
/// passed since the last copy; take() is called by one display thread.

#include <array>
#include <cstdint>

#include "gshaptics/device/clock.h"
#include "gshaptics/servo/collision_worker.h"
#include "gshaptics/device/triple_buffer.h"

namespace gshaptics {

/// The contacts of one collision result, as shown (at most kMaxShown of them).
struct ContactSnapshot {
  static constexpr std::size_t kMaxShown = 2048;
  std::uint64_t pose_sequence = 0;  ///< 0: none yet
  PoseCommand pose;                 ///< the tool pose the contacts belong to
  QueryCounts counts;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< force model output for this pose, N
  Eigen::Vector3d proxy = Eigen::Vector3d::Zero();  ///< proxy centre (the pose's own without a proxy), m
  float query_us = 0;
  std::uint32_t shown = 0;  ///< entries used in `record` (min(contacts, kMaxShown))
  /// Position of each shown contact in CollisionWorld::gaussians() (world frame geometry).
  std::array<std::uint32_t, kMaxShown> record{};
};

class ContactSnapshotObserver final : public ResultObserver {
 public:
  /// Copies at most one snapshot per 1 / display_hz (every result when display_hz <= 0).
  ContactSnapshotObserver(double display_hz, Clock& clock);
  void on_result(const PoseCommand& pose, std::span<const Contact> contacts,
                 const CollisionResult& result) noexcept override;
  /// Display thread: the newest snapshot; false when none arrived since the last take.
  bool take(ContactSnapshot& out) noexcept { return buffer_.read_if_new(out); }

 private:
  Nanos min_interval_;
  Clock& clock_;
  Nanos last_copy_ = -1;
  ContactSnapshot scratch_;
  TripleBuffer<ContactSnapshot> buffer_;
};

}  // namespace gshaptics
