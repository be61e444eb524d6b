#include "ros1_transport.h"

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TwistStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <chrono>
#include <stdexcept>
#include <thread>

namespace gshaptics::ros1 {

struct Transport::State {
  TransportOptions options;
  std::function<void(const PoseIn&)> on_pose;
  std::function<void(const std::array<double, 3>&)> on_twist;
  std::function<void(const std::array<double, 3>&, const std::array<double, 3>&)> on_sensor;
  std::unique_ptr<ros::NodeHandle> nh;
  ros::Subscriber pose_sub, twist_sub, sensor_sub;
  ros::Publisher wrench_pub, marker_pub, setpoint_pub, setpoint_twist_pub;
  std::vector<ros::Publisher> object_pubs;
  geometry_msgs::PoseStamped object_pose;
  geometry_msgs::PoseStamped setpoint;
  geometry_msgs::TwistStamped setpoint_twist;
  std::unique_ptr<ros::AsyncSpinner> spinner;
  geometry_msgs::WrenchStamped wrench;

  void pose_cb(const ros::MessageEvent<geometry_msgs::PoseStamped const>& ev) {
    const geometry_msgs::PoseStamped& m = *ev.getMessage();
    PoseIn p;
    p.position = {m.pose.position.x, m.pose.position.y, m.pose.position.z};
    p.orientation_xyzw = {m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z, m.pose.orientation.w};
    p.sec = std::int32_t(m.header.stamp.sec);
    p.nanosec = m.header.stamp.nsec;
    p.publisher = ev.getPublisherName();
    on_pose(p);
  }
  void twist_cb(const geometry_msgs::TwistStamped::ConstPtr& m) {
    on_twist({m->twist.linear.x, m->twist.linear.y, m->twist.linear.z});
  }
  void sensor_cb(const geometry_msgs::WrenchStamped::ConstPtr& m) {
    on_sensor({m->wrench.force.x, m->wrench.force.y, m->wrench.force.z},
              {m->wrench.torque.x, m->wrench.torque.y, m->wrench.torque.z});
  }
};

Transport::Transport(const TransportOptions& o, std::function<void(const PoseIn&)> on_pose,
                     std::function<void(const std::array<double, 3>&)> on_twist,
                     std::function<void(const std::array<double, 3>&, const std::array<double, 3>&)> on_sensor)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.options = o;
  s.on_pose = std::move(on_pose);
  s.on_twist = std::move(on_twist);
  s.on_sensor = std::move(on_sensor);
  if (!ros::isInitialized()) {
    // roscpp reads remappings, __name and __ns from its command line (and ROS_NAMESPACE).
    std::vector<std::string> args{"gshaptics"};
    args.insert(args.end(), o.remappings.begin(), o.remappings.end());
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    int argc = int(argv.size());
    ros::init(argc, argv.data(), o.node_name, ros::init_options::NoSigintHandler);
    if (argc > 1)
      throw std::runtime_error("ROS 1: not a remapping: '" + std::string(argv[1]) + "' (expected from:=to)");
  }
  const auto t0 = std::chrono::steady_clock::now();
  while (!ros::master::check()) {
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > o.master_timeout)
      throw std::runtime_error("ROS 1: no master at " + ros::master::getURI() +
                               " (start roscore, or set ROS_MASTER_URI)");
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  s.nh = std::make_unique<ros::NodeHandle>();
  s.pose_sub = s.nh->subscribe(o.pose_topic, 64, &State::pose_cb, &s,
                                                            ros::TransportHints().tcpNoDelay());
  s.twist_sub = s.nh->subscribe<geometry_msgs::TwistStamped>(o.twist_topic, 64, &State::twist_cb, &s,
                                                              ros::TransportHints().tcpNoDelay());
  s.wrench_pub = s.nh->advertise<geometry_msgs::WrenchStamped>(o.wrench_topic, 64);
  s.marker_pub = s.nh->advertise<visualization_msgs::MarkerArray>(o.markers_topic, 2);
  s.wrench.header.frame_id = o.frame_id;
  if (!o.sensor_topic.empty()) {
    s.sensor_sub = s.nh->subscribe<geometry_msgs::WrenchStamped>(o.sensor_topic, 64, &State::sensor_cb, &s,
                                                                  ros::TransportHints().tcpNoDelay());
    s.setpoint_pub = s.nh->advertise<geometry_msgs::PoseStamped>(o.setpoint_topic, 64);
    s.setpoint_twist_pub = s.nh->advertise<geometry_msgs::TwistStamped>(o.setpoint_twist_topic, 64);
    s.setpoint.header.frame_id = o.frame_id;
    s.setpoint.pose.orientation.w = 1;
    s.setpoint_twist.header.frame_id = o.frame_id;
  }
  s.spinner = std::make_unique<ros::AsyncSpinner>(1);
  s.spinner->start();
  // One log line through roscpp now, while this node is the one registered under its name. The
  // first ROS_* line makes roscpp's rosout appender subscribe a cached parameter at the master
  // with the node's name and URI; a node that first logs when it is shut down (roscpp's
  // "Shutdown request received") re-registers under its name as it goes, and the master then
  // shuts down the node that replaced it (ros/ros_comm#2018), leaving none.
  ROS_INFO("gshaptics node %s: poses on %s, wrench on %s", ros::this_node::getName().c_str(),
           ros::names::resolve(o.pose_topic).c_str(), ros::names::resolve(o.wrench_topic).c_str());
}

Transport::~Transport() {
  if (state_->spinner) state_->spinner->stop();
  state_->pose_sub.shutdown();
  state_->twist_sub.shutdown();
  state_->sensor_sub.shutdown();
}

void Transport::publish_setpoint(const std::array<double, 3>& p, const std::array<double, 4>& q,
                                 const std::array<double, 3>& v, const std::array<double, 3>& w, std::int32_t sec,
                                 std::uint32_t nanosec) {
  State& s = *state_;
  if (s.options.sensor_topic.empty()) return;
  const ros::Time stamp(std::uint32_t(sec), nanosec);
  s.setpoint_twist.header.stamp = stamp;
  s.setpoint_twist.twist.linear.x = v[0], s.setpoint_twist.twist.linear.y = v[1], s.setpoint_twist.twist.linear.z = v[2];
  s.setpoint_twist.twist.angular.x = w[0], s.setpoint_twist.twist.angular.y = w[1], s.setpoint_twist.twist.angular.z = w[2];
  s.setpoint_twist_pub.publish(s.setpoint_twist);
  s.setpoint.header.stamp = stamp;
  s.setpoint.pose.position.x = p[0], s.setpoint.pose.position.y = p[1], s.setpoint.pose.position.z = p[2];
  s.setpoint.pose.orientation.x = q[0], s.setpoint.pose.orientation.y = q[1];
  s.setpoint.pose.orientation.z = q[2], s.setpoint.pose.orientation.w = q[3];
  s.setpoint_pub.publish(s.setpoint);
}

std::string Transport::resolve(const std::string& name) const { return ros::names::resolve(name); }

std::string Transport::node_name() const { return ros::this_node::getName(); }

bool Transport::ok() noexcept { return ros::ok() && !ros::isShuttingDown(); }

void Transport::publish_wrench(const std::array<double, 3>& f, const std::array<double, 3>& t, std::int32_t sec,
                               std::uint32_t nanosec) {
  geometry_msgs::WrenchStamped& m = state_->wrench;
  m.header.stamp = ros::Time(std::uint32_t(sec), nanosec);
  m.wrench.force.x = f[0], m.wrench.force.y = f[1], m.wrench.force.z = f[2];
  m.wrench.torque.x = t[0], m.wrench.torque.y = t[1], m.wrench.torque.z = t[2];
  state_->wrench_pub.publish(m);
}

void Transport::publish_markers(const std::vector<RosMarker>& markers) {
  visualization_msgs::MarkerArray arr;
  const ros::Time now = ros::Time::now();
  arr.markers.resize(markers.size());
  for (std::size_t i = 0; i < markers.size(); ++i) {
    const RosMarker& in = markers[i];
    visualization_msgs::Marker& m = arr.markers[i];
    m.header.frame_id = state_->options.frame_id;
    m.header.stamp = now;
    m.ns = in.ns;
    m.id = in.id;
    m.type = in.type;
    m.action = in.action;
    m.pose.position.x = in.position[0], m.pose.position.y = in.position[1], m.pose.position.z = in.position[2];
    m.pose.orientation.x = in.orientation_xyzw[0], m.pose.orientation.y = in.orientation_xyzw[1];
    m.pose.orientation.z = in.orientation_xyzw[2], m.pose.orientation.w = in.orientation_xyzw[3];
    m.scale.x = in.scale[0], m.scale.y = in.scale[1], m.scale.z = in.scale[2];
    m.color.r = in.rgba[0], m.color.g = in.rgba[1], m.color.b = in.rgba[2], m.color.a = in.rgba[3];
    m.lifetime = ros::Duration(in.lifetime);
  }
  state_->marker_pub.publish(arr);
}

void Transport::advertise_object_poses(const std::vector<std::string>& topics) {
  for (const std::string& t : topics) state_->object_pubs.push_back(state_->nh->advertise<geometry_msgs::PoseStamped>(t, 8));
  state_->object_pose.header.frame_id = state_->options.frame_id;
}

void Transport::publish_object_pose(std::size_t i, const std::array<double, 3>& p, const std::array<double, 4>& q) {
  if (i >= state_->object_pubs.size()) return;
  geometry_msgs::PoseStamped& m = state_->object_pose;
  m.header.stamp = ros::Time::now();
  m.pose.position.x = p[0], m.pose.position.y = p[1], m.pose.position.z = p[2];
  m.pose.orientation.x = q[0], m.pose.orientation.y = q[1], m.pose.orientation.z = q[2], m.pose.orientation.w = q[3];
  state_->object_pubs[i].publish(m);
}

}  // namespace gshaptics::ros1
