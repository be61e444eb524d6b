#pragma once
/// @file
/// ROS 1 (Debian's roscpp, no catkin) for labs still on ROS 1, as the paper's setup likely is:
/// the same topics as the ROS 2 bridge. geometry_msgs/PoseStamped (and optional TwistStamped) in,
/// geometry_msgs/WrenchStamped out at the servo rate with the pose's stamp echoed,
/// visualization_msgs/MarkerArray of the tool and the colliding Gaussians.
///
/// Threading contract: roscpp callbacks run on an AsyncSpinner thread, never on the servo
/// thread; poses reach the servo thread through a triple buffer (StreamDevice), wrenches leave it
/// the same way to a publisher thread (woken by a futex, no lock). A second publisher on the pose
/// topic: both streams interleave and the newest sample wins; publishers are counted.

#include <memory>
#include <string>

#include "gshaptics/net/ros_bridge.h"
#include "gshaptics/device/clock.h"
#include "gshaptics/device/stream_device.h"

namespace gshaptics {

struct Ros1Impl;

class Ros1NetworkDevice final : public RosBridgeDevice {
 public:
  /// Initialises roscpp once per process as `node_name` (empty: options.node_name), with
  /// options.ros_args as its remappings (without its SIGINT handler), and waits up to
  /// `master_timeout` s for the master at ROS_MASTER_URI; throws InputError when none answers or
  /// an argument is not a remapping.
  Ros1NetworkDevice(const RosBridgeOptions& options, Clock& clock, const std::string& node_name = {},
                    double master_timeout = 10);
  ~Ros1NetworkDevice() override;
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos now) override;
  /// The newest pose; under admittance (RosBridgeOptions::admittance) with the sensor's newest
  /// reading as the user force, and no new data while the sensor is stale.
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  /// Admittance: published with the tick's wrench on the setpoint topics (PoseStamped, TwistStamped).
  void write_setpoint(const Setpoint& setpoint, Nanos now) noexcept override;
  void stop(Nanos now) noexcept override;
  /// True once roscpp has shut down (the master asked this node to end).
  [[nodiscard]] bool finished() const noexcept override;
  [[nodiscard]] const RosBridgeStats& stats() const noexcept override;
  void start_markers(const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                     const Eigen::Vector3d& tool_axes, const RosObjects& objects) override;
  void stop_markers() override;
  [[nodiscard]] std::string wire_topic(const std::string& ros_name) const override;
  [[nodiscard]] std::string shutdown_reason() const override;

 private:
  StreamDevice input_;
  std::unique_ptr<Ros1Impl> impl_;
  DeviceInfo info_;
  Setpoint setpoint_;  // servo thread
  bool has_setpoint_ = false;
};

}  // namespace gshaptics
