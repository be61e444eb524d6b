#include "gshaptics/session_ros/node_session.h"

#include <fmt/format.h>

#include <algorithm>
#include <memory>
#include <nlohmann/json.hpp>

#include "gshaptics/error.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/percentile.h"
#include "gshaptics/servo/tick_log.h"
#include "gshaptics/device/publishing_device.h"
#include "gshaptics/device/simulated_device.h"
#ifdef GSHAPTICS_HAVE_ROS2
#include "gshaptics/ros2/ros2_bridge.h"
#endif
#ifdef GSHAPTICS_HAVE_ROS1
#include "gshaptics/ros1/ros1_bridge.h"
#endif

namespace gshaptics::session {

namespace {

std::unique_ptr<RosBridgeDevice> make_bridge(const NodeOptions& o) {
#ifdef GSHAPTICS_HAVE_ROS2
  if (o.ros2) return std::make_unique<Ros2NetworkDevice>(o.topics, MonotonicClock::instance());
#endif
#ifdef GSHAPTICS_HAVE_ROS1
  if (o.ros1) return std::make_unique<Ros1NetworkDevice>(o.topics, MonotonicClock::instance());
#endif
  throw InputError(std::string("node: this build has no ") + (o.ros2 ? "ROS 2 (Cyclone DDS)" : "ROS 1 (roscpp)") +
                   " bridge; install the packages scripts/setup.sh lists and rebuild");
}

// The name of a DDS QoS policy id (ROS 2 builds; ROS 1 has no QoS mismatch).
std::string qos_policy(std::uint32_t id) {
#ifdef GSHAPTICS_HAVE_ROS2
  return ros2_qos_policy_name(id);
#else
  return "policy " + std::to_string(id);
#endif
}

}  // namespace

int run_node(NodeOptions o) {
  if (!o.ros2 && !o.ros1) throw InputError("node: give --ros2 or --ros1");
  // The remote device is a robot with a force sensor under admittance control.
  o.topics.admittance = o.run.device == "ros" && o.run.control.mode == ControlMode::kAdmittance;
  if (o.run.simulated_time) throw InputError("--simulated-time: node runs in real time (use `run --simulated-time`)");
  if (o.run.device != "ros" && !is_hardware_device(o.run.device))
    throw InputError("--device: node takes 'ros' (default), 'haply[:N]', 'dhd[:N]' or 'openhaptics[:NAME]', got '" +
                     o.run.device + "'");
  // A hardware device is opened before the scene load, once.
  std::unique_ptr<HapticDevice> opened = o.run.device != "ros" ? validate_runtime_options(o.run, false) : nullptr;
  if (o.ros2) (void)Ros2Names::parse(o.topics.ros_args, o.topics.node_name);  // before the scene load too
  const RendererSpec renderer = o.run.force.spec();
  const SceneOptions so = with_bundled_defaults(o.run.scene, "node", renderer);
  prepare_run_out_dir(o.run, so);
  const PreparedWorld pw = prepare_world(so, o.run.quiet);
  warn_if_outside_profile(pw, o.run.force);
  RuntimeSetup setup;
  setup.tool_radius = o.run.tool_radius > 0 ? o.run.tool_radius : default_tool_radius(pw.world);
  setup.planned = o.run.duration;
  auto device = make_bridge(o);
  RosBridgeDevice& net = *device;
  const bool local = is_hardware_device(o.run.device);
  std::unique_ptr<HapticDevice> bridge_owner;
  if (local) {
    // The local device drives the runtime; the bridge only publishes (wrench, markers).
    setup.device = std::move(opened);
    setup.device->start(0);  // a missing device is an error before anything starts
    setup.device->stop(0);
    wrap_in_workspace_mapping(o.run, setup, /*hardware=*/true, tool_start_point(pw, setup.tool_radius),
                              pw.world.up());
    bridge_owner = std::move(device);
    auto tee = std::make_unique<PublishingDevice>(*setup.device, net);
    setup.inner_keep = std::move(setup.device);
    setup.device = std::move(tee);
  } else {
    setup.device = std::move(device);
    wrap_in_workspace_mapping(o.run, setup);  // a desktop device's driver publishes device coordinates
  }
  setup.config = runtime_config_from(o.run, setup.tool_radius, setup.planned);
  attach_scene_objects(setup, pw, so, o.run.rate);
  HapticRuntime rt(pw.world, *setup.device, setup.config);
  ContactSnapshotObserver snapshots(o.topics.marker_hz, MonotonicClock::instance());
  rt.set_observer(&snapshots);
  fmt::print("node       {}: pose {} (+ twist {}) in, wrench {} at {:.0f} Hz and markers {} at {:.0f} Hz "
             "out, frame '{}'{}, tool radius {:.4g}\n", o.ros2 ? "ROS 2" : "ROS 1",
             net.wire_topic(o.topics.pose_topic), net.wire_topic(o.topics.twist_topic),
             net.wire_topic(o.topics.wrench_topic), o.run.rate, net.wire_topic(o.topics.markers_topic),
             o.topics.marker_hz, o.topics.frame_id,
             o.ros2 ? fmt::format(", readers {}, writers {} depth {}", o.topics.reliable_input ? "reliable" : "best-effort",
                                   o.topics.reliable_output ? "reliable" : "best-effort", o.topics.depth)
                     : std::string(), setup.tool_radius);
  fmt::print("node       ready\n");
  std::fflush(stdout);
  RosObjects objects;
  if (!setup.objects.empty()) {
    objects = {setup.objects.bodies, setup.objects.poses, setup.objects.sizes};
    fmt::print("node       {} object pose(s) out on {}/objectI (PoseStamped), boxes in the markers\n",
               setup.objects.bodies.size(), net.wire_topic(o.topics.objects_topic));
  }
  net.start_markers(pw.world, snapshots, setup.config.tool.semi_axes, objects);
  const RosBridgeStats& st = net.stats();
  const auto qos_problem = [&st] {
    const std::uint64_t n = st.qos_incompatible.load();
    return n == 0 ? std::string() : fmt::format("{} incompatible QoS ({})", n, qos_policy(st.qos_last_policy.load()));
  };
  const bool interrupted = run_live(rt, setup.planned, o.run.quiet, [&st, &qos_problem] {
    const std::string q = qos_problem();
    return fmt::format(" | poses {} | wrenches {}{}", st.poses_received.load(), st.wrenches_published.load(),
                       q.empty() ? "" : " | " + q);
  });
  net.stop_markers();
  fmt::print("\n{}       {} poses received ({} dropped: NaN/Inf), {} twists, {} wrenches and {} marker "
             "arrays published, {} pose publisher(s)\n", o.ros2 ? "ros2" : "ros1",
             st.poses_received.load(), st.poses_dropped.load(), st.twists_received.load(),
             st.wrenches_published.load(), st.markers_published.load(), st.pose_publishers.load());
  if (st.stamp_fallbacks.load() + st.stamp_rejected.load() > 0)
    fmt::print("stamps     {} poses without a usable header stamp (velocity from arrival times), {} with an "
               "impossible stamp step\n", st.stamp_fallbacks.load(), st.stamp_rejected.load());
  if (!qos_problem().empty())
    fmt::print(stderr, "warning: {}: a subscriber or publisher could not match the node's QoS (see --reliable, "
                       "--best-effort-output)\n", qos_problem());
  if (st.pose_publishers.load() > 1)
    fmt::print(stderr, "warning: {} publishers on {}: their poses interleaved (the newest sample wins)\n",
               st.pose_publishers.load(), net.wire_topic(o.topics.pose_topic));
  const std::string shutdown = net.shutdown_reason();
  if (!shutdown.empty())
    fmt::print(stderr, "node       ended: {}; the force was ramped to zero\n", shutdown);
  nlohmann::json extra = {{"poses_received", st.poses_received.load()}, {"poses_dropped", st.poses_dropped.load()},
                          {"twists_received", st.twists_received.load()},
                          {"wrenches_published", st.wrenches_published.load()},
                          {"markers_published", st.markers_published.load()},
                          {"pose_publishers", st.pose_publishers.load()},
                          {"stamp_fallbacks", st.stamp_fallbacks.load()},
                          {"stamp_rejected", st.stamp_rejected.load()},
                          {"qos_incompatible", st.qos_incompatible.load()},
                          {"qos_last_policy", qos_policy(st.qos_last_policy.load())},
                          {"shutdown_reason", shutdown}};
  return write_run_outputs(rt, o.run, so, pw, setup, interrupted, "node", {{o.ros2 ? "ros2" : "ros1", extra}});
}

#ifdef GSHAPTICS_HAVE_ROS2

int run_device_sim(DeviceSimOptions o) {
  const SceneOptions so = with_bundled_defaults(o.scene, "device-sim", ForceModelOptions{}.spec());
  const std::string out_dir = prepare_out_dir(o.out_dir, so.scene, {"device_log.csv", "device_summary.json"});
  const PreparedWorld pw = prepare_world(so, o.quiet);
  ProbeTrajectory traj = make_probe_trajectory(pw.world, is_scaled(so), o.sites, o.seed, o.tool_radius, ForceModelOptions{});
  const double duration = o.duration > 0 ? o.duration : traj.duration() + 0.5;
  SimulatedDeviceParams dp;
  dp.causality = o.topics.admittance ? Causality::kAdmittance : Causality::kImpedance;
  SimulatedDevice device(std::move(traj), dp);
  Ros2DeviceLink link(o.topics);
  fmt::print("device-sim waiting for a node on {} / {} ...\n", ros2_dds_topic(o.topics.pose_topic),
             ros2_dds_topic(o.topics.wrench_topic));
  std::fflush(stdout);
  if (!link.wait_for_node(o.wait))
    throw InputError(fmt::format("device-sim: no node matched {} and {} within {:.0f} s (is `gshaptics node "
                                 "--ros2` running with the same DDS config and domain?)",
                                 ros2_dds_topic(o.topics.pose_topic), ros2_dds_topic(o.topics.wrench_topic), o.wait));
  const StopSignals signals;
  DeviceLoopParams params;
  params.rate_hz = o.rate;
  params.duration_s = duration;
  const bool quiet = o.quiet;
  const DeviceLoopResult r = run_device_loop(
      device, link, params, &StopSignals::flag(),
      [quiet, duration](double t, std::uint64_t sent, std::uint64_t received, double force) {
        if (!quiet)
          fmt::print(stderr, "device-sim t {:5.1f}/{:.1f} s | sent {} | wrenches {} | |F| {:.2f} N\n", t,
                     duration, sent, received, force);
      });

  OutputStage stage(out_dir, {"device_log.csv", "device_summary.json"});
  write_tick_log_csv(stage.path("device_log.csv"), r.ticks, kDeviceLogColumns);
  const std::vector<double>& lat = r.latencies_us;
  nlohmann::json sj;
  sj["scene"] = so.scene;
  sj["rate_hz"] = o.rate;
  sj["poses_sent"] = r.poses_sent;
  sj["wrenches_received"] = r.wrenches_received;
  sj["control"] = o.topics.admittance ? "admittance" : "impedance";
  sj["setpoints_received"] = r.setpoints_received;
  const Setpoint& ls = r.last_setpoint;
  sj["last_setpoint"] = {{"position", {ls.position.x(), ls.position.y(), ls.position.z()}},
                         {"velocity", {ls.velocity.x(), ls.velocity.y(), ls.velocity.z()}}};
  sj["peak_force_n"] = r.peak_force;
  sj["interrupted"] = r.interrupted;
  sj["latency_us"] = {{"count", lat.size()},
                      {"p50", percentile(lat, 50)},
                      {"p99", percentile(lat, 99)},
                      {"max", lat.empty() ? 0 : *std::max_element(lat.begin(), lat.end())}};
  write_file_atomically(stage.path("device_summary.json"), sj.dump(2) + "\n");
  stage.commit();
  fmt::print("\ndevice-sim {} poses sent, {} wrenches received, peak |F| {:.2f} N{}\n", r.poses_sent,
             r.wrenches_received, r.peak_force,
             o.topics.admittance ? fmt::format("; {} setpoints followed (admittance)", r.setpoints_received) : "");
  fmt::print("latency    pose -> wrench round trip: p50 {:.0f} us, p99 {:.0f} us, max {:.0f} us ({} samples)\n",
             sj["latency_us"]["p50"].get<double>(), sj["latency_us"]["p99"].get<double>(),
             sj["latency_us"]["max"].get<double>(), lat.size());
  fmt::print("log        {}/device_log.csv\nsummary    {}/device_summary.json\n", out_dir, out_dir);
  return 0;
}

#endif  // GSHAPTICS_HAVE_ROS2

}  // namespace gshaptics::session
