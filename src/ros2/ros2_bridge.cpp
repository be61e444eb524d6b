#include "gshaptics/ros2/ros2_bridge.h"

#include <dds/dds.h>

#include <algorithm>
#include <chrono>
#include <initializer_list>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <vector>

#include "gshaptics/error.h"
#include "ros2_interfaces.h"

namespace gshaptics {

namespace {

char* cstr(const std::string& s) { return const_cast<char*>(s.c_str()); }
char kEmpty[] = "";

std::string dds_error(const std::string& what, dds_return_t rc) {
  return "ROS 2 / DDS: " + what + " failed: " + dds_strretcode(rc) +
         " (is the DDS configuration in CYCLONEDDS_URI valid?)";
}

dds_entity_t check(dds_entity_t e, const std::string& what) {
  if (e < 0) throw InputError(dds_error(what, e));
  return e;
}

/// QoS of the streams: best-effort or reliable, keep-last depth, XCDR1 (as rmw_cyclonedds).
dds_qos_t* stream_qos(bool reliable, int depth) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT, DDS_MSECS(100));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, std::max(1, depth));
  const dds_data_representation_id_t rep[] = {DDS_DATA_REPRESENTATION_XCDR1};
  dds_qset_data_representation(q, 1, rep);
  return q;
}

struct Qos {
  dds_qos_t* q;
  explicit Qos(dds_qos_t* x) : q(x) {}
  ~Qos() { dds_delete_qos(q); }
};

void fill_header(std_msgs_msg_dds__Header_& h, const RosTime& t, const std::string& frame) {
  h.stamp.sec = t.sec;
  h.stamp.nanosec = t.nanosec;
  h.frame_id = cstr(frame);
}

struct Endpoint {
  dds_entity_t topic = 0, entity = 0;
};

Endpoint make_reader(dds_entity_t pp, const dds_topic_descriptor_t* desc, const std::string& name, const Ros2Options& o) {
  Endpoint e;
  e.topic = check(dds_create_topic(pp, desc, ros2_dds_topic(name).c_str(), nullptr, nullptr), "topic " + name);
  // Readers keep a burst (64 samples) so that nothing arriving between two takes is
  // overwritten; the samples are applied in order and the newest wins. Best-effort by default:
  // it matches reliable and best-effort writers.
  Qos q(stream_qos(o.reliable_input, std::max(o.depth, 64)));
  e.entity = check(dds_create_reader(pp, e.topic, q.q, nullptr), "reader on " + name);
  return e;
}

Endpoint make_writer(dds_entity_t pp, const dds_topic_descriptor_t* desc, const std::string& name, const Ros2Options& o) {
  Endpoint e;
  e.topic = check(dds_create_topic(pp, desc, ros2_dds_topic(name).c_str(), nullptr, nullptr), "topic " + name);
  // Reliable keep-last by default: it serves reliable and best-effort readers alike.
  Qos q(stream_qos(o.reliable_output, o.depth));
  e.entity = check(dds_create_writer(pp, e.topic, q.q, nullptr), "writer on " + name);
  return e;
}

// Before a participant goes: waits, at most kAckWait in all, until the matched readers have
// acknowledged what `writers` wrote (Cyclone DDS's dds_wait_for_acks; a reliable writer deleted
// with samples unacknowledged drops them, so a node's last wrench and setpoint at rest, or a
// device's last poses, would not arrive). Best-effort writers and writers never created (entity
// 0) return at once.
constexpr dds_duration_t kAckWait = DDS_MSECS(500);
void wait_for_acks(std::initializer_list<const Endpoint*> writers) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::nanoseconds(kAckWait);
  for (const Endpoint* w : writers) {
    const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(end - std::chrono::steady_clock::now());
    if (w->entity > 0 && left.count() > 0) (void)dds_wait_for_acks(w->entity, dds_duration_t(left.count()));
  }
}

// An entity's DDS GUID as a ROS 2 GID (Humble: 24 octets, the GUID's 16 then zeros), as
// rmw_cyclonedds converts it.
rmw_dds_common_msg_dds__Gid_ gid_of(dds_entity_t e) {
  rmw_dds_common_msg_dds__Gid_ g{};
  dds_guid_t guid{};
  if (dds_get_guid(e, &guid) == DDS_RETCODE_OK) std::memcpy(g.data, guid.v, sizeof guid.v);
  return g;
}

}  // namespace

void publish_discovery_info(dds_entity_t participant, const std::string& ns, const std::string& node,
                            const std::vector<dds_entity_t>& readers, const std::vector<dds_entity_t>& writers) {
  const dds_entity_t topic = check(
      dds_create_topic(participant, &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc, kRos2DiscoveryTopic,
                       nullptr, nullptr), "topic ros_discovery_info");
  Qos q(stream_qos(true, 1));
  dds_qset_durability(q.q, DDS_DURABILITY_TRANSIENT_LOCAL);
  const dds_entity_t writer = check(dds_create_writer(participant, topic, q.q, nullptr), "writer on ros_discovery_info");
  std::vector<rmw_dds_common_msg_dds__Gid_> reader_gids, writer_gids;
  for (dds_entity_t r : readers) reader_gids.push_back(gid_of(r));
  for (dds_entity_t w : writers) writer_gids.push_back(gid_of(w));
  rmw_dds_common_msg_dds__NodeEntitiesInfo_ info{};
  std::snprintf(info.node_namespace, sizeof info.node_namespace, "%s", ns.c_str());
  std::snprintf(info.node_name, sizeof info.node_name, "%s", node.c_str());
  info.reader_gid_seq._length = info.reader_gid_seq._maximum = std::uint32_t(reader_gids.size());
  info.reader_gid_seq._buffer = reader_gids.data();
  info.writer_gid_seq._length = info.writer_gid_seq._maximum = std::uint32_t(writer_gids.size());
  info.writer_gid_seq._buffer = writer_gids.data();
  rmw_dds_common_msg_dds__ParticipantEntitiesInfo_ msg{};
  msg.gid = gid_of(participant);
  msg.node_entities_info_seq._length = msg.node_entities_info_seq._maximum = 1;
  msg.node_entities_info_seq._buffer = &info;
  const dds_return_t rc = dds_write(writer, &msg);
  if (rc != DDS_RETCODE_OK) throw InputError(dds_error("writing ros_discovery_info", rc));
}

std::string ros2_dds_topic(const std::string& ros_name) {
  std::size_t i = 0;
  while (i < ros_name.size() && ros_name[i] == '/') ++i;
  return "rt/" + ros_name.substr(i);
}


// ---------------------------------------------------------------------------------------------

struct Ros2Impl {
  Ros2Options options;
  RosBridgeStats stats;
  dds_entity_t participant = 0;
  Endpoint pose_reader, twist_reader, wrench_writer;
  // Admittance (options.admittance): the robot's sensor in, its setpoint out.
  Endpoint sensor_reader, setpoint_writer, setpoint_twist_writer;
  dds_entity_t waitset = 0;
  std::thread reader_thread;
  std::atomic<bool> stop{false};
  RosPoseIntake intake;
  RosSensorIntake sensor;
  RosWrenchOutbox outbox;
  geometry_msgs_msg_dds__WrenchStamped_ wrench_msg{};  // publisher thread only

  Ros2Impl(const Ros2Options& o, Clock& c, StreamDevice& in)
      : options(o), intake(in, c, stats, o.input_timeout), sensor(c),
        outbox([this](const Wrench& w, const Setpoint* sp, const RosTime& echo) { publish(w, sp, echo); }, stats) {
    participant = check(dds_create_participant(o.domain < 0 ? DDS_DOMAIN_DEFAULT : dds_domainid_t(o.domain), nullptr, nullptr),
                        "participant");
    pose_reader = make_reader(participant, &geometry_msgs_msg_dds__PoseStamped__desc, o.pose_topic, o);
    twist_reader = make_reader(participant, &geometry_msgs_msg_dds__TwistStamped__desc, o.twist_topic, o);
    wrench_writer = make_writer(participant, &geometry_msgs_msg_dds__WrenchStamped__desc, o.wrench_topic, o);
    waitset = check(dds_create_waitset(participant), "waitset");
    dds_waitset_attach(waitset, pose_reader.entity, pose_reader.entity);
    dds_waitset_attach(waitset, twist_reader.entity, twist_reader.entity);
    dds_set_status_mask(pose_reader.entity, DDS_DATA_AVAILABLE_STATUS);
    dds_set_status_mask(twist_reader.entity, DDS_DATA_AVAILABLE_STATUS);
    if (o.admittance) {
      sensor_reader = make_reader(participant, &geometry_msgs_msg_dds__WrenchStamped__desc, o.sensor_topic, o);
      setpoint_writer = make_writer(participant, &geometry_msgs_msg_dds__PoseStamped__desc, o.setpoint_topic, o);
      setpoint_twist_writer =
          make_writer(participant, &geometry_msgs_msg_dds__TwistStamped__desc, o.setpoint_twist_topic, o);
      dds_waitset_attach(waitset, sensor_reader.entity, sensor_reader.entity);
      dds_set_status_mask(sensor_reader.entity, DDS_DATA_AVAILABLE_STATUS);
    }
  }
  ~Ros2Impl() {
    shutdown();
    wait_for_acks({&wrench_writer, &setpoint_writer, &setpoint_twist_writer});
    dds_delete(participant);
  }

  void shutdown() {
    stop.store(true);
    if (waitset > 0) dds_waitset_set_trigger(waitset, true);
    if (reader_thread.joinable()) reader_thread.join();
    outbox.stop();
  }

  void publish(const Wrench& w, const Setpoint* sp, const RosTime& echo) {
    // The setpoint first: a robot's position controller gets it as soon as it exists.
    if (sp != nullptr && setpoint_writer.entity > 0) {
      geometry_msgs_msg_dds__TwistStamped_ tw{};
      fill_header(tw.header, echo, options.frame_id);
      tw.twist.linear = {sp->velocity.x(), sp->velocity.y(), sp->velocity.z()};
      tw.twist.angular = {sp->angular_velocity.x(), sp->angular_velocity.y(), sp->angular_velocity.z()};
      dds_write(setpoint_twist_writer.entity, &tw);
      geometry_msgs_msg_dds__PoseStamped_ ps{};
      fill_header(ps.header, echo, options.frame_id);
      ps.pose.position = {sp->position.x(), sp->position.y(), sp->position.z()};
      const Eigen::Quaterniond& q = sp->orientation;
      ps.pose.orientation = {q.x(), q.y(), q.z(), q.w()};
      dds_write(setpoint_writer.entity, &ps);
    }
    fill_header(wrench_msg.header, echo, options.frame_id);
    wrench_msg.wrench.force = {w.force.x(), w.force.y(), w.force.z()};
    wrench_msg.wrench.torque = {w.torque.x(), w.torque.y(), w.torque.z()};
    dds_write(wrench_writer.entity, &wrench_msg);
  }

  void take_sensor() {
    if (sensor_reader.entity <= 0) return;
    void* samples[16] = {};
    dds_sample_info_t infos[16];
    const int n = dds_take(sensor_reader.entity, samples, infos, 16, 16);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* m = static_cast<const geometry_msgs_msg_dds__WrenchStamped_*>(samples[i]);
      sensor.on_wrench({m->wrench.force.x, m->wrench.force.y, m->wrench.force.z},
                       {m->wrench.torque.x, m->wrench.torque.y, m->wrench.torque.z});
    }
    if (n > 0) dds_return_loan(sensor_reader.entity, samples, n);
  }

  void take_twists() {
    void* samples[16] = {};
    dds_sample_info_t infos[16];
    const int n = dds_take(twist_reader.entity, samples, infos, 16, 16);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* m = static_cast<const geometry_msgs_msg_dds__TwistStamped_*>(samples[i]);
      intake.on_twist({m->twist.linear.x, m->twist.linear.y, m->twist.linear.z});
    }
    if (n > 0) dds_return_loan(twist_reader.entity, samples, n);
  }

  void take_poses() {
    void* samples[16] = {};
    dds_sample_info_t infos[16];
    const int n = dds_take(pose_reader.entity, samples, infos, 16, 16);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* m = static_cast<const geometry_msgs_msg_dds__PoseStamped_*>(samples[i]);
      const auto& q = m->pose.orientation;
      intake.on_pose({m->pose.position.x, m->pose.position.y, m->pose.position.z}, {q.x, q.y, q.z, q.w},
                     {m->header.stamp.sec, m->header.stamp.nanosec}, infos[i].publication_handle);
    }
    if (n > 0) dds_return_loan(pose_reader.entity, samples, n);
  }

  // Matches DDS refused for incompatible QoS, on our wrench writer and pose reader: counted, with
  // the policy named, so that a driver that gets no wrench is never silent.
  void poll_qos() {
    dds_offered_incompatible_qos_status_t offered{};
    dds_requested_incompatible_qos_status_t requested{};
    std::uint64_t total = 0;
    std::uint32_t last = 0;
    if (dds_get_offered_incompatible_qos_status(wrench_writer.entity, &offered) == DDS_RETCODE_OK && offered.total_count > 0) {
      total += offered.total_count;
      last = offered.last_policy_id;
    }
    if (dds_get_requested_incompatible_qos_status(pose_reader.entity, &requested) == DDS_RETCODE_OK &&
        requested.total_count > 0) {
      total += requested.total_count;
      last = requested.last_policy_id;
    }
    stats.qos_incompatible.store(total);
    if (last != 0) stats.qos_last_policy.store(last);
  }

  void reader_main() {
    while (!stop.load()) {
      dds_attach_t triggered[3];
      dds_waitset_wait(waitset, triggered, 3, DDS_MSECS(100));
      if (stop.load()) break;
      take_twists();
      take_sensor();
      take_poses();
      poll_qos();
    }
  }
};

namespace {

// The options with every topic resolved in the node's namespace and remapped (--ros-args).
Ros2Options resolved(const Ros2Options& o, const Ros2Names& names) {
  Ros2Options r = o;
  r.node_name = names.node;
  for (std::string* t : {&r.pose_topic, &r.twist_topic, &r.wrench_topic, &r.markers_topic, &r.objects_topic, &r.sensor_topic,
                         &r.setpoint_topic, &r.setpoint_twist_topic})
    *t = names.resolve(*t);
  return r;
}

}  // namespace

Ros2NetworkDevice::Ros2NetworkDevice(const Ros2Options& options, Clock& clock)
    : names_(Ros2Names::parse(options.ros_args, options.node_name)),
      input_(network_device_params("ros2 (" + ros2_dds_topic(names_.resolve(options.pose_topic)) + ")",
                                   options.input_timeout),
             Eigen::Vector3d::Zero()),
      impl_(std::make_unique<Ros2Impl>(resolved(options, names_), clock, input_)) {
  // ROS 2 tools find nodes through ros_discovery_info: say which node this participant hosts.
  Ros2Impl& m = *impl_;
  std::vector<dds_entity_t> readers{m.pose_reader.entity, m.twist_reader.entity}, writers{m.wrench_writer.entity};
  if (options.admittance) {
    readers.push_back(m.sensor_reader.entity);
    writers.push_back(m.setpoint_writer.entity);
    writers.push_back(m.setpoint_twist_writer.entity);
  }
  publish_discovery_info(m.participant, names_.ns, names_.node, readers, writers);
  info_ = input_.info();
  if (options.admittance) {
    info_.admittance = true;
    info_.name = "ros2 robot (" + ros2_dds_topic(names_.resolve(options.pose_topic)) + ", sensor " +
                 ros2_dds_topic(names_.resolve(options.sensor_topic)) + ")";
  }
}

Ros2NetworkDevice::~Ros2NetworkDevice() { stop_markers(); }

void Ros2NetworkDevice::start(Nanos now) {
  input_.start(now);
  has_setpoint_ = false;
  impl_->sensor.restart();
  impl_->reader_thread = std::thread([this] { impl_->reader_main(); });
  impl_->outbox.start();
}

DeviceSample Ros2NetworkDevice::read(Nanos now) noexcept {
  DeviceSample s = input_.read(now);
  if (!info_.admittance) return s;
  // The sensor is part of the device's data: while its readings are stale the sample is too
  // (the sequence stops), so the watchdog brakes the robot as for a stale pose.
  impl_->sensor.fill(s, impl_->options.input_timeout);
  return s;
}

void Ros2NetworkDevice::write_setpoint(const Setpoint& setpoint, Nanos now) noexcept {
  (void)now;
  setpoint_ = setpoint;
  has_setpoint_ = true;
}

void Ros2NetworkDevice::write(const Wrench& wrench, Nanos now) noexcept {
  input_.write(wrench, now);
  impl_->outbox.post(wrench, impl_->intake.wrench_stamp(), info_.admittance && has_setpoint_ ? &setpoint_ : nullptr);
}

void Ros2NetworkDevice::stop(Nanos now) noexcept {
  input_.stop(now);
  impl_->shutdown();  // the outbox publishes a zero wrench as its last message
}

const RosBridgeStats& Ros2NetworkDevice::stats() const noexcept { return impl_->stats; }

std::string ros2_qos_policy_name(std::uint32_t id) {
  switch (id) {
    case 0: return "none";
    case DDS_RELIABILITY_QOS_POLICY_ID: return "RELIABILITY";
    case DDS_DURABILITY_QOS_POLICY_ID: return "DURABILITY";
    case DDS_DEADLINE_QOS_POLICY_ID: return "DEADLINE";
    case DDS_LIVELINESS_QOS_POLICY_ID: return "LIVELINESS";
    case DDS_OWNERSHIP_QOS_POLICY_ID: return "OWNERSHIP";
    case DDS_HISTORY_QOS_POLICY_ID: return "HISTORY";
    case DDS_DESTINATIONORDER_QOS_POLICY_ID: return "DESTINATION_ORDER";
    case DDS_PRESENTATION_QOS_POLICY_ID: return "PRESENTATION";
    case DDS_DATA_REPRESENTATION_QOS_POLICY_ID: return "DATA_REPRESENTATION";
    case DDS_TYPE_CONSISTENCY_ENFORCEMENT_QOS_POLICY_ID: return "TYPE_CONSISTENCY";
    default: return "policy " + std::to_string(id);
  }
}

// ---------------------------------------------------------------------------------------------

struct Ros2MarkerPublisher::State {
  Ros2Impl& dds;
  Endpoint writer;
  std::vector<Endpoint> pose_writers;  // one PoseStamped writer per object
  RosMarkerLoop loop;
  std::vector<visualization_msgs_msg_dds__Marker_> msgs;  // marker thread only

  State(Ros2Impl& d, const CollisionWorld& w, ContactSnapshotObserver& s, const Eigen::Vector3d& axes,
        const RosObjects& objects)
      : dds(d),
        writer(make_writer(d.participant, &visualization_msgs_msg_dds__MarkerArray__desc, d.options.markers_topic,
                           d.options)),
        pose_writers(object_writers(d, objects.empty() ? 0 : objects.bodies.size())),
        loop([this](const std::vector<RosMarker>& m) { publish(m); }, w, s, axes, d.options.marker_hz,
             d.options.max_markers, d.stats, d.options.input_timeout + 0.01, objects,
             [this](const ObjectPoses& p) { publish_poses(p); }) {}

  static std::vector<Endpoint> object_writers(Ros2Impl& d, std::size_t n) {
    std::vector<Endpoint> out;
    for (std::size_t i = 0; i < n; ++i)
      out.push_back(make_writer(d.participant, &geometry_msgs_msg_dds__PoseStamped__desc,
                                object_pose_topic(d.options.objects_topic, i), d.options));
    return out;
  }

  void publish_poses(const ObjectPoses& poses) {
    const RosTime t = RosTime::now();
    for (std::size_t i = 0; i < poses.count && i < pose_writers.size(); ++i) {
      geometry_msgs_msg_dds__PoseStamped_ ps{};
      fill_header(ps.header, t, dds.options.frame_id);
      const BodyPose& p = poses.poses[i];
      ps.pose.position = {p.position.x(), p.position.y(), p.position.z()};
      ps.pose.orientation = {p.rotation.x(), p.rotation.y(), p.rotation.z(), p.rotation.w()};
      dds_write(pose_writers[i].entity, &ps);
    }
  }

  void publish(const std::vector<RosMarker>& markers) {
    const RosTime t = RosTime::now();
    msgs.assign(markers.size(), visualization_msgs_msg_dds__Marker_{});
    for (std::size_t i = 0; i < markers.size(); ++i) {
      const RosMarker& in = markers[i];
      visualization_msgs_msg_dds__Marker_& m = msgs[i];
      fill_header(m.header, t, dds.options.frame_id);
      m.ns = const_cast<char*>(in.ns.c_str());
      m.id = in.id;
      m.type = in.type;
      m.action = in.action;
      m.pose.position = {in.position[0], in.position[1], in.position[2]};
      m.pose.orientation = {in.orientation_xyzw[0], in.orientation_xyzw[1], in.orientation_xyzw[2], in.orientation_xyzw[3]};
      m.scale = {in.scale[0], in.scale[1], in.scale[2]};
      m.color = {in.rgba[0], in.rgba[1], in.rgba[2], in.rgba[3]};
      m.lifetime.sec = std::int32_t(in.lifetime);
      m.lifetime.nanosec = std::uint32_t((in.lifetime - std::floor(in.lifetime)) * 1e9);
      m.texture_resource = kEmpty;
      m.texture.header.frame_id = kEmpty;
      m.texture.format = kEmpty;
      m.text = kEmpty;
      m.mesh_resource = kEmpty;
      m.mesh_file.filename = kEmpty;
    }
    visualization_msgs_msg_dds__MarkerArray_ arr{};
    arr.markers._length = arr.markers._maximum = std::uint32_t(msgs.size());
    arr.markers._buffer = msgs.data();
    arr.markers._release = false;
    dds_write(writer.entity, &arr);
  }
};

Ros2MarkerPublisher::Ros2MarkerPublisher(Ros2NetworkDevice& device, const CollisionWorld& world,
                                         ContactSnapshotObserver& snapshots, const Eigen::Vector3d& tool_axes,
                                         const RosObjects& objects)
    : state_(std::make_unique<State>(device.impl(), world, snapshots, tool_axes, objects)) {}

Ros2MarkerPublisher::~Ros2MarkerPublisher() { stop(); }

void Ros2NetworkDevice::start_markers(const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                                      const Eigen::Vector3d& tool_axes, const RosObjects& objects) {
  markers_ = std::make_unique<Ros2MarkerPublisher>(*this, world, snapshots, tool_axes, objects);
  markers_->start();
}

void Ros2NetworkDevice::stop_markers() {
  if (markers_) markers_->stop();
}

void Ros2MarkerPublisher::start() { state_->loop.start(); }
void Ros2MarkerPublisher::stop() { state_->loop.stop(); }

// ---------------------------------------------------------------------------------------------

struct Ros2DeviceLink::State {
  Ros2Options options;
  dds_entity_t participant = 0;
  Endpoint pose_writer, twist_writer, wrench_reader;
  Endpoint sensor_writer, setpoint_reader, setpoint_twist_reader;  // admittance
  Eigen::Vector3d setpoint_velocity = Eigen::Vector3d::Zero(), setpoint_angular = Eigen::Vector3d::Zero();
};

Ros2DeviceLink::Ros2DeviceLink(const Ros2Options& options) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.options = options;
  s.participant = check(dds_create_participant(options.domain < 0 ? DDS_DOMAIN_DEFAULT : dds_domainid_t(options.domain),
                                               nullptr, nullptr), "participant");
  try {
    s.pose_writer = make_writer(s.participant, &geometry_msgs_msg_dds__PoseStamped__desc, options.pose_topic, options);
    s.twist_writer = make_writer(s.participant, &geometry_msgs_msg_dds__TwistStamped__desc, options.twist_topic, options);
    s.wrench_reader = make_reader(s.participant, &geometry_msgs_msg_dds__WrenchStamped__desc, options.wrench_topic, options);
    if (options.admittance) {
      s.sensor_writer = make_writer(s.participant, &geometry_msgs_msg_dds__WrenchStamped__desc, options.sensor_topic, options);
      s.setpoint_reader = make_reader(s.participant, &geometry_msgs_msg_dds__PoseStamped__desc, options.setpoint_topic, options);
      s.setpoint_twist_reader =
          make_reader(s.participant, &geometry_msgs_msg_dds__TwistStamped__desc, options.setpoint_twist_topic, options);
    }
  } catch (...) {
    dds_delete(s.participant);
    throw;
  }
}

Ros2DeviceLink::~Ros2DeviceLink() {
  State& s = *state_;
  wait_for_acks({&s.pose_writer, &s.twist_writer, &s.sensor_writer});
  dds_delete(s.participant);
}

bool Ros2DeviceLink::wait_for_node(double timeout_s) {
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < timeout_s) {
    dds_publication_matched_status_t pm{};
    dds_subscription_matched_status_t sm{};
    dds_get_publication_matched_status(state_->pose_writer.entity, &pm);
    dds_get_subscription_matched_status(state_->wrench_reader.entity, &sm);
    if (pm.current_count > 0 && sm.current_count > 0) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

void Ros2DeviceLink::publish(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                             const Eigen::Vector3d& velocity, const RosTime& stamp) {
  State& s = *state_;
  geometry_msgs_msg_dds__TwistStamped_ tw{};
  fill_header(tw.header, stamp, s.options.frame_id);
  tw.twist.linear = {velocity.x(), velocity.y(), velocity.z()};
  dds_write(s.twist_writer.entity, &tw);
  geometry_msgs_msg_dds__PoseStamped_ ps{};
  fill_header(ps.header, stamp, s.options.frame_id);
  ps.pose.position = {position.x(), position.y(), position.z()};
  ps.pose.orientation = {orientation.x(), orientation.y(), orientation.z(), orientation.w()};
  dds_write(s.pose_writer.entity, &ps);
}

bool Ros2DeviceLink::take_wrench(Eigen::Vector3d& force, RosTime& echo) {
  void* samples[32] = {};
  dds_sample_info_t infos[32];
  const int n = dds_take(state_->wrench_reader.entity, samples, infos, 32, 32);
  bool got = false;
  for (int i = 0; i < n; ++i) {
    if (!infos[i].valid_data) continue;
    const auto* m = static_cast<const geometry_msgs_msg_dds__WrenchStamped_*>(samples[i]);
    force = {m->wrench.force.x, m->wrench.force.y, m->wrench.force.z};
    echo = {m->header.stamp.sec, m->header.stamp.nanosec};
    got = true;
  }
  if (n > 0) dds_return_loan(state_->wrench_reader.entity, samples, n);
  return got;
}

void Ros2DeviceLink::publish_sensor(const Eigen::Vector3d& force, const Eigen::Vector3d& torque, const RosTime& stamp) {
  State& s = *state_;
  if (s.sensor_writer.entity <= 0) return;
  geometry_msgs_msg_dds__WrenchStamped_ m{};
  fill_header(m.header, stamp, s.options.frame_id);
  m.wrench.force = {force.x(), force.y(), force.z()};
  m.wrench.torque = {torque.x(), torque.y(), torque.z()};
  dds_write(s.sensor_writer.entity, &m);
}

bool Ros2DeviceLink::take_setpoint(Setpoint& setpoint) {
  State& s = *state_;
  if (s.setpoint_reader.entity <= 0) return false;
  void* samples[32] = {};
  dds_sample_info_t infos[32];
  int n = dds_take(s.setpoint_twist_reader.entity, samples, infos, 32, 32);
  for (int i = 0; i < n; ++i) {
    if (!infos[i].valid_data) continue;
    const auto* m = static_cast<const geometry_msgs_msg_dds__TwistStamped_*>(samples[i]);
    const Eigen::Vector3d v(m->twist.linear.x, m->twist.linear.y, m->twist.linear.z);
    const Eigen::Vector3d w(m->twist.angular.x, m->twist.angular.y, m->twist.angular.z);
    if (v.allFinite() && w.allFinite()) s.setpoint_velocity = v, s.setpoint_angular = w;
  }
  if (n > 0) dds_return_loan(s.setpoint_twist_reader.entity, samples, n);
  bool got = false;
  n = dds_take(s.setpoint_reader.entity, samples, infos, 32, 32);
  for (int i = 0; i < n; ++i) {
    if (!infos[i].valid_data) continue;
    const auto* m = static_cast<const geometry_msgs_msg_dds__PoseStamped_*>(samples[i]);
    const Eigen::Vector3d p(m->pose.position.x, m->pose.position.y, m->pose.position.z);
    if (!p.allFinite()) continue;
    const auto& o = m->pose.orientation;
    const Eigen::Quaterniond q(o.w, o.x, o.y, o.z);
    setpoint.position = p;
    setpoint.velocity = s.setpoint_velocity;
    setpoint.orientation = q.coeffs().allFinite() && q.squaredNorm() > 0 ? q.normalized() : Eigen::Quaterniond::Identity();
    setpoint.angular_velocity = s.setpoint_angular;
    got = true;
  }
  if (n > 0) dds_return_loan(s.setpoint_reader.entity, samples, n);
  return got;
}

}  // namespace gshaptics
