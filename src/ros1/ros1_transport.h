#pragma once
// The roscpp side of the ROS 1 bridge, behind plain types. Debian's ROS 1 message headers need
// std::allocator<void>::rebind, which C++20 removed, so this file and ros1_transport.cpp build
// as C++17 and include nothing of gshaptics (whose headers are C++20). Not a public header.

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gshaptics/net/ros_marker.h"

namespace gshaptics::ros1 {

struct PoseIn {
  std::array<double, 3> position{};
  std::array<double, 4> orientation_xyzw{};
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
  std::string publisher;  ///< caller id of the publishing node
};

struct TransportOptions {
  std::string node_name, pose_topic, twist_topic, wrench_topic, markers_topic, frame_id;
  /// Admittance: the force/torque sensor in (WrenchStamped), the setpoint out (PoseStamped,
  /// TwistStamped). Empty sensor_topic: not an admittance node.
  std::string sensor_topic, setpoint_topic, setpoint_twist_topic;
  std::vector<std::string> remappings;  ///< `from:=to`, `__name:=`, `__ns:=` as on a ROS 1 command line
  double master_timeout = 10;
};

class Transport {
 public:
  /// Initialises roscpp (once per process, without its SIGINT handler; with the remappings as its
  /// command line), waits for the master,
  /// subscribes and advertises; callbacks run on an AsyncSpinner thread. Throws
  /// std::runtime_error with a message naming the master when none answers.
  /// `on_sensor` (admittance, may be empty otherwise): the sensor's force (N) and torque (N m).
  Transport(const TransportOptions& options, std::function<void(const PoseIn&)> on_pose,
            std::function<void(const std::array<double, 3>&)> on_twist,
            std::function<void(const std::array<double, 3>&, const std::array<double, 3>&)> on_sensor = {});
  ~Transport();
  void publish_wrench(const std::array<double, 3>& force, const std::array<double, 3>& torque,
                      std::int32_t sec, std::uint32_t nanosec);
  void publish_markers(const std::vector<RosMarker>& markers);
  /// Advertises one geometry_msgs/PoseStamped topic per name (the objects' poses, issue 72);
  /// publish_object_pose(i, ...) then writes topic i, stamped now.
  void advertise_object_poses(const std::vector<std::string>& topics);
  void publish_object_pose(std::size_t i, const std::array<double, 3>& position,
                           const std::array<double, 4>& orientation_xyzw);
  /// Admittance: the setpoint, m, x y z w, m/s and rad/s, stamped.
  void publish_setpoint(const std::array<double, 3>& position, const std::array<double, 4>& orientation_xyzw,
                        const std::array<double, 3>& velocity, const std::array<double, 3>& angular,
                        std::int32_t sec, std::uint32_t nanosec);
  /// `name` resolved in the node's namespace, remappings applied (what the master lists).
  [[nodiscard]] std::string resolve(const std::string& name) const;
  /// The node's full name (/namespace/name).
  [[nodiscard]] std::string node_name() const;
  /// False once roscpp has shut down (the master asked: rosnode kill, or a node of the same name).
  [[nodiscard]] static bool ok() noexcept;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace gshaptics::ros1
