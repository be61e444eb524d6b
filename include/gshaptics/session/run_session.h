#pragma once
/// @file
/// The session layer (see world_session.h), live and replayed runs: the runtime's options, the
/// device a --device value names (through the device registry) under its workspace mapping, the
/// tool's start point, the runtime configuration, the live loop with its status line and signal
/// handling, and the outputs of a run (servo_log.csv, run_summary.json, run.png).

#include <atomic>
#include <csignal>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "gshaptics/device/stream_device.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/servo/simulated_runtime.h"
#include "gshaptics/session/probe_session.h"

namespace gshaptics::session {


/// Turns SIGINT/SIGTERM into a flag for the lifetime of the object (restoring the old handlers
/// after), so a run can stop cleanly with the device at zero force.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
  /// The signal received since construction (0: none). Async-signal-safe flag, any thread.
  [[nodiscard]] static int received() noexcept;
  /// The flag itself, for library loops that poll a stop flag.
  [[nodiscard]] static const std::atomic<int>& flag() noexcept;

 private:
  struct sigaction old_int_ {}, old_term_ {};
};

struct RuntimeOptions {
  SceneOptions scene;
  std::string device = "sim";
  double rate = RuntimeConfig{}.rate_hz;
  double duration = 0;
  ExecutionOptions exec;
  bool simulated_time = false;  ///< run on simulated time (SimulatedRuntime): sim and replay devices
  double candidate_cache = 0.25;  ///< candidate cache margin, fraction of the tool radius
  int query_threads = 0;          ///< 0: default_query_threads()
  int sites = ProbeParams{}.sites;
  std::uint64_t seed = ProbeParams{}.seed;
  double tool_radius = 0;
  /// --tool: a compound tool (collision/compound_tool.h: sphere:R, ellipsoid:A,B,C,
  /// stylus:L,R, disc:R,T or FILE.json), parsed once; none given: a sphere of tool_radius.
  ToolOption tool;
  ForceModelOptions force;
  SafetyParams safety;
  /// --control, --virtual-mass, --virtual-damping: impedance (command force) or admittance
  /// control (command the virtual tool's position; servo/admittance.h).
  ControlParams control;
  RealtimeOptions realtime;
  bool no_pin = false;
  double spin_us = 0;
  double log_seconds = 0;  ///< 0: the whole run (the runtime's default)
  std::string workspace_scale, workspace_offset;  ///< "" : no workspace mapping
  /// "W,X,Y,Z": the device's axes in the world (replaces the default, device z -> world up); "": default.
  std::string workspace_rotation;
  int clutch_button = -1;
  double bubble_radius = 0, bubble_gain = 0;
  std::string haply_url = "ws://127.0.0.1:10001/";  ///< the Haply Inverse Service
  bool haply_allow_uncalibrated = false;  ///< DeviceOptions::haply_allow_uncalibrated
  std::string out_dir;
  bool no_plot = false;
  bool quiet = false;
};

/// The device a --device value names, made for a world. `mouse` is set for --device mouse
/// (allowed only when `allow_mouse`).
struct RuntimeSetup {
  std::unique_ptr<HapticDevice> inner;  ///< the device under a workspace mapping, when one is set
  std::unique_ptr<HapticDevice> device;
  /// A device that another wrapper around it uses (node: the mapped local device under the tee
  /// that also publishes its wrench); kept alive with the setup.
  std::unique_ptr<HapticDevice> inner_keep;
  StreamDevice* mouse = nullptr;  ///< the device the page steers (mouse or XR controller)
  bool xr = false;                ///< --device xr: the page's VR controller steers it
  Eigen::Vector3d mouse_start = Eigen::Vector3d::Zero();  ///< where the mouse device starts
  /// The device's workspace in the world at start (hardware devices with a known workspace).
  std::optional<Eigen::AlignedBox3d> workspace_box;
  double tool_radius = 0;
  double planned = 0;  ///< s, 0: open-ended
  /// The simulated hand (--device sim): when it first reaches a probe site and how long a pass
  /// is, s (-1: not a probe run).
  double first_site = -1, pass = -1;
  RuntimeConfig config;
  /// The scene's rigid objects (--object): config.make_renderer is theirs; their poses' channel.
  SceneObjects objects;
};
/// Checks --device before the scene loads (throws InputError naming the option).
void check_device_option(const std::string& device, bool allow_mouse);
/// Everything about the device that can be checked before the scene is loaded: the --device
/// value, the workspace options, and the device itself when the registry makes it (a hardware
/// device's vendor library, a replay file), opened here once: hand it to make_runtime_setup.
/// Null for the devices that need the scene (sim) and the viewer's streams (mouse, xr). Throws
/// InputError.
[[nodiscard]] std::unique_ptr<HapticDevice> validate_runtime_options(const RuntimeOptions& o, bool allow_mouse);
/// "; GRAMMAR: summary" for every kind of the device registry (only the hardware ones when
/// `hardware_only`), for --device help texts.
[[nodiscard]] std::string registry_device_help(bool hardware_only);
/// True for the desktop haptic devices: haply[:N], dhd[:N], openhaptics[:NAME].
[[nodiscard]] bool is_hardware_device(const std::string& device);
/// Opens the device a --device value names through the device registry (a hardware device or a
/// replay log; InputError: what is missing, what to install).
[[nodiscard]] std::unique_ptr<HapticDevice> make_hardware_device(const RuntimeOptions& o);
/// Where a tool starts over a world: above its most upward-facing probe site (or above its
/// middle), 12 tool radii up. World frame.
[[nodiscard]] Eigen::Vector3d tool_start_point(const PreparedWorld& pw, double tool_radius);
/// The device, its workspace mapping and the runtime configuration for a run over `pw`.
/// `opened`: the registry's device validate_runtime_options() opened (null: opened here).
/// The scene's rigid objects (so.objects, cut into pw) for a run of `s`: setup.objects, their
/// renderer factory as s.config.make_renderer (set s.config first), and a track of their poses
/// for the run's objects_log.csv. Nothing without objects. Throws as scene_objects().
void attach_scene_objects(RuntimeSetup& s, const PreparedWorld& pw, const SceneOptions& so, double rate_hz);
RuntimeSetup make_runtime_setup(const RuntimeOptions& o, const SceneOptions& so, const PreparedWorld& pw,
                                bool allow_mouse, std::unique_ptr<HapticDevice> opened = nullptr);

/// With any --workspace-* / --clutch-button / --bubble-* option, or always for a hardware device
/// (`hardware`), puts `s.device` under a WorkspaceMapping (the original moves to `s.inner`).
/// A hardware device's frame (z up) is turned to the world's up and its origin placed at
/// `default_offset` unless --workspace-offset says otherwise. InputError for the mouse device.
void wrap_in_workspace_mapping(const RuntimeOptions& o, RuntimeSetup& s, bool hardware = false,
                               const Eigen::Vector3d& default_offset = Eigen::Vector3d::Zero(),
                               const Eigen::Vector3d& world_up = Eigen::Vector3d::UnitZ());

/// The runtime configuration from the options, for a tool of `tool_radius` and a run of
/// `planned` seconds (0: open-ended).
RuntimeConfig runtime_config_from(const RuntimeOptions& o, double tool_radius, double planned);

/// Starts the runtime, shows the live status line (plus `extra()` when given) until it ends,
/// and turns SIGINT/SIGTERM into a clean stop. Returns true when a signal ended it.
bool run_live(HapticRuntime& rt, double planned, bool quiet, const std::function<std::string()>& extra = {});

/// Resolves and checks `o.out_dir` before any work (see prepare_out_dir) and clears the files a
/// run writes there.
void prepare_run_out_dir(RuntimeOptions& o, const SceneOptions& so);

/// Writes servo_log.csv and run_summary.json (and run.png unless no_plot) into the output
/// folder and prints the summary. Returns the exit status: 0, 1 when plotting failed, or
/// kExitOutputsLost (the folder is then left as it was).
/// `extra` is merged into run_summary.json.
int write_run_outputs(const HapticRuntime& rt, const RuntimeOptions& o, const SceneOptions& so,
                       const PreparedWorld& pw, const RuntimeSetup& setup, bool interrupted,
                       const std::string& command, const nlohmann::json& extra = nlohmann::json::object());
/// The same for a run on simulated time (`run --simulated-time`).
int write_run_outputs(const SimulatedRuntime& rt, const RuntimeOptions& o, const SceneOptions& so,
                       const PreparedWorld& pw, const RuntimeSetup& setup, const std::string& command);

}  // namespace gshaptics::session
