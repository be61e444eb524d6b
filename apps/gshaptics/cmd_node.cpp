// `gshaptics node [SCENE] --ros2|--ros1` and `gshaptics device-sim [SCENE] --ros2`: the paper's
// two-machine split (Sec. IV) over ROS 2 / DDS or ROS 1. The node runs the servo loop and the collision
// worker against a device whose pose arrives over the network, publishes the wrench at the servo
// rate and the tool + colliding Gaussians as a MarkerArray. device-sim is the simulated
// admittance device and hand as a separate process that publishes poses and applies the wrench.

#include <cstdint>
#include <memory>

#include "commands.h"
#include "gshaptics/error.h"
#include "gshaptics/session_ros/node_session.h"
#include "options.h"

namespace gshaptics::cli {

namespace {

void add_topic_options(CLI::App& cmd, RosBridgeOptions& t) {
  cmd.add_option("--pose-topic", t.pose_topic, "geometry_msgs/PoseStamped of the tool")->capture_default_str();
  cmd.add_option("--twist-topic", t.twist_topic, "geometry_msgs/TwistStamped of the tool (optional)")->capture_default_str();
  cmd.add_option("--wrench-topic", t.wrench_topic, "geometry_msgs/WrenchStamped to the device")->capture_default_str();
  cmd.add_option("--markers-topic", t.markers_topic, "visualization_msgs/MarkerArray: tool and contacts")->capture_default_str();
  cmd.add_option("--sensor-topic", t.sensor_topic,
                 "--control admittance, ROS 2: geometry_msgs/WrenchStamped of the force/torque sensor at the "
                 "robot's handle (the user's wrench, N; ros2_control's force_torque_sensor_broadcaster)")
      ->capture_default_str();
  cmd.add_option("--setpoint-topic", t.setpoint_topic,
                 "--control admittance, ROS 2: geometry_msgs/PoseStamped setpoint for the robot's position controller")
      ->capture_default_str();
  cmd.add_option("--setpoint-twist-topic", t.setpoint_twist_topic,
                 "--control admittance, ROS 2: geometry_msgs/TwistStamped setpoint velocity (feed-forward)")
      ->capture_default_str();
  cmd.add_option("--frame-id", t.frame_id, "header.frame_id of what is published")->capture_default_str();
  cmd.add_flag("--reliable", t.reliable_input,
               "ROS 2 only: read poses RELIABLE instead of BEST_EFFORT (best-effort matches either kind of writer)");
  cmd.add_flag("--best-effort-output", [&t](std::int64_t n) { t.reliable_output = n == 0; },
               "ROS 2 only: write wrenches and markers BEST_EFFORT instead of RELIABLE keep-last --depth "
               "(reliable serves either kind of subscriber)");
  cmd.add_option("--depth", t.depth, "ROS 2 only: keep-last depth of the streams")->capture_default_str()->check(CLI::Range(1, 1000));
  cmd.add_option("--input-timeout", t.input_timeout,
                 "No pose for this long and the device's data stops; the force is zero --device-timeout later "
                 "(0.09 + 0.01 = 0.1 s by default), s")
      ->capture_default_str()->check(check::range(0.001, 10.0));
  cmd.add_option("--marker-rate", t.marker_hz, "MarkerArrays per second")->capture_default_str()->check(check::range(1.0, 200.0));
}

}  // namespace

void register_node(CLI::App& app) {
  auto o = std::make_shared<NodeOptions>();
  CLI::App* cmd = app.add_subcommand(
      "node",
      "The haptic node of a two-machine setup (paper Sec. IV): the servo loop and collision "
      "worker run here; the device's pose arrives over ROS 2 (PoseStamped, optional "
      "TwistStamped), the wrench goes back (WrenchStamped) at the servo rate, and the tool plus "
      "colliding Gaussians go out as a MarkerArray (ROS 1: the same topics through roscpp and "
      "the master at ROS_MASTER_URI). Runs until Ctrl-C or --duration; writes the run's log and "
      "summary like `run`. The device side: `gshaptics device-sim --ros2` or your driver.");
  o->run.device = "ros";
  add_runtime_options(*cmd, o->run,
                      "ros: the device's pose arrives over ROS (default)" + registry_device_help(true) +
                          ": a desktop device on this machine drives the runtime, and the node "
                          "publishes its wrench and markers (e.g. for a headset's viewer)");
  auto* f2 = cmd->add_flag("--ros2", o->ros2, "Speak ROS 2 over DDS (Cyclone DDS; ROS 2 Humble message layouts)");
  auto* f1 = cmd->add_flag("--ros1", o->ros1, "Speak ROS 1 (roscpp; master at ROS_MASTER_URI)");
  f2->excludes(f1);
  cmd->add_option("--domain", o->topics.domain, "ROS 2 only: DDS domain id (ROS_DOMAIN_ID); -1: the DDS default")->check(CLI::Range(-1, 232));
  cmd->add_option("--node-name", o->topics.node_name,
                  "ROS 1: the node's name at the master (two nodes on one master need two names; __name:= too)")
      ->capture_default_str();
  add_topic_options(*cmd, o->topics);
  add_object_option(*cmd, o->run.scene);
  cmd->add_option("--objects-topic", o->topics.objects_topic,
                  "With --object: object I's pose goes out on TOPIC/objectI (geometry_msgs/PoseStamped) at the marker rate")
      ->capture_default_str();
  cmd->footer(
      "ROS arguments pass through: ROS 1 remappings and names (pose:=/arm1/pose, __ns:=/arm1, "
      "__name:=left), or ROS 2's --ros-args -r FROM:=TO (also -r __ns:=/arm1). Relative topic "
      "names (the defaults) resolve in the node's namespace (ROS 1: also ROS_NAMESPACE).");
  cmd->callback([o, cmd] {
    o->topics.ros_args = ros_arguments();
    if (o->ros1)
      for (const char* ros2_only : {"--domain", "--depth", "--reliable", "--best-effort-output"})
        if (cmd->count(ros2_only) > 0)
          throw InputError(std::string("node: ") + ros2_only +
                           " is a ROS 2 (DDS) option; ROS 1 has no counterpart here (roscpp over TCP, queues of "
                           "64 poses and 64 wrenches)");
    if (const int rc = run_node(*o)) set_exit_code(rc);
  });
}

#ifdef GSHAPTICS_HAVE_ROS2

void register_device_sim(CLI::App& app) {
  auto o = std::make_shared<DeviceSimOptions>();
  CLI::App* cmd = app.add_subcommand(
      "device-sim",
      "The simulated device and hand of `simulate` as a separate process on the network: publishes "
      "the device's pose and twist at --rate, applies the wrench it receives (or, with --control "
      "admittance, publishes its force sensor and follows the setpoint it receives), "
      "follows the same seeded probe trajectory (so give it the same scene and options as the "
      "node). Records the round-trip pose-to-wrench latency. Writes device_log.csv and "
      "device_summary.json.");
  cmd->add_option("scene", o->scene.scene, "Scene file (default: bundled data/truck.splat)");
  add_world_options(*cmd, o->scene);
  add_world_cache_option(*cmd, o->scene);
  cmd->add_flag("--ros2", o->ros2, "Speak ROS 2 over DDS (the only transport of device-sim)")->required();
  cmd->add_option("--domain", o->topics.domain, "DDS domain id (ROS_DOMAIN_ID); -1: the DDS default")->check(CLI::Range(-1, 232));
  add_topic_options(*cmd, o->topics);
  cmd->add_option("--rate", o->rate, "Device rate, Hz")->capture_default_str()->check(check::range(10.0, 20000.0));
  cmd->add_option("--duration", o->duration, "Run length, s (default: one pass of the trajectory)")->check(check::positive());
  cmd->add_option("--sites", o->sites, "Contact sites")->capture_default_str()->check(CLI::Range(1, 100));
  cmd->add_option("--seed", o->seed, "Seed of the site choice")->capture_default_str();
  cmd->add_option("--tool-radius", o->tool_radius, "Tool radius (default: 1% of the scene's extent)")->check(check::positive());
  cmd->add_option("--wait", o->wait, "Wait this long for a node to match, s")->capture_default_str()->check(check::non_negative());
  cmd->add_option("--out", o->out_dir, "Output folder (default: runs/<name>-<extension>, e.g. runs/truck-splat)");
  cmd->add_flag("--quiet", o->quiet, "No progress line");
  cmd->add_option_function<std::string>(
         "--control", [o](const std::string& v) { o->topics.admittance = v == "admittance"; },
         "impedance: an ideal mass-damper that applies the wrench it receives. admittance: a robot under a "
         "position servo that follows the node's setpoint and publishes its force/torque sensor (the node "
         "runs with --control admittance). Default: impedance")
      ->check(CLI::IsMember({"impedance", "admittance"}));
  cmd->callback([o] {
    if (const int rc = run_device_sim(*o)) set_exit_code(rc);
  });
}

#endif  // GSHAPTICS_HAVE_ROS2

}  // namespace gshaptics::cli
