#include "gshaptics/ros2/ros2_bridge.h"

#include <dds/dds.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <vector>

#include "gshaptics/io/error.h"
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
dds_qos_t* stream_qos(const Ros2Options& o) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, o.reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT, DDS_MSECS(100));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, std::max(1, o.depth));
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
  // overwritten; the samples are applied in order and the newest wins.
  Ros2Options deep = o;
  deep.depth = std::max(o.depth, 64);
  Qos q(stream_qos(deep));
  e.entity = check(dds_create_reader(pp, e.topic, q.q, nullptr), "reader on " + name);
  return e;
}

Endpoint make_writer(dds_entity_t pp, const dds_topic_descriptor_t* desc, const std::string& name, const Ros2Options& o,
                     bool reliable_override = false) {
  Endpoint e;
  e.topic = check(dds_create_topic(pp, desc, ros2_dds_topic(name).c_str(), nullptr, nullptr), "topic " + name);
  Ros2Options oo = o;
  if (reliable_override) oo.reliable = true;
  Qos q(stream_qos(oo));
  e.entity = check(dds_create_writer(pp, e.topic, q.q, nullptr), "writer on " + name);
  return e;
}

}  // namespace

std::string ros2_dds_topic(const std::string& ros_name) {
  std::size_t i = 0;
  while (i < ros_name.size() && ros_name[i] == '/') ++i;
  return "rt/" + ros_name.substr(i);
}


// ---------------------------------------------------------------------------------------------

struct Ros2Impl {
  Ros2Options options;
  Clock& clock;
  StreamDevice& input;
  dds_entity_t participant = 0;
  Endpoint pose_reader, twist_reader, wrench_writer;
  dds_entity_t waitset = 0;
  std::thread reader_thread, writer_thread;
  std::atomic<bool> stop{false};
  std::atomic<std::uint32_t> wrench_signal{0};
  struct WrenchOut {
    Wrench wrench;
    RosTime echo;
  };
  TripleBuffer<WrenchOut> wrenches;
  TripleBuffer<RosTime> pose_stamps;  // newest pose header stamp (reader thread -> servo thread)
  RosTime last_pose_stamp;
  Ros2Stats stats;
  std::vector<dds_instance_handle_t> publishers;
  Eigen::Vector3d twist = Eigen::Vector3d::Zero();
  Nanos twist_at = -1;

  Ros2Impl(const Ros2Options& o, Clock& c, StreamDevice& in) : options(o), clock(c), input(in) {
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
  }
  ~Ros2Impl() {
    shutdown();
    dds_delete(participant);
  }

  void shutdown() {
    stop.store(true);
    wrench_signal.fetch_add(1);
    wrench_signal.notify_all();
    if (waitset > 0) dds_waitset_set_trigger(waitset, true);
    if (reader_thread.joinable()) reader_thread.join();
    if (writer_thread.joinable()) writer_thread.join();
  }

  void take_twists() {
    void* samples[16] = {};
    dds_sample_info_t infos[16];
    const int n = dds_take(twist_reader.entity, samples, infos, 16, 16);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* m = static_cast<const geometry_msgs_msg_dds__TwistStamped_*>(samples[i]);
      const Eigen::Vector3d v(m->twist.linear.x, m->twist.linear.y, m->twist.linear.z);
      if (!v.allFinite()) {
        stats.poses_dropped.fetch_add(1);
        continue;
      }
      twist = v;
      twist_at = clock.now();
      stats.twists_received.fetch_add(1);
    }
    if (n > 0) dds_return_loan(twist_reader.entity, samples, n);
  }

  void take_poses() {
    void* samples[16] = {};
    dds_sample_info_t infos[16];
    const int n = dds_take(pose_reader.entity, samples, infos, 16, 16);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const dds_instance_handle_t pub = infos[i].publication_handle;
      if (std::find(publishers.begin(), publishers.end(), pub) == publishers.end()) {
        publishers.push_back(pub);
        stats.pose_publishers.store(std::uint32_t(publishers.size()));
      }
      const auto* m = static_cast<const geometry_msgs_msg_dds__PoseStamped_*>(samples[i]);
      const Eigen::Vector3d p(m->pose.position.x, m->pose.position.y, m->pose.position.z);
      Eigen::Quaterniond q(m->pose.orientation.w, m->pose.orientation.x, m->pose.orientation.y, m->pose.orientation.z);
      if (!p.allFinite() || !q.coeffs().allFinite()) {
        stats.poses_dropped.fetch_add(1);
        continue;
      }
      // An all-zero quaternion (an unset field, common from command-line publishers) is identity.
      if (q.coeffs().squaredNorm() < 1e-12) q = Eigen::Quaterniond::Identity();
      const Nanos now = clock.now();
      const bool fresh_twist = twist_at >= 0 && now - twist_at < to_nanos(0.05);
      input.set_target(p, q.normalized(), now, fresh_twist ? &twist : nullptr);
      pose_stamps.write({m->header.stamp.sec, m->header.stamp.nanosec});
      stats.poses_received.fetch_add(1);
    }
    if (n > 0) dds_return_loan(pose_reader.entity, samples, n);
  }

  void reader_main() {
    while (!stop.load()) {
      dds_attach_t triggered[2];
      dds_waitset_wait(waitset, triggered, 2, DDS_MSECS(100));
      if (stop.load()) break;
      take_twists();
      take_poses();
    }
  }

  void writer_main() {
    std::uint32_t seen = wrench_signal.load();
    geometry_msgs_msg_dds__WrenchStamped_ msg{};
    WrenchOut w;
    while (true) {
      wrench_signal.wait(seen);
      seen = wrench_signal.load();
      const bool stopping = stop.load();
      if (wrenches.read_if_new(w) || stopping) {
        if (stopping) w.wrench = Wrench{};  // leave the device at zero force
        fill_header(msg.header, w.echo, options.frame_id);
        msg.wrench.force = {w.wrench.force.x(), w.wrench.force.y(), w.wrench.force.z()};
        msg.wrench.torque = {w.wrench.torque.x(), w.wrench.torque.y(), w.wrench.torque.z()};
        if (dds_write(wrench_writer.entity, &msg) >= 0) stats.wrenches_published.fetch_add(1);
      }
      if (stopping) break;
    }
  }
};

Ros2NetworkDevice::Ros2NetworkDevice(const Ros2Options& options, Clock& clock)
    : input_([&] {
        StreamDeviceParams p;
        p.name = "ros2 (" + ros2_dds_topic(options.pose_topic) + ")";
        p.input_timeout = options.input_timeout;
        p.interpolate = false;
        p.alive_before_first_target = false;
        return p;
      }(), Eigen::Vector3d::Zero()),
      impl_(std::make_unique<Ros2Impl>(options, clock, input_)) {}

Ros2NetworkDevice::~Ros2NetworkDevice() { stop_markers(); }

void Ros2NetworkDevice::start(Nanos now) {
  input_.start(now);
  impl_->reader_thread = std::thread([this] { impl_->reader_main(); });
  impl_->writer_thread = std::thread([this] { impl_->writer_main(); });
}

DeviceSample Ros2NetworkDevice::read(Nanos now) noexcept {
  RosTime t;
  if (impl_->pose_stamps.read_if_new(t)) impl_->last_pose_stamp = t;
  return input_.read(now);
}

void Ros2NetworkDevice::write(const Wrench& wrench, Nanos now) noexcept {
  input_.write(wrench, now);
  impl_->wrenches.write({wrench, impl_->last_pose_stamp});
  impl_->wrench_signal.fetch_add(1, std::memory_order_release);
  impl_->wrench_signal.notify_one();
}

void Ros2NetworkDevice::stop(Nanos now) noexcept {
  input_.stop(now);
  impl_->shutdown();  // the writer thread publishes a zero wrench as its last message
}

const RosBridgeStats& Ros2NetworkDevice::stats() const noexcept { return impl_->stats; }

// ---------------------------------------------------------------------------------------------

struct Ros2MarkerPublisher::State {
  Ros2Impl& dds;
  const CollisionWorld& world;
  ContactSnapshotObserver& snapshots;
  Eigen::Vector3d tool_axes;
  Endpoint writer;
  std::thread thread;
  std::atomic<bool> stop{false};
  ContactSnapshot snap;

  State(Ros2Impl& d, const CollisionWorld& w, ContactSnapshotObserver& s, const Eigen::Vector3d& axes)
      : dds(d), world(w), snapshots(s), tool_axes(axes) {
    writer = make_writer(d.participant, &visualization_msgs_msg_dds__MarkerArray__desc, d.options.markers_topic,
                         d.options, /*reliable_override=*/true);
  }

  static visualization_msgs_msg_dds__Marker_ blank(const RosTime& t, const std::string& frame) {
    visualization_msgs_msg_dds__Marker_ m{};
    fill_header(m.header, t, frame);
    m.ns = kEmpty;
    m.texture_resource = kEmpty;
    m.texture.header.frame_id = kEmpty;
    m.texture.format = kEmpty;
    m.text = kEmpty;
    m.mesh_resource = kEmpty;
    m.mesh_file.filename = kEmpty;
    m.pose.orientation.w = 1;
    return m;
  }

  void publish_once() {
    if (!snapshots.take(snap) || snap.pose_sequence == 0) return;
    const RosTime t = RosTime::now();
    const std::string& frame = dds.options.frame_id;
    static std::string ns_clear = "", ns_tool = "tool", ns_contacts = "contacts";
    const std::size_t shown = std::min<std::size_t>(snap.shown, dds.options.max_markers);
    std::vector<visualization_msgs_msg_dds__Marker_> markers(2 + shown);
    // 0: delete the previous frame's markers; 1: the tool ellipsoid; then one per contact.
    markers[0] = blank(t, frame);
    markers[0].action = 3;  // DELETEALL
    markers[0].ns = cstr(ns_clear);
    visualization_msgs_msg_dds__Marker_& tool = markers[1] = blank(t, frame);
    tool.ns = cstr(ns_tool);
    tool.type = 2;  // SPHERE
    tool.pose.position = {snap.pose.position.x(), snap.pose.position.y(), snap.pose.position.z()};
    tool.pose.orientation = {snap.pose.orientation.x(), snap.pose.orientation.y(), snap.pose.orientation.z(),
                             snap.pose.orientation.w()};
    tool.scale = {2 * tool_axes.x(), 2 * tool_axes.y(), 2 * tool_axes.z()};  // diameters
    tool.color = {0.4f, 0.8f, 1.0f, 0.5f};
    for (std::size_t i = 0; i < shown; ++i) {
      const CollisionGaussian& g = world.gaussians()[snap.record[i]];
      visualization_msgs_msg_dds__Marker_& m = markers[2 + i] = blank(t, frame);
      m.ns = cstr(ns_contacts);
      m.id = std::int32_t(g.source_index);  // index into the original scene file
      m.type = 2;
      m.pose.position = {g.center[0], g.center[1], g.center[2]};
      Eigen::Matrix3d r;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) r(a, b) = double(g.rotation[3 * a + b]);
      const Eigen::Quaterniond q = Eigen::Quaterniond(r).normalized();
      m.pose.orientation = {q.x(), q.y(), q.z(), q.w()};
      m.scale = {2.0 * g.semi_axes[0], 2.0 * g.semi_axes[1], 2.0 * g.semi_axes[2]};
      m.color = {1.0f, 0.15f, 0.25f, 0.85f};
    }
    visualization_msgs_msg_dds__MarkerArray_ arr{};
    arr.markers._length = arr.markers._maximum = std::uint32_t(markers.size());
    arr.markers._buffer = markers.data();
    arr.markers._release = false;
    if (dds_write(writer.entity, &arr) >= 0) dds.stats.markers_published.fetch_add(1);
  }

  void run() {
    const auto period = std::chrono::duration<double>(1.0 / std::max(1.0, dds.options.marker_hz));
    while (!stop.load()) {
      publish_once();
      std::this_thread::sleep_for(period);
    }
  }
};

Ros2MarkerPublisher::Ros2MarkerPublisher(Ros2NetworkDevice& device, const CollisionWorld& world,
                                         ContactSnapshotObserver& snapshots, const Eigen::Vector3d& tool_axes)
    : state_(std::make_unique<State>(device.impl(), world, snapshots, tool_axes)) {}

Ros2MarkerPublisher::~Ros2MarkerPublisher() { stop(); }

void Ros2NetworkDevice::start_markers(const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                                      const Eigen::Vector3d& tool_axes) {
  markers_ = std::make_unique<Ros2MarkerPublisher>(*this, world, snapshots, tool_axes);
  markers_->start();
}

void Ros2NetworkDevice::stop_markers() {
  if (markers_) markers_->stop();
}

void Ros2MarkerPublisher::start() {
  state_->thread = std::thread([s = state_.get()] { s->run(); });
}

void Ros2MarkerPublisher::stop() {
  state_->stop.store(true);
  if (state_->thread.joinable()) state_->thread.join();
}

// ---------------------------------------------------------------------------------------------

struct Ros2DeviceLink::State {
  Ros2Options options;
  dds_entity_t participant = 0;
  Endpoint pose_writer, twist_writer, wrench_reader;
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
  } catch (...) {
    dds_delete(s.participant);
    throw;
  }
}

Ros2DeviceLink::~Ros2DeviceLink() { dds_delete(state_->participant); }

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

}  // namespace gshaptics
