#pragma once
/// @file
/// The live poses of a scene's rigid objects (issue 72), as the servo thread publishes them and
/// the viewer, ROS and the logs read them. No MuJoCo here: a reader needs only these values.
///
/// Frames: an object's body frame has its axes along the world's at rest and its origin at
/// RigidObject::rest_origin (objects/rigid_object.h); a pose maps the body frame into the world,
/// x_world = rotation * x_body + position. Units: metres, seconds, newtons.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gshaptics/device/triple_buffer.h"
#include "gshaptics/scene/scene_cut.h"

namespace gshaptics {

/// A rigid pose of a body frame in the world: x_world = rotation * x_body + position.
struct BodyPose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< m
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();   ///< of the body origin, m/s, world
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  ///< rad/s, world
  /// The world velocity of the body-fixed point now at `p` (world), m/s.
  [[nodiscard]] Eigen::Vector3d velocity_at(const Eigen::Vector3d& p) const noexcept {
    return linear_velocity + angular_velocity.cross(p - position);
  }
};

/// The wrench the hand (the tool's coupling) put on an object over the last dynamics step:
/// force in N and torque about the object's centre of mass in N m, both in world axes (MuJoCo's
/// xfrc_applied). Zero while nothing touches the object.
struct AppliedWrench {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
};

/// The live state of a scene's objects, one value per dynamics step (a plain struct: it is copied
/// through TripleBuffers without allocating).
struct ObjectPoses {
  double time = 0;  ///< simulated time since the run's start, s
  std::uint32_t count = 0;
  std::array<BodyPose, kMaxObjects> poses{};
  std::array<AppliedWrench, kMaxObjects> wrenches{};
};

/// The objects' poses and applied wrenches over a run, one row per published dynamics step (a
/// sleeping step publishes nothing: nothing moved). Memory is reserved up front; push() drops and
/// counts rows past the capacity instead of allocating, so the servo tick may call it.
class ObjectTrack {
 public:
  /// Room for `capacity` rows of `objects` objects (at most kMaxObjects).
  ObjectTrack(std::size_t objects, std::size_t capacity);
  void push(const ObjectPoses& poses) noexcept;
  [[nodiscard]] std::size_t objects() const noexcept { return objects_; }
  [[nodiscard]] std::size_t rows() const noexcept { return times_.size(); }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return dropped_; }
  [[nodiscard]] double time(std::size_t row) const noexcept { return times_[row]; }
  /// Object `object`'s body origin (m), rotation and the hand's force on it (N) at row `row`.
  [[nodiscard]] Eigen::Vector3d position(std::size_t row, std::size_t object) const noexcept {
    return Eigen::Map<const Eigen::Vector3f>(at(row, object)).cast<double>();
  }
  [[nodiscard]] Eigen::Quaterniond rotation(std::size_t row, std::size_t object) const noexcept {
    const float* v = at(row, object) + 3;
    return Eigen::Quaterniond(v[0], v[1], v[2], v[3]);
  }
  [[nodiscard]] Eigen::Vector3d force(std::size_t row, std::size_t object) const noexcept {
    return Eigen::Map<const Eigen::Vector3f>(at(row, object) + 7).cast<double>();
  }
  /// Writes objects_log.csv's form: time_s, then per object I: objI_x, objI_y, objI_z (body
  /// origin, m), objI_qw, objI_qx, objI_qy, objI_qz, objI_fx, objI_fy, objI_fz (the hand's force
  /// on it, N), to a temporary name, then renames. Throws InputError naming `path`.
  void write_csv(const std::string& path) const;

 private:
  static constexpr std::size_t kValues = 10;  // x y z qw qx qy qz fx fy fz, float (a row of 8 objects: 320 B)
  [[nodiscard]] const float* at(std::size_t row, std::size_t object) const noexcept {
    return values_.data() + (row * objects_ + object) * kValues;
  }
  std::size_t objects_;
  std::vector<double> times_;
  std::vector<float> values_;
  std::uint64_t dropped_ = 0;
};

/// Hands ObjectPoses from the one thread that steps the dynamics (the servo thread) to up to
/// kMaxReaders other threads (the viewer, a ROS publisher, a logger), each through its own
/// TripleBuffer: the writer never waits, a reader always gets the newest complete value.
///
/// Threading: subscribe() from any thread (once per reader, before its reads); write() from one
/// thread; read_if_new(r) from the thread that holds reader slot r. All lock-free and
/// allocation-free; write() costs kMaxReaders copies of ObjectPoses (about 5 KB).
class ObjectPoseChannel {
 public:
  static constexpr int kMaxReaders = 4;

  /// A reader slot for the calling thread's reads, or -1 when all kMaxReaders are taken.
  [[nodiscard]] int subscribe() noexcept {
    int n = readers_.load(std::memory_order_relaxed);
    while (n < kMaxReaders && !readers_.compare_exchange_weak(n, n + 1, std::memory_order_acq_rel)) {
    }
    return n < kMaxReaders ? n : -1;
  }
  /// Every written value also goes to `track` (null: none). Set it before the writer starts
  /// (a run's logs: RuntimeSetup); the channel keeps it alive.
  void record_into(std::shared_ptr<ObjectTrack> track) noexcept { track_ = std::move(track); }
  [[nodiscard]] const std::shared_ptr<ObjectTrack>& track() const noexcept { return track_; }
  /// The writer: publishes `poses` to every reader slot, subscribed or not yet (so a reader that
  /// subscribes later still gets the newest value, even if nothing is written after it came: the
  /// dynamics only step while the device sends poses), and to the track.
  void write(const ObjectPoses& poses) noexcept {
    for (TripleBuffer<ObjectPoses>& b : buffers_) b.write(poses);
    if (track_) track_->push(poses);
  }
  /// Reader `reader` (from subscribe()): the newest value into `out` when one was written since
  /// its last read; false otherwise (and for an invalid slot).
  bool read_if_new(int reader, ObjectPoses& out) noexcept {
    if (reader < 0 || reader >= readers_.load(std::memory_order_acquire)) return false;
    return buffers_[std::size_t(reader)].read_if_new(out);
  }

 private:
  std::array<TripleBuffer<ObjectPoses>, kMaxReaders> buffers_;
  std::atomic<int> readers_{0};
  std::shared_ptr<ObjectTrack> track_;
};

}  // namespace gshaptics
