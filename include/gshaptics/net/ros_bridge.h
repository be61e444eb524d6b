#pragma once
/// @file
/// What the ROS 2 (DDS) and ROS 1 (roscpp) bridges share: topic and QoS options, ROS time, the
/// bridge counters, the device interface the CLI's `node` command drives, and the middleware-free
/// parts of a bridge (pose intake, wrench outbox, marker loop; library gshaptics_ros_common). No
/// middleware here, so the core and either bridge build without the other.

#include <atomic>
#include <cstdint>
#include <ctime>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/net/ros_marker.h"
#include "gshaptics/net/contact_snapshot.h"
#include "gshaptics/servo/object_poses.h"
#include "gshaptics/device/haptic_device.h"
#include "gshaptics/device/stream_device.h"
#include "gshaptics/device/triple_buffer.h"

namespace gshaptics {

/// Topics, frame and QoS. Topic names are ROS names: relative ones (the defaults) resolve in the
/// node's namespace (ROS 1: ROS_NAMESPACE or __ns:=; ROS 2: __ns), absolute ones ('/...') do not.
struct RosBridgeOptions {
  /// The node's name (ROS 1: registered with the master; two nodes on one master need two names).
  std::string node_name = "gshaptics_node";
  /// Command-line arguments for the middleware, passed through as given: ROS 1 remappings
  /// (`from:=to`, `__name:=`, `__ns:=`), or ROS 2's `--ros-args -r from:=to ...`.
  std::vector<std::string> ros_args;
  int domain = -1;  ///< ROS 2: DDS domain (= ROS_DOMAIN_ID); -1: the DDS default. ROS 1: unused
  std::string pose_topic = "gshaptics/tool_pose";    ///< geometry_msgs/PoseStamped, in
  std::string twist_topic = "gshaptics/tool_twist";  ///< geometry_msgs/TwistStamped, in (optional)
  std::string wrench_topic = "gshaptics/wrench";     ///< geometry_msgs/WrenchStamped, out
  std::string markers_topic = "gshaptics/markers";   ///< visualization_msgs/MarkerArray, out
  /// With rigid objects (--object): object I's pose (its body origin, world frame) as a
  /// geometry_msgs/PoseStamped on OBJECTS_TOPIC/objectI, out, at the marker rate.
  std::string objects_topic = "gshaptics/objects";
  std::string frame_id = "world";                    ///< header.frame_id of what we publish
  /// Admittance control (issue 73): the remote device is a robot with a force/torque sensor at its
  /// handle. The node then reads the sensor and writes the robot's setpoint as well.
  bool admittance = false;
  /// geometry_msgs/WrenchStamped, in (admittance): the user's wrench at the handle, world frame, N
  /// and N m; ros2_control's force_torque_sensor_broadcaster publishes on this name.
  std::string sensor_topic = "force_torque_sensor_broadcaster/wrench";
  std::string setpoint_topic = "gshaptics/setpoint_pose";         ///< geometry_msgs/PoseStamped, out (admittance)
  std::string setpoint_twist_topic = "gshaptics/setpoint_twist";  ///< geometry_msgs/TwistStamped, out (admittance)
  /// ROS 2 readers (pose, twist): BEST_EFFORT by default, which matches reliable and best-effort
  /// writers alike (as ROS 2's sensor-data profile does); true asks for RELIABLE (then a
  /// best-effort driver cannot match: the mismatch is counted, see RosBridgeStats).
  bool reliable_input = false;
  /// ROS 2 writers (wrench, markers): RELIABLE keep-last `depth` by default, which serves
  /// reliable and best-effort subscribers alike (ROS 2 subscriptions are reliable by default);
  /// false writes BEST_EFFORT (a reliable subscriber then gets nothing: counted).
  bool reliable_output = true;
  int depth = 1;          ///< ROS 2 keep-last depth of the written streams (readers keep 64)
  double marker_hz = 30;  ///< MarkerArray rate
  std::size_t max_markers = 500;  ///< colliding Gaussians per MarkerArray (the rest are counted)
  /// No pose for this long: the device's data stops, s; the servo's watchdog zeroes the force
  /// SafetyParams::device_timeout later (0.09 + 0.01 = 0.1 s by default).
  double input_timeout = 0.09;
};

/// ROS 2 naming for a bridge without rcl: the node's namespace and name and the topic remappings
/// of a `--ros-args` command line (`-r`/`--remap` with `FROM:=TO`, `__ns:=/NS`, `__node:=NAME`),
/// resolved the way rcl resolves them: a relative name is put under the namespace, and a remap rule
/// applies when its FROM, resolved the same way, equals the resolved name.
struct Ros2Names {
  std::string ns = "/";  ///< absolute
  std::string node = "gshaptics_node";
  std::vector<std::pair<std::string, std::string>> remaps;  ///< resolved FROM -> resolved TO

  /// Parses `args` (empty, or starting with "--ros-args"); `node` is the default node name.
  /// Throws InputError naming an argument that is not a remap rule this bridge understands.
  [[nodiscard]] static Ros2Names parse(const std::vector<std::string>& args, const std::string& node);
  /// `name` resolved: absolute, remapped.
  [[nodiscard]] std::string resolve(const std::string& name) const;
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
  /// Poses whose header stamp was missing (zero) or not after the previous one: their velocity
  /// came from arrival times instead.
  std::atomic<std::uint64_t> stamp_fallbacks{0};
  /// Poses whose stamp step was impossible (more than 1 s off the arrival step): velocity from
  /// arrival times too.
  std::atomic<std::uint64_t> stamp_rejected{0};
  /// ROS 2: matches refused for incompatible QoS (offered by our writers + requested by our
  /// readers), and the DDS policy id of the last one (qos_policy_name() names it; 0: none).
  std::atomic<std::uint64_t> qos_incompatible{0};
  std::atomic<std::uint32_t> qos_last_policy{0};
};

/// A scene's rigid objects as the ROS side shows them (issue 72): their body-frame worlds (to place
/// their contacts), the channel their live poses come through, and each one's box for its marker.
struct RosObjects {
  std::vector<std::shared_ptr<const CollisionWorld>> bodies;
  std::shared_ptr<ObjectPoseChannel> poses;
  /// Each object's box: the extents of its hull points (m), centred on its body origin.
  std::vector<Eigen::Vector3d> sizes;
  [[nodiscard]] bool empty() const noexcept { return bodies.empty() || !poses; }
};

/// Object I's pose topic: `objects_topic`/objectI (a ROS name).
[[nodiscard]] inline std::string object_pose_topic(const std::string& objects_topic, std::size_t i) {
  return objects_topic + "/object" + std::to_string(i);
}

/// A device on a ROS network: the pose comes in, the wrench goes out, markers on the side.
class RosBridgeDevice : public HapticDevice {
 public:
  [[nodiscard]] virtual const RosBridgeStats& stats() const noexcept = 0;
  /// Starts publishing the tool and colliding Gaussians as MarkerArrays (own thread), and with
  /// `objects` each object's pose (PoseStamped) and box marker.
  virtual void start_markers(const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                             const Eigen::Vector3d& tool_axes, const RosObjects& objects) = 0;
  virtual void stop_markers() = 0;
  /// The full names of the pose, twist, wrench and markers topics on the wire.
  [[nodiscard]] virtual std::string wire_topic(const std::string& ros_name) const = 0;
  /// Why the middleware ended this node (ROS 1: the master shut it down), empty while it has not.
  /// A node that was shut down reports finished(), so the runtime ramps the force to zero and ends.
  [[nodiscard]] virtual std::string shutdown_reason() const { return {}; }
};

/// StreamDevice parameters of a network device: the newest pose as it is (inputs come at the
/// servo rate), and no data before the first pose arrives (nothing is rendered for a pose
/// nobody sent).
[[nodiscard]] inline StreamDeviceParams network_device_params(const std::string& name, double input_timeout) {
  StreamDeviceParams p;
  p.name = name;
  p.input_timeout = input_timeout;
  p.interpolate = false;
  p.alive_before_first_target = false;
  return p;
}

/// A pose's header stamp and when it arrived (ns on the bridge's clock; -1: none yet).
struct RosPoseArrival {
  RosTime stamp;
  Nanos arrival = -1;
};

/// The device side of a bridge's input, on the middleware's receive thread: validates a pose
/// (NaN/Inf dropped and counted; an all-zero quaternion, an unset field, taken as identity),
/// counts distinct publishers, pairs it with a recent twist and hands it to the StreamDevice.
/// Threading: on_pose()/on_twist() from one receive thread; newest_stamp() from the servo thread.
class RosPoseIntake {
 public:
  /// `fresh_for`: how long after its arrival a pose's stamp is echoed in the wrenches, s (the
  /// bridge's input timeout).
  RosPoseIntake(StreamDevice& input, Clock& clock, RosBridgeStats& stats, double fresh_for = 0.1)
      : input_(input), clock_(clock), stats_(stats), fresh_for_(to_nanos(fresh_for)) {}
  /// A twist (m/s, world); used with poses arriving within 50 ms of it.
  void on_twist(const Eigen::Vector3d& linear);
  /// A pose: position (m), orientation (x, y, z, w as in ROS), its header stamp, and a key that
  /// identifies its publisher. Without a fresh twist, the velocity is the pose's change over the
  /// change of its header stamps (the sender's clock, so transport jitter does not enter),
  /// smoothed by a first-order filter of time constant kVelocityTau; it falls back to arrival
  /// times when the stamp is zero, does not advance, or steps more than 1 s off the arrival
  /// step (each counted in the stats).
  void on_pose(const Eigen::Vector3d& position, const Eigen::Vector4d& orientation_xyzw,
               const RosTime& stamp, std::uint64_t publisher);
  /// Time constant of the velocity filter, s.
  static constexpr double kVelocityTau = 0.002;
  /// Servo thread: the stamp of the newest pose. Never blocks. Zero before the first pose.
  [[nodiscard]] const RosTime& newest_stamp() noexcept;
  /// Servo thread: the stamp for a wrench computed now. While poses are fresh (the newest
  /// arrived within `fresh_for` and carries a stamp) it is that pose's stamp, so a driver can
  /// pair the wrench with the pose it answers; otherwise (before the first pose, after the
  /// publisher stopped, for unstamped poses) the current ROS time, so the zero-force wrenches
  /// of the watchdog are never stale. Never zero. Never blocks.
  [[nodiscard]] RosTime wrench_stamp() noexcept;

 private:
  StreamDevice& input_;
  Clock& clock_;
  RosBridgeStats& stats_;
  std::vector<std::uint64_t> publishers_;
  Eigen::Vector3d twist_ = Eigen::Vector3d::Zero();
  Nanos twist_at_ = -1;
  Nanos fresh_for_;
  TripleBuffer<RosPoseArrival> stamps_;
  RosPoseArrival newest_;
  // Velocity estimate from stamps (reader thread only).
  bool have_prev_ = false;
  Eigen::Vector3d prev_position_ = Eigen::Vector3d::Zero(), velocity_ = Eigen::Vector3d::Zero();
  std::int64_t prev_stamp_ = 0;
  Nanos prev_arrival_ = 0;
};

/// A force/torque sensor reading and when it arrived (ns on the bridge's clock; -1: none yet).
struct RosSensorReading {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
  Nanos arrival = -1;
};

/// What the servo thread posts to the outbox: the tick's wrench, its echo stamp and, under
/// admittance control, the robot's setpoint.
struct RosOutboxItem {
  Wrench wrench;
  RosTime echo;
  Setpoint setpoint;
  bool has_setpoint = false;
};

/// The force/torque sensor's way in (admittance): the receive thread hands each reading over, the
/// servo thread takes the newest and whether it is fresh. Wait-free, no allocation.
class RosSensorIntake {
 public:
  explicit RosSensorIntake(Clock& clock) : clock_(clock) {}
  /// Receive thread: a reading, N and N m (world frame). Non-finite readings are dropped and counted.
  void on_wrench(const Eigen::Vector3d& force, const Eigen::Vector3d& torque = Eigen::Vector3d::Zero()) noexcept;
  /// Servo thread: the newest reading into `force` and `torque`; true when one arrived within
  /// `fresh_for` s.
  [[nodiscard]] bool newest(Eigen::Vector3d& force, Eigen::Vector3d& torque, double fresh_for) noexcept;
  /// Servo thread: the newest reading into the sample's user force and torque. The sensor is part
  /// of the device's data: while it is stale (no reading within `fresh_for` s) the sample's
  /// sequence stays at the last one seen while it was fresh (0 before any), so the watchdog
  /// brakes the robot as for a stale pose.
  void fill(DeviceSample& sample, double fresh_for) noexcept;
  /// Servo thread: forgets the sequence (at the device's start).
  void restart() noexcept { frozen_ = 0; }
  [[nodiscard]] std::uint64_t received() const noexcept { return received_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  Clock& clock_;
  TripleBuffer<RosSensorReading> readings_;
  RosSensorReading newest_;
  std::uint64_t frozen_ = 0;  // the sample's sequence when the sensor was last fresh
  std::atomic<std::uint64_t> received_{0}, dropped_{0};
};

/// The wrench's way out: the servo thread post()s (wait-free, no allocation; wakes the publisher
/// thread through a futex), a publisher thread calls `publish`. stop() publishes a zero wrench
/// last, so the device is left at zero force.
class RosWrenchOutbox {
 public:
  /// `setpoint`: the robot's setpoint posted with the wrench (admittance), null when none was.
  using PublishFn = std::function<void(const Wrench&, const Setpoint* setpoint, const RosTime& echo)>;
  RosWrenchOutbox(PublishFn publish, RosBridgeStats& stats) : publish_(std::move(publish)), stats_(stats) {}
  ~RosWrenchOutbox() { stop(); }
  void start();
  /// Posts the tick's wrench, and under admittance control the setpoint (null: none).
  void post(const Wrench& wrench, const RosTime& echo, const Setpoint* setpoint = nullptr) noexcept;
  /// Publishes the last message (zero wrench; the last setpoint with zero velocity) and ends.
  void stop();

 private:
  using Item = RosOutboxItem;
  PublishFn publish_;
  RosBridgeStats& stats_;
  TripleBuffer<Item> items_;
  std::atomic<std::uint32_t> signal_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// The tool ellipsoid and the colliding Gaussians of a snapshot as markers: DELETEALL first, then
/// the tool (ns "tool"), then one SPHERE per contact (ns "contacts", id = index into the original
/// scene file, scale = the k-sigma ellipsoid's diameters; an object's contact where the object is
/// now, one whose world is not in `worlds` left out), at most `max_contacts`, and last the
/// proxy (ns "proxy", a ghost of the tool) while the proxy force model holds the tool away from
/// the device's pose. Every added marker carries `lifetime` s (0: none).
[[nodiscard]] std::vector<RosMarker> contact_markers(const ContactSnapshot& snapshot, const SnapshotWorlds& worlds,
                                                     const Eigen::Vector3d& tool_axes,
                                                     std::size_t max_contacts, double lifetime = 0);
[[nodiscard]] inline std::vector<RosMarker> contact_markers(const ContactSnapshot& snapshot,
                                                            const CollisionWorld& world,
                                                            const Eigen::Vector3d& tool_axes,
                                                            std::size_t max_contacts, double lifetime = 0) {
  return contact_markers(snapshot, SnapshotWorlds{&world, {}, nullptr}, tool_axes, max_contacts, lifetime);
}

/// Each object as a CUBE marker (ns "objects", id I) at its pose, `sizes[I]` its extents, with
/// `lifetime` s. Objects without a size are left out.
[[nodiscard]] std::vector<RosMarker> object_markers(const ObjectPoses& poses, std::span<const Eigen::Vector3d> sizes,
                                                    double lifetime = 0);

/// Publishes contact_markers() of the newest snapshot at `hz` from its own thread, every period
/// whether or not the snapshot is new (each marker lives three periods, so a node that dies leaves
/// nothing behind). When no new snapshot arrived for `stale_after` s (at least 2.5 periods; the
/// poses stopped: the
/// watchdog zeroed the force), it publishes a lone DELETEALL instead, and once more at stop().
/// With objects, every period also hands the objects' newest poses to `publish_poses` (once the
/// first has arrived) and adds their markers (object_markers) after the contacts'.
class RosMarkerLoop {
 public:
  using PublishFn = std::function<void(const std::vector<RosMarker>&)>;
  using PublishPosesFn = std::function<void(const ObjectPoses&)>;
  /// Throws InputError when the objects' channel has no reader slot left.
  RosMarkerLoop(PublishFn publish, const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                const Eigen::Vector3d& tool_axes, double hz, std::size_t max_contacts, RosBridgeStats& stats,
                double stale_after = 0.1, RosObjects objects = {}, PublishPosesFn publish_poses = {});
  ~RosMarkerLoop() { stop(); }
  void start();
  void stop();

 private:
  PublishFn publish_;
  const CollisionWorld& world_;
  ContactSnapshotObserver& snapshots_;
  Eigen::Vector3d tool_axes_;
  double hz_;
  std::size_t max_;
  RosBridgeStats& stats_;
  double stale_after_;
  RosObjects objects_;
  PublishPosesFn publish_poses_;
  int pose_reader_ = -1;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace gshaptics
