#pragma once
#include <cstdio>
/// @file
/// The session layer (see world_session.h), probe runs: the force model a session renders with
/// (a RendererSpec plus the safety layer's limit and a device profile), the execution mode, the
/// seeded probe trajectory with scene-relative sizes, the diagnosis of a run without contact,
/// and the figure (tools/plot_probe_run.py).

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/force/force_model.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/session/world_session.h"
#include "gshaptics/sim/probe_run.h"
#include "gshaptics/sim/probe_trajectory.h"

namespace gshaptics::session {


/// The force model a command renders with, and the parameters of each model.
struct ForceModelOptions {
  RendererKind model = RendererKind::kProxy;  ///< --force-model (renderer_names())
  ForceParams force;            ///< the paper model's parameters
  ProxyParams proxy;            ///< the proxy's parameters
  double f_max = SafetyParams{}.f_max;  ///< --f-max: the safety layer's limit, N (every model)
  std::string profile;  ///< --device-profile: "" (none), desktop or room
  /// --materials: a material map (MaterialMap::load), read on the proxy; nullptr: none.
  std::shared_ptr<const MaterialMap> materials;
  /// The force options as given on a command line, each name followed by its value
  /// ("--stiffness", "500"), for a report's command line; empty from a library call.
  std::vector<std::string> given;
  /// The renderer the options name, with its parameters.
  [[nodiscard]] RendererSpec spec() const;
};

/// A --tool option, parsed once: the text as given (for summaries) and the tool it names.
struct ToolOption {
  std::string spec;   ///< "" : none given (a sphere of the tool radius)
  CompoundTool tool;  ///< parse_tool_spec(spec); count 0 when none given
  [[nodiscard]] bool given() const noexcept { return !spec.empty(); }
  /// Which kind of proxy renders it (a single part at the TCP, or none given: the one-part proxy).
  [[nodiscard]] ProxyTool proxy_tool() const noexcept {
    return given() && !tool.is_single_at_tcp() ? ProxyTool::kCompound : ProxyTool::kOnePart;
  }
};
/// Parses a --tool value (parse_tool_spec: sphere:R, ellipsoid:A,B,C, stylus:L,R, disc:R,T or a
/// JSON file). Throws InputError naming the spec or file.
[[nodiscard]] ToolOption parse_tool_option(const std::string& spec);

/// An option the user set, and the force model it belongs to (none: every model's).
struct GivenOption {
  std::string name;  ///< as on the command line, "--stiffness"
  std::optional<RendererKind> model;
};
/// Refuses (InputError naming each option, what it serves and why) the `given` options that do
/// not apply: another model's options than `model`'s, the proxy's surface-specific options
/// (surface_specific_proxy_fields()) with a `surface` they do not serve, and its tool-specific
/// options (tool_specific_proxy_fields()) with a `tool` they do not serve (no `tool`: a command
/// that renders both kinds, whose tool-specific options apply to one kind of its runs).
void refuse_options_not_applying(RendererKind model, std::optional<ProxyTool> tool, ProxySurface surface,
                                 std::span<const GivenOption> given);

/// How the servo step runs: inline (query inside the tick) or the decoupled worker, and, on
/// simulated time, the worker's latency in ticks.
struct ExecutionOptions {
  bool inline_query = RuntimeConfig{}.inline_query;
  int latency_ticks = RuntimeConfig{}.latency_ticks;
};
/// "inline" or "decoupled (worker thread)" / "decoupled, N tick(s) latency" on simulated time.
std::string describe_execution(const ExecutionOptions& o, bool simulated);


/// "impedance: ..." or "admittance: virtual tool M kg, B N s/m, ..." for the printed header;
/// `simulated`: the device is the simulated one (says which causality it has).
std::string describe_control(const ControlParams& c, bool simulated);
/// The control scheme for summaries: {"mode", "virtual_mass_kg", "virtual_damping_ns_per_m"}.
nlohmann::json control_json(const ControlParams& c);
/// A log's columns under `c`: admittance control adds the setpoint (kColumnsAdmittance).
unsigned log_columns(unsigned columns, const ControlParams& c);

/// Warns when the world is larger than the --device-profile's workspace, with the --reg-scale
/// that fits it.
void warn_if_outside_profile(const PreparedWorld& w, const ForceModelOptions& o);

/// ProbeParams::first_touch on the seen solid of `world` (the proxy's --surface seen): the
/// sphere of `tool_radius` moved from a start in free space meets it where its leading point
/// first reaches half transmittance, seen from the start (SeenSolid::first_inside). Builds the
/// solid once (allocates); the function keeps it.
std::function<double(const Eigen::Vector3d&, const Eigen::Vector3d&, double)> seen_first_touch(
    const CollisionWorld& world, double tool_radius);

/// ProbeParams::tool_touch for a compound tool held at the world's orientation: on the seen
/// solid (`seen`: the proxy's --surface seen) the first of its parts' fronts to meet it, over
/// each part's centre line and the seen proxies' footprint lines (seen_footprint), each pushed
/// as SeenCompoundProxy pushes a part (SeenSolid::push, its eye up to `seen_window` times the
/// tool's largest semi-axis behind: ProxyParams::seen_window); on the world's ellipsoids the
/// first overlap of any part (ContactQuery::any_contact), stepped at an eighth of its smallest
/// semi-axis. Throws InputError for an invalid tool. Builds its solid or query once; the
/// function keeps it.
std::function<double(const Eigen::Vector3d&, const Eigen::Vector3d&, double)> tool_first_touch(
    const CollisionWorld& world, const CompoundTool& tool, bool seen, double seen_window = ProxyParams{}.seen_window);

/// The seeded probe trajectory; tool_radius <= 0 picks 1 % of the scene's robust extent.
/// With a compound `tool` (not nullptr, not a single part at the TCP), sites where another part
/// of it meets the object before the tip does are left out (ProbeParams::tool_touch).
/// On the proxy's seen surface the touch points lie on the seen solid (seen_first_touch).
/// Speeds scale with the tool so that any scene unit gives a similar run. The simulated hand
/// presses to half of `force`'s limit (f_max) through the proxy's coupling stiffness
/// (press_depth_for_force), so the peaks sit in the middle of the device's range on any scene.
/// Prints one line. The probe approaches along -CollisionWorld::up(), the registered world's up.
/// `scaled`: a registration or --reg-scale was given (the world is meant to be in metres).
/// `report`: where the line goes (nullptr: nowhere; the warnings go to stderr). `up`: the
/// approach's up instead of the world's.
ProbeTrajectory make_probe_trajectory(const CollisionWorld& world, bool scaled, int sites, std::uint64_t seed,
                                      double tool_radius, const ForceModelOptions& force, std::FILE* report = stdout,
                                      const std::optional<Eigen::Vector3d>& up = std::nullopt,
                                      const CompoundTool* tool = nullptr);

/// After a probe run that made no contact: the likely causes, from the numbers at hand (units,
/// up axis, opacity filter, tool size), one line each, printed to stderr.
void print_no_contact_hints(const PreparedWorld& w, const SceneOptions& so, double tool_radius);

/// Runs tools/plot_probe_run.py on a log and summary; false (with a message) when it fails.
bool plot_run(const std::string& csv, const std::string& summary, const std::string& png,
              const std::string& command);

/// `gshaptics simulate`: the main job's options.
/// What `simulate` runs: the paper's probe run of a scene, or the push scenario (a box of
/// Gaussians pushed across a floor, its dynamics on MuJoCo; session/object_session.h).
enum class SimulateScenario { kProbe, kPush };

struct SimulateOptions {
  SimulateScenario scenario = SimulateScenario::kProbe;
  /// The push scenario's box: mass (kg) and friction against the floor (unset: PushScenario's).
  std::optional<double> object_mass, object_friction;
  SceneOptions scene;
  std::string out_dir;
  int sites = ProbeParams{}.sites;
  std::uint64_t seed = ProbeParams{}.seed;
  double tool_radius = 0;  // 0: 1% of the scene's robust extent (or --tool's largest semi-axis)
  ToolOption tool;         // --tool (parse_tool_option); none given: the sphere
  double rate = RuntimeConfig{}.rate_hz;
  ForceModelOptions force;
  ExecutionOptions exec;
  SafetyParams safety;
  /// --control: the simulated device's causality and the servo step's control scheme.
  ControlParams control;
  bool no_plot = false;
  bool quiet = false;
};

/// The probe run of `simulate` on a built world, with no files written: the seeded trajectory
/// (make_probe_trajectory, `o`'s sites, seed, tool radius, force limit and stiffness; `up`
/// instead of the world's when given) and the run through the servo step on simulated time
/// (sim/probe_run.h) with `o`'s rate, force model, execution mode, safety layer and tool.
/// `scaled`: the world is meant to be in metres (only a warning depends on it); `report`: where
/// the trajectory's line goes (nullptr: nowhere); `progress` gets the fraction done;
/// `make_renderer`: a scene with objects (scene_objects().make_renderer; the sites are on `world`).
struct ProbeSessionResult {
  ProbeTrajectory trajectory;
  ProbeRunResult run;
};
ProbeSessionResult simulate_probe(const CollisionWorld& world, const SimulateOptions& o, bool scaled,
                                  std::FILE* report = stdout, const std::optional<Eigen::Vector3d>& up = std::nullopt,
                                  const std::function<void(double)>& progress = {},
                                  const RendererFactory& make_renderer = {});

/// The main job: a seeded probe trajectory over the world, a simulated hand on a simulated
/// admittance device, every tick through the runtime's servo step on simulated time; writes
/// probe_log.csv, summary.json and probe_run.png (the paper's Fig. 5) and prints the episodes.
/// Returns the exit status (0; 1: no contact or the figure failed; kExitOutputsLost).
/// Throws InputError for bad options or input files.
int run_simulate(SimulateOptions o);

}  // namespace gshaptics::session
