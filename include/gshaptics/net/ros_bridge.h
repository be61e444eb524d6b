#pragma once
/// @file
/// What the ROS 2 (DDS) and ROS 1 (roscpp) bridges share: topic and QoS options, ROS time, the
/// bridge counters and the device interface the CLI's `node` command drives. Header-only; no
/// middleware here, so the core and either bridge build without the other.

#include <atomic>
#include <cstdint>
#include <ctime>
#include <string>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/servo/contact_snapshot.h"
#include "gshaptics/servo/haptic_device.h"

namespace gshaptics {

/// Topics, frame and QoS. Topic names are ROS names (leading '/' optional).
struct RosBridgeOptions {
  int domain = -1;  ///< ROS 2: DDS domain (= ROS_DOMAIN_ID); -1: the DDS default. ROS 1: unused
  std::string pose_topic = "gshaptics/tool_pose";    ///< geometry_msgs/PoseStamped, in
  std::string twist_topic = "gshaptics/tool_twist";  ///< geometry_msgs/TwistStamped, in (optional)
  std::string wrench_topic = "gshaptics/wrench";     ///< geometry_msgs/WrenchStamped, out
  std::string markers_topic = "gshaptics/markers";   ///< visualization_msgs/MarkerArray, out
  std::string frame_id = "world";                    ///< header.frame_id of what we publish
  bool reliable = false;  ///< ROS 2 streams: best-effort (default) or reliable
  int depth = 1;          ///< ROS 2 keep-last depth of the written streams (readers keep 64)
  double marker_hz = 30;  ///< MarkerArray rate
  std::size_t max_markers = 500;  ///< colliding Gaussians per MarkerArray (the rest are counted)
  double input_timeout = 0.1;     ///< no pose for this long: the device stops (watchdog), s
};

/// ROS time (the system clock) as builtin_interfaces/Time (ROS 2) or ros::Time (ROS 1) fields.
struct RosTime {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
  [[nodiscard]] static RosTime now() noexcept {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    return {std::int32_t(ts.tv_sec), std::uint32_t(ts.tv_nsec)};
  }
  [[nodiscard]] std::int64_t nanos() const noexcept { return std::int64_t(sec) * 1'000'000'000 + nanosec; }
};

/// Counters of a bridge (any thread).
struct RosBridgeStats {
  std::atomic<std::uint64_t> poses_received{0};
  std::atomic<std::uint64_t> poses_dropped{0};  ///< NaN/Inf pose or twist: dropped, counted
  std::atomic<std::uint64_t> twists_received{0};
  std::atomic<std::uint64_t> wrenches_published{0};
  std::atomic<std::uint64_t> markers_published{0};
  std::atomic<std::uint32_t> pose_publishers{0};  ///< distinct publishers seen on the pose topic
};

/// A device on a ROS network: the pose comes in, the wrench goes out, markers on the side.
class RosBridgeDevice : public HapticDevice {
 public:
  [[nodiscard]] virtual const RosBridgeStats& stats() const noexcept = 0;
  /// Starts publishing the tool and colliding Gaussians as MarkerArrays (own thread).
  virtual void start_markers(const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                             const Eigen::Vector3d& tool_axes) = 0;
  virtual void stop_markers() = 0;
  /// The full names of the pose, twist, wrench and markers topics on the wire.
  [[nodiscard]] virtual std::string wire_topic(const std::string& ros_name) const = 0;
};

}  // namespace gshaptics
