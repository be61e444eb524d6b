#include "gshaptics/ros1/ros1_bridge.h"

#include <functional>
#include <stdexcept>

#include "gshaptics/error.h"
#include "ros1_transport.h"

namespace gshaptics {

struct Ros1Impl {
  RosBridgeOptions options;
  RosBridgeStats stats;
  RosPoseIntake intake;
  RosSensorIntake sensor;
  std::unique_ptr<ros1::Transport> transport;
  RosWrenchOutbox outbox;
  std::unique_ptr<RosMarkerLoop> markers;

  Ros1Impl(const RosBridgeOptions& o, Clock& c, StreamDevice& in)
      : options(o), intake(in, c, stats, o.input_timeout), sensor(c),
        outbox([this](const Wrench& w, const Setpoint* sp, const RosTime& echo) {
          // The setpoint first: a robot's position controller gets it as soon as it exists.
          if (sp != nullptr)
            transport->publish_setpoint(
                {sp->position.x(), sp->position.y(), sp->position.z()},
                {sp->orientation.x(), sp->orientation.y(), sp->orientation.z(), sp->orientation.w()},
                {sp->velocity.x(), sp->velocity.y(), sp->velocity.z()},
                {sp->angular_velocity.x(), sp->angular_velocity.y(), sp->angular_velocity.z()}, echo.sec, echo.nanosec);
          transport->publish_wrench({w.force.x(), w.force.y(), w.force.z()}, {w.torque.x(), w.torque.y(), w.torque.z()},
                                    echo.sec, echo.nanosec);
        }, stats) {}
};

Ros1NetworkDevice::Ros1NetworkDevice(const RosBridgeOptions& options, Clock& clock, const std::string& node_name,
                                     double master_timeout)
    : input_(network_device_params("ros1 (" + options.pose_topic + ")", options.input_timeout),
             Eigen::Vector3d::Zero()),
      impl_(std::make_unique<Ros1Impl>(options, clock, input_)) {
  info_ = input_.info();
  ros1::TransportOptions t;
  if (options.admittance) {
    info_.admittance = true;
    info_.name = "ros1 robot (" + options.pose_topic + ", sensor " + options.sensor_topic + ")";
    t.sensor_topic = options.sensor_topic;
    t.setpoint_topic = options.setpoint_topic;
    t.setpoint_twist_topic = options.setpoint_twist_topic;
  }
  t.node_name = node_name.empty() ? options.node_name : node_name;
  t.remappings = options.ros_args;
  // Relative names stay relative: roscpp resolves them in the node's namespace.
  t.pose_topic = options.pose_topic;
  t.twist_topic = options.twist_topic;
  t.wrench_topic = options.wrench_topic;
  t.markers_topic = options.markers_topic;
  t.frame_id = options.frame_id;
  t.master_timeout = master_timeout;
  Ros1Impl& m = *impl_;
  try {
    m.transport = std::make_unique<ros1::Transport>(
        t,
        [&m](const ros1::PoseIn& p) {
          m.intake.on_pose({p.position[0], p.position[1], p.position[2]},
                           {p.orientation_xyzw[0], p.orientation_xyzw[1], p.orientation_xyzw[2], p.orientation_xyzw[3]},
                           {p.sec, p.nanosec}, std::hash<std::string>{}(p.publisher));
        },
        [&m](const std::array<double, 3>& v) { m.intake.on_twist({v[0], v[1], v[2]}); },
        [&m](const std::array<double, 3>& f, const std::array<double, 3>& tau) {
          m.sensor.on_wrench({f[0], f[1], f[2]}, {tau[0], tau[1], tau[2]});
        });
  } catch (const std::runtime_error& e) {
    throw InputError(e.what());
  }
}

Ros1NetworkDevice::~Ros1NetworkDevice() {
  stop_markers();
  impl_->outbox.stop();
  impl_->transport.reset();
}

void Ros1NetworkDevice::start(Nanos now) {
  input_.start(now);
  has_setpoint_ = false;
  impl_->sensor.restart();
  impl_->outbox.start();
}

DeviceSample Ros1NetworkDevice::read(Nanos now) noexcept {
  DeviceSample s = input_.read(now);
  if (!info_.admittance) return s;
  // As the ROS 2 bridge: a stale sensor stops the device's data as a stale pose does.
  impl_->sensor.fill(s, impl_->options.input_timeout);
  return s;
}

void Ros1NetworkDevice::write_setpoint(const Setpoint& setpoint, Nanos now) noexcept {
  (void)now;
  setpoint_ = setpoint;
  has_setpoint_ = true;
}

void Ros1NetworkDevice::write(const Wrench& wrench, Nanos now) noexcept {
  input_.write(wrench, now);
  impl_->outbox.post(wrench, impl_->intake.wrench_stamp(), info_.admittance && has_setpoint_ ? &setpoint_ : nullptr);
}

void Ros1NetworkDevice::stop(Nanos now) noexcept {
  input_.stop(now);
  impl_->outbox.stop();  // publishes a zero wrench as its last message
}

const RosBridgeStats& Ros1NetworkDevice::stats() const noexcept { return impl_->stats; }

void Ros1NetworkDevice::start_markers(const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                                      const Eigen::Vector3d& tool_axes, const RosObjects& objects) {
  Ros1Impl& m = *impl_;
  if (!objects.empty()) {
    std::vector<std::string> topics;
    for (std::size_t i = 0; i < objects.bodies.size(); ++i) topics.push_back(object_pose_topic(m.options.objects_topic, i));
    m.transport->advertise_object_poses(topics);
  }
  m.markers = std::make_unique<RosMarkerLoop>(
      [&m](const std::vector<RosMarker>& markers) { m.transport->publish_markers(markers); }, world, snapshots,
      tool_axes, m.options.marker_hz, m.options.max_markers, m.stats, m.options.input_timeout + 0.01, objects,
      [&m](const ObjectPoses& poses) {
        for (std::size_t i = 0; i < poses.count; ++i) {
          const BodyPose& p = poses.poses[i];
          m.transport->publish_object_pose(i, {p.position.x(), p.position.y(), p.position.z()},
                                           {p.rotation.x(), p.rotation.y(), p.rotation.z(), p.rotation.w()});
        }
      });
  m.markers->start();
}

void Ros1NetworkDevice::stop_markers() {
  if (impl_->markers) impl_->markers->stop();
}

std::string Ros1NetworkDevice::wire_topic(const std::string& ros_name) const {
  return impl_->transport ? impl_->transport->resolve(ros_name) : ros_name;
}

bool Ros1NetworkDevice::finished() const noexcept { return !ros1::Transport::ok(); }

std::string Ros1NetworkDevice::shutdown_reason() const {
  if (ros1::Transport::ok()) return {};
  return "the ROS master shut this node down (rosnode kill, or another node registered as " +
         impl_->transport->node_name() + ")";
}

}  // namespace gshaptics
