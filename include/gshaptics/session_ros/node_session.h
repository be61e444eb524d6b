#pragma once
/// @file
/// The session layer (see world_session.h), ROS: the haptic node of the paper's two-machine split
/// (Sec. IV) over ROS 2 / DDS or ROS 1, and the simulated device on the other side of it
/// (device-sim, ROS 2). Built only with a ROS bridge (target gshaptics_session_ros, not installed,
/// as the bridges are not).

#include <cstdint>
#include <string>

#include "gshaptics/net/ros_bridge.h"
#include "gshaptics/session/run_session.h"
#ifdef GSHAPTICS_HAVE_ROS2
#include "gshaptics/ros2/device_sim.h"
#endif

namespace gshaptics::session {

/// `gshaptics node`: the runtime and collision worker here, the device's pose over ROS (or a
/// desktop device on this machine, whose wrench and markers the node publishes).
struct NodeOptions {
  RuntimeOptions run;
  bool ros2 = false, ros1 = false;
  RosBridgeOptions topics;
};

/// Runs the node until the run ends (--duration, a signal) and writes its outputs. Returns the
/// exit status (0; 1: the figure failed; kExitOutputsLost). Throws InputError for bad options
/// or a build without the transport asked for.
int run_node(NodeOptions o);

#ifdef GSHAPTICS_HAVE_ROS2
/// `gshaptics device-sim`: the simulated admittance device and hand of `simulate` in a process
/// of its own, publishing poses over ROS 2 and applying the wrench it receives.
struct DeviceSimOptions {
  SceneOptions scene;
  bool ros2 = false;
  Ros2Options topics;
  double rate = RuntimeConfig{}.rate_hz;
  double duration = 0;
  int sites = ProbeParams{}.sites;
  std::uint64_t seed = ProbeParams{}.seed;
  double tool_radius = 0;
  double wait = 30;
  std::string out_dir;
  bool quiet = false;
};

/// Waits for a node, runs the device loop and writes device_log.csv and device_summary.json.
/// Returns the exit status. Throws InputError when no node matches within `wait`.
int run_device_sim(DeviceSimOptions o);
#endif

}  // namespace gshaptics::session
