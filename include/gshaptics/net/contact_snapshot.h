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
#include <memory>
#include <optional>
#include <span>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/device/clock.h"
#include "gshaptics/servo/object_poses.h"
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
  /// Position of each shown contact in its world's gaussians(): the static world's (body 0) or
  /// object body - 1's body world (Contact::slot).
  std::array<std::uint32_t, kMaxShown> record{};
  /// The body each shown contact belongs to (Contact::body: 0 the static scene, i + 1 object i).
  std::array<std::uint8_t, kMaxShown> body{};
};

/// The worlds a snapshot's contacts index, for drawing them: the static world, and each object's
/// body-frame world with its pose now (a scene with rigid objects, issue 72).
struct SnapshotWorlds {
  const CollisionWorld* scene = nullptr;
  std::span<const std::shared_ptr<const CollisionWorld>> bodies;  ///< object i's body world
  const ObjectPoses* poses = nullptr;  ///< their poses now (an object's contacts need them)
};

/// A shown contact's Gaussian in the world frame.
struct ShownGaussian {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< m
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  ///< its axes in the world
  Eigen::Vector3f semi_axes = Eigen::Vector3f::Zero();  ///< k-sigma, m
  std::uint32_t source_index = 0;  ///< index in the scene file
};

/// Shown contact i of `snap` (i < snap.shown) in the world: an object's Gaussian moved by the
/// object's pose in `worlds`. nullopt when its world or pose is not in `worlds` or its slot is out
/// of range (a snapshot from another world never reads out of bounds).
[[nodiscard]] std::optional<ShownGaussian> shown_gaussian(const ContactSnapshot& snap, std::size_t i,
                                                          const SnapshotWorlds& worlds) noexcept;

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
