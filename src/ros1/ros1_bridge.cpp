#include "gshaptics/ros1/ros1_bridge.h"

#include <algorithm>
#include <chrono>
#include <thread>
#include <vector>

#include "gshaptics/io/error.h"
#include "gshaptics/servo/triple_buffer.h"
#include "ros1_transport.h"

namespace gshaptics {

namespace {

std::string absolute(const std::string& name) { return name.empty() || name[0] == '/' ? name : "/" + name; }


}  // namespace

struct Ros1Impl {
  RosBridgeOptions options;
  Clock& clock;
  StreamDevice& input;
  std::unique_ptr<ros1::Transport> transport;
  std::thread writer_thread, marker_thread;
  std::atomic<bool> stop{false}, markers_stop{false};
  std::atomic<std::uint32_t> wrench_signal{0};
  struct WrenchOut {
    Wrench wrench;
    RosTime echo;
  };
  TripleBuffer<WrenchOut> wrenches;
  TripleBuffer<RosTime> pose_stamps;
  RosTime last_pose_stamp;
  RosBridgeStats stats;
  std::vector<std::string> publishers;  // spinner thread only
  Eigen::Vector3d twist = Eigen::Vector3d::Zero();
  Nanos twist_at = -1;

  Ros1Impl(const RosBridgeOptions& o, Clock& c, StreamDevice& in) : options(o), clock(c), input(in) {}

  void on_twist(const std::array<double, 3>& t) {
    const Eigen::Vector3d v(t[0], t[1], t[2]);
    if (!v.allFinite()) {
      stats.poses_dropped.fetch_add(1);
      return;
    }
    twist = v;
    twist_at = clock.now();
    stats.twists_received.fetch_add(1);
  }

  void on_pose(const ros1::PoseIn& m) {
    if (std::find(publishers.begin(), publishers.end(), m.publisher) == publishers.end()) {
      publishers.push_back(m.publisher);
      stats.pose_publishers.store(std::uint32_t(publishers.size()));
    }
    const Eigen::Vector3d p(m.position[0], m.position[1], m.position[2]);
    Eigen::Quaterniond q(m.orientation_xyzw[3], m.orientation_xyzw[0], m.orientation_xyzw[1], m.orientation_xyzw[2]);
    if (!p.allFinite() || !q.coeffs().allFinite()) {
      stats.poses_dropped.fetch_add(1);
      return;
    }
    // ROS 1 messages have no defaults: an unset orientation is all zeros; take it as identity.
    if (q.coeffs().squaredNorm() < 1e-12) q = Eigen::Quaterniond::Identity();
    const Nanos now = clock.now();
    const bool fresh_twist = twist_at >= 0 && now - twist_at < to_nanos(0.05);
    input.set_target(p, q.normalized(), now, fresh_twist ? &twist : nullptr);
    pose_stamps.write({m.sec, m.nanosec});
    stats.poses_received.fetch_add(1);
  }

  void writer_main() {
    std::uint32_t seen = wrench_signal.load();
    WrenchOut w;
    while (true) {
      wrench_signal.wait(seen);
      seen = wrench_signal.load();
      const bool stopping = stop.load();
      if (wrenches.read_if_new(w) || stopping) {
        if (stopping) w.wrench = Wrench{};  // leave the device at zero force
        transport->publish_wrench({w.wrench.force.x(), w.wrench.force.y(), w.wrench.force.z()},
                                  {w.wrench.torque.x(), w.wrench.torque.y(), w.wrench.torque.z()}, w.echo.sec,
                                  w.echo.nanosec);
        stats.wrenches_published.fetch_add(1);
      }
      if (stopping) break;
    }
  }

  void marker_main(const CollisionWorld& world, ContactSnapshotObserver& snapshots, Eigen::Vector3d axes) {
    ContactSnapshot snap;
    const auto period = std::chrono::duration<double>(1.0 / std::max(1.0, options.marker_hz));
    while (!markers_stop.load()) {
      if (snapshots.take(snap) && snap.pose_sequence != 0) {
        std::vector<ros1::MarkerOut> arr;
        ros1::MarkerOut clear;
        clear.action = 3;  // DELETEALL
        arr.push_back(clear);
        ros1::MarkerOut tool;
        tool.ns = "tool";
        tool.position = {snap.pose.position.x(), snap.pose.position.y(), snap.pose.position.z()};
        tool.orientation_xyzw = {snap.pose.orientation.x(), snap.pose.orientation.y(), snap.pose.orientation.z(),
                                 snap.pose.orientation.w()};
        tool.scale = {2 * axes.x(), 2 * axes.y(), 2 * axes.z()};  // diameters
        tool.rgba = {0.4f, 0.8f, 1.0f, 0.5f};
        arr.push_back(tool);
        const std::size_t shown = std::min<std::size_t>(snap.shown, options.max_markers);
        for (std::size_t i = 0; i < shown; ++i) {
          const CollisionGaussian& g = world.gaussians()[snap.record[i]];
          ros1::MarkerOut m;
          m.ns = "contacts";
          m.id = std::int32_t(g.source_index);  // index into the original scene file
          m.position = {g.center[0], g.center[1], g.center[2]};
          Eigen::Matrix3d r;
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) r(a, b) = double(g.rotation[3 * a + b]);
          const Eigen::Quaterniond q = Eigen::Quaterniond(r).normalized();
          m.orientation_xyzw = {q.x(), q.y(), q.z(), q.w()};
          m.scale = {2.0 * g.semi_axes[0], 2.0 * g.semi_axes[1], 2.0 * g.semi_axes[2]};
          m.rgba = {1.0f, 0.15f, 0.25f, 0.85f};
          arr.push_back(m);
        }
        transport->publish_markers(arr);
        stats.markers_published.fetch_add(1);
      }
      std::this_thread::sleep_for(period);
    }
  }
};

Ros1NetworkDevice::Ros1NetworkDevice(const RosBridgeOptions& options, Clock& clock, const std::string& node_name,
                                     double master_timeout)
    : input_([&] {
        StreamDeviceParams p;
        p.name = "ros1 (" + absolute(options.pose_topic) + ")";
        p.input_timeout = options.input_timeout;
        p.interpolate = false;
        p.alive_before_first_target = false;
        return p;
      }(), Eigen::Vector3d::Zero()),
      impl_(std::make_unique<Ros1Impl>(options, clock, input_)) {
  ros1::TransportOptions t;
  t.node_name = node_name;
  t.pose_topic = absolute(options.pose_topic);
  t.twist_topic = absolute(options.twist_topic);
  t.wrench_topic = absolute(options.wrench_topic);
  t.markers_topic = absolute(options.markers_topic);
  t.frame_id = options.frame_id;
  t.master_timeout = master_timeout;
  Ros1Impl& m = *impl_;
  try {
    m.transport = std::make_unique<ros1::Transport>(
        t, [&m](const ros1::PoseIn& p) { m.on_pose(p); }, [&m](const std::array<double, 3>& v) { m.on_twist(v); });
  } catch (const std::runtime_error& e) {
    throw InputError(e.what());
  }
}

Ros1NetworkDevice::~Ros1NetworkDevice() {
  stop_markers();
  impl_->stop.store(true);
  impl_->wrench_signal.fetch_add(1);
  impl_->wrench_signal.notify_all();
  if (impl_->writer_thread.joinable()) impl_->writer_thread.join();
  impl_->transport.reset();
}

void Ros1NetworkDevice::start(Nanos now) {
  input_.start(now);
  impl_->writer_thread = std::thread([this] { impl_->writer_main(); });
}

DeviceSample Ros1NetworkDevice::read(Nanos now) noexcept {
  RosTime t;
  if (impl_->pose_stamps.read_if_new(t)) impl_->last_pose_stamp = t;
  return input_.read(now);
}

void Ros1NetworkDevice::write(const Wrench& wrench, Nanos now) noexcept {
  input_.write(wrench, now);
  impl_->wrenches.write({wrench, impl_->last_pose_stamp});
  impl_->wrench_signal.fetch_add(1, std::memory_order_release);
  impl_->wrench_signal.notify_one();
}

void Ros1NetworkDevice::stop(Nanos now) noexcept {
  input_.stop(now);
  impl_->stop.store(true);
  impl_->wrench_signal.fetch_add(1);
  impl_->wrench_signal.notify_all();
  if (impl_->writer_thread.joinable()) impl_->writer_thread.join();
}

const RosBridgeStats& Ros1NetworkDevice::stats() const noexcept { return impl_->stats; }

void Ros1NetworkDevice::start_markers(const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                                      const Eigen::Vector3d& tool_axes) {
  impl_->markers_stop.store(false);
  impl_->marker_thread = std::thread([this, &world, &snapshots, tool_axes] {
    impl_->marker_main(world, snapshots, tool_axes);
  });
}

void Ros1NetworkDevice::stop_markers() {
  impl_->markers_stop.store(true);
  if (impl_->marker_thread.joinable()) impl_->marker_thread.join();
}

std::string Ros1NetworkDevice::wire_topic(const std::string& ros_name) const { return absolute(ros_name); }

}  // namespace gshaptics
