#include "gshaptics/net/ros_bridge.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <optional>

#include "gshaptics/error.h"

namespace gshaptics {

namespace {

// `name` under namespace `ns` (absolute, no trailing '/'), without repeated or trailing slashes.
std::string expand(const std::string& ns, const std::string& name) {
  std::string full = !name.empty() && name[0] == '/' ? name : (ns == "/" ? "" : ns) + "/" + name;
  std::string out;
  for (char c : full)
    if (!(c == '/' && !out.empty() && out.back() == '/')) out += c;
  if (out.size() > 1 && out.back() == '/') out.pop_back();
  return out.empty() ? "/" : out;
}

}  // namespace

Ros2Names Ros2Names::parse(const std::vector<std::string>& args, const std::string& node) {
  Ros2Names n;
  n.node = node;
  if (args.empty()) return n;
  if (args.front() != "--ros-args")
    throw InputError("ROS 2: '" + args.front() + "' is a ROS 1 remapping; ROS 2 takes --ros-args -r FROM:=TO");
  std::vector<std::pair<std::string, std::string>> rules;
  for (std::size_t i = 1; i < args.size(); ++i) {
    const std::string& a = args[i];
    if ((a != "-r" && a != "--remap") || i + 1 >= args.size())
      throw InputError("ROS 2: --ros-args '" + a + "': this node takes remap rules only (-r FROM:=TO, -r __ns:=/NS, "
                       "-r __node:=NAME)");
    const std::string rule = args[++i];
    const std::size_t eq = rule.find(":=");
    if (eq == std::string::npos || eq == 0 || eq + 2 >= rule.size())
      throw InputError("ROS 2: remap rule '" + rule + "' is not FROM:=TO");
    const std::string from = rule.substr(0, eq), to = rule.substr(eq + 2);
    if (from == "__ns") {
      if (to[0] != '/') throw InputError("ROS 2: __ns:=" + to + ": a namespace must be absolute ('/...')");
      n.ns = expand("/", to);
    } else if (from == "__node" || from == "__name") {
      n.node = to;
    } else {
      rules.emplace_back(from, to);
    }
  }
  for (const auto& [from, to] : rules) n.remaps.emplace_back(expand(n.ns, from), expand(n.ns, to));
  return n;
}

std::string Ros2Names::resolve(const std::string& name) const {
  const std::string full = expand(ns, name);
  for (const auto& [from, to] : remaps)
    if (from == full) return to;
  return full;
}

void RosPoseIntake::on_twist(const Eigen::Vector3d& linear) {
  if (!linear.allFinite()) {
    stats_.poses_dropped.fetch_add(1);
    return;
  }
  twist_ = linear;
  twist_at_ = clock_.now();
  stats_.twists_received.fetch_add(1);
}

void RosPoseIntake::on_pose(const Eigen::Vector3d& position, const Eigen::Vector4d& q_xyzw, const RosTime& stamp,
                            std::uint64_t publisher) {
  if (std::find(publishers_.begin(), publishers_.end(), publisher) == publishers_.end()) {
    publishers_.push_back(publisher);
    stats_.pose_publishers.store(std::uint32_t(publishers_.size()));
  }
  if (!position.allFinite() || !q_xyzw.allFinite()) {
    stats_.poses_dropped.fetch_add(1);
    return;
  }
  Eigen::Quaterniond q(q_xyzw[3], q_xyzw[0], q_xyzw[1], q_xyzw[2]);
  if (q.coeffs().squaredNorm() < 1e-12) q = Eigen::Quaterniond::Identity();
  const Nanos now = clock_.now();
  const bool fresh_twist = twist_at_ >= 0 && now - twist_at_ < to_nanos(0.05);
  // Velocity from the sender's stamps (transport jitter would otherwise enter the damping term
  // as a force spike), arrival times only when the stamps cannot be used.
  const std::int64_t st = stamp.nanos();
  if (have_prev_) {
    const std::int64_t d_stamp = st - prev_stamp_;
    const Nanos d_arrival = now - prev_arrival_;
    double dt = 0;
    if (st == 0 || prev_stamp_ == 0 || d_stamp <= 0) {
      stats_.stamp_fallbacks.fetch_add(1);
      dt = to_seconds(d_arrival);
    } else if (std::llabs(d_stamp - d_arrival) > 1'000'000'000LL) {
      stats_.stamp_rejected.fetch_add(1);
      dt = to_seconds(d_arrival);
    } else {
      dt = double(d_stamp) * 1e-9;
    }
    if (dt > 0) {
      const Eigen::Vector3d raw = (position - prev_position_) / dt;
      velocity_ += (1.0 - std::exp(-dt / kVelocityTau)) * (raw - velocity_);
    }
  }
  have_prev_ = true;
  prev_position_ = position;
  prev_stamp_ = st;
  prev_arrival_ = now;
  input_.set_target(position, q.normalized(), now, fresh_twist ? &twist_ : &velocity_);
  stamps_.write(RosPoseArrival{stamp, now});
  stats_.poses_received.fetch_add(1);
}

const RosTime& RosPoseIntake::newest_stamp() noexcept {
  stamps_.read_if_new(newest_);
  return newest_.stamp;
}

RosTime RosPoseIntake::wrench_stamp() noexcept {
  stamps_.read_if_new(newest_);
  const bool fresh = newest_.arrival >= 0 && clock_.now() - newest_.arrival <= fresh_for_ && newest_.stamp.nanos() != 0;
  return fresh ? newest_.stamp : RosTime::now();
}

void RosWrenchOutbox::start() {
  stop_.store(false);
  thread_ = std::thread([this] {
    std::uint32_t seen = signal_.load();
    Item item;
    while (true) {
      signal_.wait(seen);
      seen = signal_.load();
      const bool stopping = stop_.load();
      if (items_.read_if_new(item) || stopping) {
        if (stopping) {  // the last message: zero force, a robot at rest, stamped when it is sent
          item.wrench = Wrench{};
          item.setpoint.velocity.setZero();
          item.echo = RosTime::now();
        }
        publish_(item.wrench, item.has_setpoint ? &item.setpoint : nullptr, item.echo);
        stats_.wrenches_published.fetch_add(1);
      }
      if (stopping) break;
    }
  });
}

void RosWrenchOutbox::post(const Wrench& wrench, const RosTime& echo, const Setpoint* setpoint) noexcept {
  Item item{wrench, echo, {}, setpoint != nullptr};
  if (setpoint != nullptr) item.setpoint = *setpoint;
  items_.write(item);
  signal_.fetch_add(1, std::memory_order_release);
  signal_.notify_one();
}

void RosSensorIntake::on_wrench(const Eigen::Vector3d& force, const Eigen::Vector3d& torque) noexcept {
  if (!force.allFinite() || !torque.allFinite()) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  readings_.write({force, torque, clock_.now()});
  received_.fetch_add(1, std::memory_order_relaxed);
}

bool RosSensorIntake::newest(Eigen::Vector3d& force, Eigen::Vector3d& torque, double fresh_for) noexcept {
  (void)readings_.read_if_new(newest_);
  force = newest_.force;
  torque = newest_.torque;
  return newest_.arrival >= 0 && clock_.now() - newest_.arrival <= to_nanos(fresh_for);
}

void RosSensorIntake::fill(DeviceSample& s, double fresh_for) noexcept {
  if (newest(s.user_force, s.user_torque, fresh_for))
    frozen_ = s.sequence;
  else
    s.sequence = frozen_;
}

void RosWrenchOutbox::stop() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  signal_.fetch_add(1);
  signal_.notify_all();
  thread_.join();
}

std::vector<RosMarker> contact_markers(const ContactSnapshot& snap, const SnapshotWorlds& worlds,
                                       const Eigen::Vector3d& tool_axes, std::size_t max_contacts, double lifetime) {
  const std::size_t shown = std::min<std::size_t>(snap.shown, max_contacts);
  std::vector<RosMarker> out;
  out.reserve(3 + shown);
  RosMarker clear;
  clear.action = RosMarker::kDeleteAll;
  out.push_back(clear);
  RosMarker tool;
  tool.ns = "tool";
  tool.position = {snap.pose.position.x(), snap.pose.position.y(), snap.pose.position.z()};
  tool.orientation_xyzw = {snap.pose.orientation.x(), snap.pose.orientation.y(), snap.pose.orientation.z(),
                           snap.pose.orientation.w()};
  tool.scale = {2 * tool_axes.x(), 2 * tool_axes.y(), 2 * tool_axes.z()};
  tool.rgba = {0.4f, 0.8f, 1.0f, 0.5f};
  tool.lifetime = lifetime;
  out.push_back(tool);
  for (std::size_t i = 0; i < shown; ++i) {
    const std::optional<ShownGaussian> g = shown_gaussian(snap, i, worlds);
    if (!g) continue;
    RosMarker m;
    m.ns = "contacts";
    m.id = std::int32_t(g->source_index);
    m.position = {g->center.x(), g->center.y(), g->center.z()};
    const Eigen::Quaterniond& q = g->rotation;
    m.orientation_xyzw = {q.x(), q.y(), q.z(), q.w()};
    m.scale = {2.0 * g->semi_axes[0], 2.0 * g->semi_axes[1], 2.0 * g->semi_axes[2]};
    m.rgba = {1.0f, 0.15f, 0.25f, 0.85f};
    m.lifetime = lifetime;
    out.push_back(m);
  }
  // The proxy (god-object) as a ghost of the tool, last, while it holds the tool off the pose.
  if ((snap.proxy - snap.pose.position).norm() > 0.02 * tool_axes.maxCoeff()) {
    RosMarker ghost = tool;
    ghost.ns = "proxy";
    ghost.position = {snap.proxy.x(), snap.proxy.y(), snap.proxy.z()};
    ghost.rgba = {0.6f, 1.0f, 0.6f, 0.35f};
    out.push_back(ghost);
  }
  return out;
}

std::vector<RosMarker> object_markers(const ObjectPoses& poses, std::span<const Eigen::Vector3d> sizes,
                                      double lifetime) {
  std::vector<RosMarker> out;
  for (std::size_t i = 0; i < poses.count && i < sizes.size(); ++i) {
    const BodyPose& p = poses.poses[i];
    RosMarker m;
    m.ns = "objects";
    m.id = std::int32_t(i);
    m.type = RosMarker::kCube;
    m.position = {p.position.x(), p.position.y(), p.position.z()};
    m.orientation_xyzw = {p.rotation.x(), p.rotation.y(), p.rotation.z(), p.rotation.w()};
    m.scale = {sizes[i].x(), sizes[i].y(), sizes[i].z()};
    m.rgba = {0.95f, 0.55f, 0.15f, 0.6f};
    m.lifetime = lifetime;
    out.push_back(m);
  }
  return out;
}

RosMarkerLoop::RosMarkerLoop(PublishFn publish, const CollisionWorld& world, ContactSnapshotObserver& snapshots,
                             const Eigen::Vector3d& tool_axes, double hz, std::size_t max_contacts,
                             RosBridgeStats& stats, double stale_after, RosObjects objects, PublishPosesFn publish_poses)
    : publish_(std::move(publish)), world_(world), snapshots_(snapshots), tool_axes_(tool_axes),
      hz_(std::max(1.0, hz)), max_(max_contacts), stats_(stats), stale_after_(std::max(stale_after, 2.5 / hz_)),
      objects_(std::move(objects)), publish_poses_(std::move(publish_poses)) {
  if (!objects_.empty()) {
    pose_reader_ = objects_.poses->subscribe();
    if (pose_reader_ < 0) throw InputError("ROS markers: the objects' pose channel has no reader slot left");
  }
}

void RosMarkerLoop::start() {
  stop_.store(false);
  thread_ = std::thread([this] {
    ContactSnapshot snap;
    ObjectPoses poses;  // count 0 until the first arrives
    bool have = false;
    const auto period = std::chrono::duration<double>(1.0 / hz_);
    const double lifetime = 3.0 / hz_;
    auto last_new = std::chrono::steady_clock::now();
    RosMarker clear;
    clear.action = RosMarker::kDeleteAll;
    const std::vector<RosMarker> clear_all{clear};
    while (!stop_.load()) {
      const auto now = std::chrono::steady_clock::now();
      if (snapshots_.take(snap) && snap.pose_sequence != 0) {
        have = true;
        last_new = now;
      }
      if (!objects_.empty()) objects_.poses->read_if_new(pose_reader_, poses);
      if (poses.count > 0 && publish_poses_) publish_poses_(poses);
      if (have) {
        const bool stale = std::chrono::duration<double>(now - last_new).count() > stale_after_;
        const SnapshotWorlds worlds{&world_, objects_.bodies, poses.count > 0 ? &poses : nullptr};
        std::vector<RosMarker> markers = stale ? clear_all : contact_markers(snap, worlds, tool_axes_, max_, lifetime);
        for (RosMarker& m : object_markers(poses, objects_.sizes, lifetime)) markers.push_back(std::move(m));
        publish_(markers);
        stats_.markers_published.fetch_add(1);
      }
      std::this_thread::sleep_for(period);
    }
    publish_(clear_all);  // nothing of this run stays on screen
    stats_.markers_published.fetch_add(1);
  });
}

void RosMarkerLoop::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

}  // namespace gshaptics
