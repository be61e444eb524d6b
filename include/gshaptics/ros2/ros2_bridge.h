#pragma once
/// @file
/// ROS 2 over DDS (Eclipse Cyclone DDS, C API) in the ROS 2 wire format, so `ros2 topic echo`
/// with rmw_cyclonedds_cpp sees our topics: DDS topic "rt/<name>", type names
/// "<pkg>::msg::dds_::<Msg>_", XCDR1, message layouts of ROS 2 Humble
/// (src/ros2/idl/ros2_interfaces.idl cites the definitions followed).
///
/// - Ros2NetworkDevice: a HapticDevice whose pose arrives as geometry_msgs/PoseStamped (and,
///   optionally, geometry_msgs/TwistStamped) and whose wrench goes out as
///   geometry_msgs/WrenchStamped at the servo rate. The paper's split (Sec. IV): the servo loop
///   on one machine, the device on another.
/// - Ros2MarkerPublisher: the tool ellipsoid and the colliding Gaussians as a
///   visualization_msgs/MarkerArray at a display rate, for a renderer on another machine.
///
/// Threading contract: DDS work never runs on the servo thread. The device's reader thread
/// takes poses and hands the newest to the servo thread through a triple buffer
/// (StreamDevice); the servo thread's write() hands the wrench to a publisher thread the same
/// way and wakes it (futex, no lock). Markers are published from their own thread.
/// A second publisher on the pose topic: samples from both are taken in arrival order and the
/// newest wins (the tool jumps between them); it is counted (pose_publishers()) and reported.

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "gshaptics/net/ros_bridge.h"
#include "gshaptics/net/contact_snapshot.h"
#include "gshaptics/device/stream_device.h"

namespace gshaptics {

using Ros2Options = RosBridgeOptions;
using Ros2Stats = RosBridgeStats;

/// "rt/" + the name without a leading '/'.
[[nodiscard]] std::string ros2_dds_topic(const std::string& ros_name);

/// The DDS topic ROS 2 tools learn the graph from (rmw_dds_common): no "rt/" prefix.
inline constexpr const char* kRos2DiscoveryTopic = "ros_discovery_info";
/// Publishes, on `participant` (a dds_entity_t), the rmw_dds_common ParticipantEntitiesInfo that
/// says it hosts node `node` in namespace `ns` (absolute) with these readers and writers (their
/// GIDs: the DDS GUIDs, zero padded to 24 octets as in Humble), reliable and transient local with
/// keep-last 1 as rmw_cyclonedds_cpp writes it, so `ros2 node list` shows the node. Throws
/// InputError when DDS refuses.
void publish_discovery_info(std::int32_t participant, const std::string& ns, const std::string& node,
                            const std::vector<std::int32_t>& readers, const std::vector<std::int32_t>& writers);

struct Ros2Impl;

/// The network device (see file comment). Throws InputError when DDS cannot start.
class Ros2MarkerPublisher;

class Ros2NetworkDevice final : public RosBridgeDevice {
 public:
  /// Topics resolve in the namespace and through the remap rules of options.ros_args
  /// (`--ros-args -r ...`, Ros2Names). Throws InputError for an argument it does not understand.
  Ros2NetworkDevice(const Ros2Options& options, Clock& clock);
  ~Ros2NetworkDevice() override;
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos now) override;
  /// The newest pose; under admittance (RosBridgeOptions::admittance) with the sensor's newest
  /// reading as the user force, and no new data while the sensor is stale.
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  /// Admittance: published with the tick's wrench on the setpoint topics (PoseStamped, TwistStamped).
  void write_setpoint(const Setpoint& setpoint, Nanos now) noexcept override;
  void stop(Nanos now) noexcept override;
  [[nodiscard]] const RosBridgeStats& stats() const noexcept override;
  void start_markers(const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                     const Eigen::Vector3d& tool_axes, const RosObjects& objects) override;
  void stop_markers() override;
  [[nodiscard]] std::string wire_topic(const std::string& ros_name) const override {
    return ros2_dds_topic(names_.resolve(ros_name));
  }
  /// The DDS participant (for a marker publisher sharing it).
  [[nodiscard]] Ros2Impl& impl() noexcept { return *impl_; }

 private:
  Ros2Names names_;
  StreamDevice input_;
  std::unique_ptr<Ros2Impl> impl_;
  DeviceInfo info_;
  Setpoint setpoint_;  // servo thread
  bool has_setpoint_ = false;
  std::unique_ptr<Ros2MarkerPublisher> markers_;
};

/// The name of a DDS QoS policy id (RosBridgeStats::qos_last_policy), e.g. "RELIABILITY".
[[nodiscard]] std::string ros2_qos_policy_name(std::uint32_t id);

/// Publishes MarkerArrays (tool ellipsoid + colliding Gaussians, and the objects' boxes) from
/// contact snapshots, and the objects' poses.
class Ros2MarkerPublisher {
 public:
  /// Uses the device's participant; `tool_axes` are the tool's semi-axes, m. With `objects`, also
  /// writes each object's PoseStamped (object_pose_topic) at the marker rate.
  Ros2MarkerPublisher(Ros2NetworkDevice& device, const CollisionWorld& world,
                      ContactSnapshotObserver& snapshots, const Eigen::Vector3d& tool_axes,
                      const RosObjects& objects = {});
  ~Ros2MarkerPublisher();
  void start();
  void stop();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace gshaptics

namespace gshaptics {

/// The device side of the split (`gshaptics device-sim --ros2`, or a driver next to the
/// hardware): publishes the device's pose and twist, receives the wrench. Single-threaded: call
/// from one thread. Throws InputError when DDS cannot start.
class Ros2DeviceLink {
 public:
  explicit Ros2DeviceLink(const Ros2Options& options);
  ~Ros2DeviceLink();
  Ros2DeviceLink(const Ros2DeviceLink&) = delete;
  Ros2DeviceLink& operator=(const Ros2DeviceLink&) = delete;
  /// Waits until the pose writer and the wrench reader are matched with a node (or the timeout,
  /// s, passes); returns whether they are.
  bool wait_for_node(double timeout_s);
  /// Publishes PoseStamped (and TwistStamped) stamped `stamp`. World frame, m, m/s.
  void publish(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
               const Eigen::Vector3d& velocity, const RosTime& stamp);
  /// Takes the newest wrench since the last call; `echo` is its header stamp (the stamp of the
  /// pose the node had read when it computed it). False when none arrived.
  bool take_wrench(Eigen::Vector3d& force, RosTime& echo);
  /// Admittance (options.admittance): publishes the force/torque sensor's reading (WrenchStamped
  /// on the sensor topic; N and N m, world frame).
  void publish_sensor(const Eigen::Vector3d& force, const Eigen::Vector3d& torque, const RosTime& stamp);
  /// Admittance: takes the newest setpoint (PoseStamped position, TwistStamped linear velocity)
  /// since the last call. False when none arrived.
  bool take_setpoint(Setpoint& setpoint);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace gshaptics
