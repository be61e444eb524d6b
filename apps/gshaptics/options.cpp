#include "options.h"

#include <fmt/format.h>

#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <vector>
#include <thread>
#include <string>

#include "gshaptics/device/device_registry.h"
#include "gshaptics/device/device_profile.h"
#include "gshaptics/servo/query_pool.h"
#include "gshaptics/force/floater_rule.h"

namespace gshaptics::cli {

namespace check {
namespace {
CLI::Validator finite_number(const std::string& what, std::function<bool(double)> ok) {
  return CLI::Validator(
      [what, ok](std::string& text) -> std::string {
        double x = 0;
        std::size_t used = 0;
        try {
          x = std::stod(text, &used);
        } catch (...) {
          used = 0;
        }
        if (used == 0 || text.find_first_not_of(" \t", used) != std::string::npos)
          return "expected a number, got '" + text + "'";
        if (!std::isfinite(x) || !ok(x)) return "must be " + what + ", got '" + text + "'";
        return std::string();
      },
      what);
}
}  // namespace

CLI::Validator positive() {
  return finite_number("a finite number > 0", [](double x) { return x > 0; });
}
CLI::Validator non_negative() {
  return finite_number("a finite number >= 0", [](double x) { return x >= 0; });
}
CLI::Validator range(double lo, double hi) {
  return finite_number(fmt::format("a finite number in [{:g}, {:g}]", lo, hi),
                       [lo, hi](double x) { return x >= lo && x <= hi; });
}
}  // namespace check

void add_object_option(CLI::App& app, SceneOptions& o) {
  app.add_option_function<std::vector<std::string>>(
         "--object",
         [&o](const std::vector<std::string>& specs) {
           for (const std::string& spec : specs) o.objects.push_back(parse_object_spec(spec, "--object"));
         },
         fmt::format("A rigid object, moved by MuJoCo (repeatable, at most {}): cut from the scene, "
                     "box:X0,Y0,Z0,X1,Y1,Z1 (the Gaussians whose world-frame centre is in the box, m), "
                     "obox:CX,CY,CZ,HX,HY,HZ,QW,QX,QY,QZ (an oriented box: centre, half extents, rotation) or "
                     "indices:I,J,... (the file's Gaussians), or a splat file of its own, "
                     "file:PATH[:registration=FILE.json] (placed like the scene, --up included); then optional "
                     ":mass=KG (default {:g}), :friction=MU (default {:g}) and :hulls=N (convex pieces for a concave object, "
                     "default 1). Objects rest on the ground fitted to the scene "
                     "around them; a cut leaves a hole where the object stood",
                     kMaxObjects, kDefaultObjectMass, kDefaultObjectFriction))
      ->type_name("SPEC")->allow_extra_args(false);
  app.add_option_function<std::vector<std::string>>(
         "--support",
         [&o](const std::vector<std::string>& specs) {
           for (const std::string& spec : specs) o.supports.push_back(parse_object_spec(spec, "--support"));
         },
         "A static part of the scene the objects stand on, a table top (box:..., obox:... or indices:..., "
         "repeatable): it stays in the scene as it was, and MuJoCo gets its convex hull, so an object pushed "
         "off its edge falls to the ground (then fitted around the supports: the floor under the table)")
      ->type_name("SPEC")->allow_extra_args(false);
  app.add_option_function<std::string>(
         "--objects",
         [&o](const std::string& path) {
           ObjectSpecList list = load_object_specs(path);
           for (ObjectSpec& spec : list.objects) o.objects.push_back(std::move(spec));
           for (ObjectSpec& spec : list.supports) o.supports.push_back(std::move(spec));
         },
         "Rigid objects from a JSON file, added to the --object ones: {\"objects\": [{\"box\": [X0, Y0, Z0, X1, Y1, "
         "Z1]} or {\"obox\": {\"center\", \"half\", \"rotation\"}} or {\"indices\": [...]} or {\"file\": PATH, \"registration\": PATH or {...}}, each with optional "
         "\"mass\", \"friction\" and \"hulls\"], \"supports\": [as --support]} (paths relative to the JSON's folder; docs/usage.md)")
      ->type_name("FILE");
  app.add_option("--objects-mjcf", o.objects_mjcf,
                 "Write the objects' MuJoCo model here (MJCF: each object a body of convex hulls, the supports, the "
                 "ground plane and the contact options), to look at in MuJoCo's own viewer")
      ->type_name("FILE");
}

void add_world_options(CLI::App& app, SceneOptions& o) {
  app.add_option("--min-opacity", o.min_opacity,
                 "Keep Gaussians with opacity > T (paper Sec. III-A: 0.1..0.3). Default: 0.0039 (1/255, every "
                 "Gaussian a viewer draws) for the proxy on the seen solid, the default; 0.2 with --surface "
                 "ellipsoids, with --force-model paper and for the commands without a force model")
      ->check(check::range(0.0, 1.0));
  app.add_option("--sigma", o.sigma, "Collision ellipsoid at K sigma (semi-axes K * scale)")
      ->capture_default_str()->check(check::positive());
  app.add_option("--registration", o.registration_file,
                 "JSON similarity transform scene->world: {\"scale\": s, \"rotation\": [w,x,y,z] "
                 "or \"matrix\": 3x3, \"translation\": [x,y,z]} (paper eq. 3)");
  app.add_option("--reg-scale", o.reg_scale, "Registration scale s (overrides the file)")->type_name("FLOAT");
  app.add_option("--reg-rotation", o.reg_rotation, "Registration rotation W,X,Y,Z (overrides)");
  app.add_option("--reg-translation", o.reg_translation, "Registration translation X,Y,Z (overrides)");
  app.add_option("--up", o.up,
                 "Turn the scene's up axis to world +z before the registration: none, auto (from "
                 "the file's convention: -y for PLY/.splat, +y for SPZ), y-down, y-up, z-up, "
                 "z-down, x-up, x-down")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "auto", "y-down", "y-up", "z-up", "z-down", "x-up", "x-down"}));
}

void add_world_cache_option(CLI::App& app, SceneOptions& o) {
  app.add_option("--world-cache", o.world_cache,
                 "Keep the built collision world in DIR (or 'auto': ~/.cache/gshaptics/worlds) and "
                 "open it from there next time with mmap, skipping load, filter and BVH build; keyed "
                 "by the scene's content and every world option, checked on open, rebuilt when stale "
                 "or damaged; a folder that cannot be written only costs the rebuild");
}

void add_execution_options(CLI::App& cmd, ExecutionOptions& o, bool simulated) {
  const bool inline_default = RuntimeConfig{}.inline_query;
  cmd.add_flag_callback("--inline", [&o] { o.inline_query = true; },
                        std::string("Run the query inside the servo tick") + (inline_default ? " (default)" : ""));
  cmd.add_flag_callback("--decoupled", [&o] { o.inline_query = false; },
                        std::string("Run the query on the collision worker (the paper's split; the force is one "
                                    "to two ticks old)") + (inline_default ? "" : " (default)"));
  if (simulated)
    cmd.add_option("--latency", o.latency_ticks,
                   "Simulated time, decoupled mode: ticks from a pose to the first tick that renders its result "
                   "(a real-time run's worker answers within 1-2)")
        ->capture_default_str()->check(CLI::Range(1, 100));
}

void add_tool_option(CLI::App& cmd, ToolOption& tool, const std::string& help) {
  cmd.add_option_function<std::string>("--tool", [&tool](const std::string& v) { tool = parse_tool_option(v); }, help)
      ->type_name("SPEC");
}

void add_force_options(CLI::App& cmd, ForceModelOptions& o, const ToolOption* tool) {
  const std::size_t first = cmd.get_options().size();  // (the options below are the force options)
  std::map<std::string, RendererKind> models;
  for (const RendererName& r : renderer_names()) models.emplace(r.name, r.kind);
  cmd.add_option("--force-model", o.model,
                 std::string("Force model: proxy (god-object on the Gaussians, virtual coupling in N/m) "
                             "or paper (the paper's penalty force, eq. 7-11). Default: ") +
                     std::string(renderer_name(ForceModelOptions{}.model)))
      ->transform(CLI::CheckedTransformer(models));
  ForceParams& force = o.force;
  cmd.add_option("--k-base", force.k_base, "paper: base stiffness k_base, N per contact (eq. 9)")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--damping", force.damping, "paper: damping D, N s/m (eq. 10)")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--f-max", o.f_max,
                 "Force limit F_max, N: the safety layer's, for every model (a device's own lower limit binds too)")
      ->capture_default_str()->check(check::positive());
  cmd.add_option("--tau-normal", force.tau_normal, "paper: time constant of the normal EMA, s")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--tau-opacity", force.tau_opacity, "paper: time constant of the opacity EMA, s")
      ->capture_default_str()->check(check::non_negative());
  ProxyParams& p = o.proxy;
  cmd.add_option("--stiffness", p.stiffness, "proxy: coupling stiffness k_c, N/m")
      ->capture_default_str()->check(check::positive());
  cmd.add_option("--coupling-damping", p.damping, "proxy: coupling damping b_c, N s/m (passive above k_c T / 2)")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--mu-s", p.mu_s, "proxy: static friction coefficient (0: off)")->capture_default_str()->check(check::non_negative());
  cmd.add_option("--mu-k", p.mu_k, "proxy: kinetic friction coefficient (<= --mu-s)")->capture_default_str()->check(check::non_negative());
  cmd.add_option_function<std::string>(
         "--materials", [&o](const std::string& v) { o.materials = std::make_shared<const MaterialMap>(MaterialMap::load(v)); },
         "proxy: a material map (JSON: materials with stiffness, damping, mu_s, mu_k, viscosity, texture and vibration, "
         "assigned to boxes, spheres, Gaussian indices or colours of the scene; docs/usage.md). The properties under the proxy blend by weight; what a material "
         "leaves out, and every surface no region claims, keeps --stiffness, --coupling-damping, --mu-s, --mu-k")
      ->type_name("FILE");
  cmd.add_flag("--opacity-stiffness", p.opacity_stiffness, "proxy, --surface ellipsoids: scale k_c by the blocking Gaussians' opacity (paper eq. 9)");
  cmd.add_option("--substeps", p.substeps, "proxy, --surface ellipsoids: sweeps per tick")->capture_default_str()->check(CLI::Range(1, 16));
  cmd.add_option_function<std::string>(
         "--energy-bound", [&p](const std::string& v) { p.energy_bound = v == "on"; },
         "proxy, --surface ellipsoids: the shaded normal's turns under the loaded coupling spring add no energy the contact's "
         "earlier turns did not take out (SpringEnergyBound). Default: on")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option("--device-shading", p.device_shading,
                 "proxy, --surface ellipsoids: where the shaded normal turns slowly, also read it where the device would rest, at most "
                 "this many tool radii from the proxy, and blend the two while they agree (0: off)")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option_function<std::string>(
         "--corner-normal", [&p](const std::string& v) { p.corner_normal = v == "on"; },
         "proxy, --surface ellipsoids: at a clean convex corner of the Gaussians (three faces) the force turns to the patch's "
         "support normal, which stays in the corner's normal cone (off: the shaded field). Default: on")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option_function<std::string>(
         "--crest-hold", [&p](const std::string& v) { p.crest_hold = v == "on"; },
         "proxy, --surface ellipsoids: pressed into a clean convex edge or corner of the Gaussians (the spring inside its normal cone, "
         "the device moving along the spring), the proxy holds where it rests, as a god-object on a polyhedron "
         "does (off: it slides off the crest). Default: on")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option_function<std::string>(
         "--overhang-falloff", [&p](const std::string& v) { p.overhang_falloff = v == "on"; },
         "proxy, --surface ellipsoids: where a disc of the other face overhangs a convex edge and blocks the tool beside it, the "
         "shaded normal leaves out that face's discs behind the face under the tool (off: every disc near "
         "counts). Default: on")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option_function<std::string>(
         "--near-lists", [&p](const std::string& v) { p.near_lists = v == "on"; },
         "proxy, --surface ellipsoids: a compound tool's sweeps read each part's last near list instead of the BVH while it rests "
         "(the same contacts; off: the BVH every sweep). Default: on")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option_function<std::string>(
         "--face-average", [&p](const std::string& v) { p.face_average = v == "on"; },
         "proxy, --surface ellipsoids: on a clean flat face of the Gaussians, a compound tool's part averages its shaded normal with the "
         "face's mean thin axis while they agree (off: the shaded field). Default: on")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option_function<std::string>(
         "--surface", [&p](const std::string& v) { p.surface = proxy_surface_from(v, "--surface"); },
         "proxy: the solid the proxy rests on: seen (where the splats composite to half transmittance along the push, "
         "as a viewer sees them; faint Gaussians kept: the world's --min-opacity defaults to 1/255) or ellipsoids (the "
         "Gaussians' exact 1-sigma ellipsoids, opacity filter 0.2 and floater rule). Default: " +
             std::string(proxy_surface_name(ProxyParams{}.surface)))
      ->check(CLI::IsMember({"ellipsoids", "seen"}));
  cmd.add_option("--seen-window", p.seen_window,
                 "proxy on the seen solid (the default): the layers within this many tool radii behind a point along the push "
                 "decide whether it is inside")
      ->capture_default_str()->check(check::positive());
  cmd.add_option_function<std::string>(
         "--seen-footprint", [&p](const std::string& v) { p.seen_footprint = v == "on"; },
         "proxy on the seen solid (the default): a sphere tool's footprint: rays around its leading point hold it as a rigid "
         "ball on the rim of a see-through hole narrower than it and on the walls of a groove (one more short ray "
         "a tick; off: the leading point's ray alone). Default: on")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option("--isolation-gap", p.isolation_gap,
                 "proxy, --surface ellipsoids: a Gaussian with no other within this many tool radii is a floater and does not block "
                 "(0: only overlapping Gaussians support each other, which lets the tool through sparse surfaces)")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--floater-cluster", p.floater_cluster,
                 "proxy, --surface ellipsoids: a clump of at most this many overlapping Gaussians with nothing else within their own "
                 "size is a floater too (1: single Gaussians only)")
      ->capture_default_str()->check(CLI::Range(std::size_t(1), FloaterRule::kLargestCluster));
  cmd.add_option("--device-profile", o.profile,
                 "Device class: desktop (Touch class: --f-max 3.3, --stiffness 1000, 160x120x70 mm "
                 "workspace) or room (--f-max 30, --stiffness 1000); explicit options win")
      ->check(CLI::IsMember({"desktop", "room"}));
  cmd.parse_complete_callback([&cmd, &o, tool, first] {
    // An option that does not apply to the model or the tool is refused, never ignored. (An
    // option's model is its help text's "proxy: " or "paper: "; fidelity, without a tool,
    // renders both kinds of tool.)
    // (The force options as given are also kept for a report's command line: those this
    // function added, from `first` on.)
    std::vector<GivenOption> given;
    const auto options = cmd.get_options();
    for (std::size_t i = 0; i < options.size(); ++i) {
      const CLI::Option* opt = options[i];
      if (opt->count() == 0 || opt->get_lnames().empty()) continue;
      const std::string& text = opt->get_description();
      std::optional<RendererKind> model;
      for (const RendererName& r : renderer_names())
        if (text.rfind(std::string(r.name) + ": ", 0) == 0) model = r.kind;
      given.push_back({"--" + opt->get_lnames().front(), model});
      if (i < first) continue;
      o.given.push_back(given.back().name);
      if (opt->get_expected_max() != 0)
        for (const std::string& value : opt->results()) o.given.push_back(value);
    }
    refuse_options_not_applying(o.model, tool ? std::optional(tool->proxy_tool()) : std::nullopt, o.proxy.surface,
                                given);
    if (o.profile.empty()) return;
    apply_device_profile(device_profile(o.profile, "--device-profile"), o.f_max, o.proxy, cmd.count("--f-max") > 0,
                         cmd.count("--stiffness") > 0);
  });
}

void add_passivity_option(CLI::App& cmd, PassivityParams& p) {
  cmd.add_option_function<std::string>(
         "--passivity", [&p](const std::string& v) { p.enabled = v == "on"; },
         "Passivity observer and controller in the servo step (Hannaford & Ryu 2002): damping where the "
         "scene would give back more energy than it took. Default: on")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option("--passivity-max-damping", p.max_damping,
                 "Cap on the passivity controller's damping, N s/m (lowered to the device's own when that is lower). "
                 "Default: what the damped body renders without chattering: the device's own when it gives one "
                 "(the simulated device: half its mass over the step), the virtual tool's under admittance control, "
                 "else 20")
      ->check(check::non_negative());
}

void add_control_options(CLI::App& cmd, ControlParams& c) {
  cmd.add_option_function<std::string>(
         "--control",
         [&c](const std::string& v) { c.mode = v == "admittance" ? ControlMode::kAdmittance : ControlMode::kImpedance; },
         "impedance: read the pose, command force (desktop devices). admittance: read the user's force "
         "at the handle, move a virtual tool under it and the rendered force, command the device to "
         "follow it (robots with a force/torque sensor, the paper's HapticGiant class; sim becomes a "
         "robot under a position servo with a force sensor). Each device takes the one its causality "
         "allows. Default: impedance")
      ->check(CLI::IsMember({"impedance", "admittance"}));
  cmd.add_option("--virtual-mass", c.admittance.mass,
                 "Admittance control: the virtual tool's mass, kg (heavier: steadier, slower to follow the hand)")
      ->capture_default_str()->check(check::positive());
  cmd.add_option("--virtual-damping", c.admittance.damping,
                 "Admittance control: the virtual tool's damping, N s/m (the drag the hand feels in free space)")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--virtual-inertia", c.admittance.inertia,
                 "Admittance control: the virtual tool's moment of inertia, kg m^2 (a 6-DoF handle: the user's torque "
                 "and the rendered torque turn it)")
      ->capture_default_str()->check(check::positive());
  cmd.add_option("--virtual-angular-damping", c.admittance.angular_damping,
                 "Admittance control: the virtual tool's rotational damping, N m s/rad")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--robot-max-speed", c.robot.max_speed,
                 "Admittance control: the setpoint's speed limit, m/s (a room-scale device; an arm guided by "
                 "hand at reduced speed: 0.25)")
      ->capture_default_str()->check(check::positive());
  cmd.add_option("--robot-max-acceleration", c.robot.max_acceleration,
                 "Admittance control: the setpoint's acceleration and braking limit, m/s^2 (a stale device or a "
                 "stop brakes the robot to rest at it)")
      ->capture_default_str()->check(check::positive());
  cmd.add_option("--sensor-tare", c.robot.tare_time,
                 "Admittance control: the force sensor is tared over this long at start, s, while the robot "
                 "holds still (do not touch the handle); 0: no tare")
      ->capture_default_str()->check(check::range(0.0, 10.0));
  cmd.add_option("--sensor-dead-band", c.robot.dead_band,
                 "Admittance control: sensor readings at or below this magnitude (after the tare) are zero, N")
      ->capture_default_str()->check(check::non_negative());
}

void add_runtime_options(CLI::App& cmd, RuntimeOptions& o, const std::string& devices) {
  cmd.add_option("scene", o.scene.scene, "Scene file (default: bundled data/truck.splat, registered z-up in metres)");
  cmd.add_option("--device", o.device, devices)->capture_default_str();
  cmd.add_option("--rate", o.rate, "Servo rate, Hz")->capture_default_str()->check(check::range(10.0, 20000.0));
  cmd.add_option("--duration", o.duration,
                 "Run length, s (default: one pass of the probe trajectory for sim, the log's "
                 "length for replay, until Ctrl-C for mouse; a longer sim run repeats the trajectory)")
      ->check(check::positive());
  add_execution_options(cmd, o.exec, /*simulated=*/true);
  cmd.add_flag("--simulated-time", o.simulated_time,
               "Run on simulated time (as fast as the CPU allows, deterministic) through the same servo step: "
               "sim and replay devices only; --latency sets the decoupled worker's latency in ticks");
  cmd.add_option("--candidate-cache", o.candidate_cache,
                 "Servo-loop candidate cache of the paper model's contact query: margin as a fraction of the "
                 "tool radius (the BVH leaves near the tool are reused while the tool stays within it; "
                 "results are bit-identical); 0: off")
      ->capture_default_str()->check(check::range(0.0, 10.0));
  cmd.add_option("--query-threads", o.query_threads,
                 "Threads sharing the narrow phase of a large query (>= 2048 candidates; the paper model), "
                 "the collision worker included; 0: all cores but the servo's and the worker's, at most 4 " +
                     fmt::format("({} on this {}-core machine)", default_query_threads(std::thread::hardware_concurrency()),
                                 std::thread::hardware_concurrency()))
      ->capture_default_str()->check(CLI::Range(0, 64));
  cmd.add_option("--sites", o.sites, "Contact sites of the simulated probe")->capture_default_str()
      ->check(CLI::Range(1, 100));
  cmd.add_option("--seed", o.seed, "Seed of the site choice")->capture_default_str();
  cmd.add_option("--tool-radius", o.tool_radius,
                 "Spherical tool radius, world units (default: 1% of the scene's 1-99 pct extent)")
      ->check(check::positive());
  add_tool_option(cmd, o.tool,
                 "A tool with a shape, in the device's tool frame (origin: the tool centre point), world units: "
                 "sphere:R, ellipsoid:A,B,C, stylus:LENGTH,RADIUS (4 ellipsoids from the TCP along +z), "
                 "disc:RADIUS,THICKNESS, or FILE.json ({\"parts\": [{\"center\", \"semi_axes\", \"rotation\"}]}). "
                 "A tool of more than one part (or off the TCP, or not a sphere) gets the compound god-object with "
                 "the proxy (the paper model: eq. 7-11 per part) and a torque, sent to devices that render torque "
                 "(limit --tau-max)");
  cmd.add_option("--tau-max", o.safety.tau_max, "Torque limit, N m (the device's own limit binds too)")
      ->capture_default_str()->check(check::positive());
  add_force_options(cmd, o.force, &o.tool);
  cmd.add_option("--hold-timeout", o.safety.hold_timeout, "Hold a late result at full force this long, s")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--fade-time", o.safety.fade_time, "Then fade it to zero over this long, s")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--ramp-time", o.safety.ramp_time, "Soft start after start and every resume, s")
      ->capture_default_str()->check(check::non_negative());
  cmd.add_option("--max-force-rate", o.safety.max_force_rate, "Force-rate limit, N/s")
      ->capture_default_str()->check(check::positive());
  cmd.add_option("--device-timeout", o.safety.device_timeout, "Watchdog: zero force when device data is older, s")
      ->capture_default_str()->check(check::positive());
  add_passivity_option(cmd, o.safety.passivity);
  add_control_options(cmd, o.control);
  cmd.add_option("--continuous-window", o.safety.continuous_window,
                 "Averaging window of the device's continuous-force limit (RMS force, I^2 t), s")
      ->capture_default_str()->check(check::positive());
  cmd.add_option("--rt-priority", o.realtime.servo_priority,
                 "SCHED_FIFO priority of the servo thread (worker: 10 lower); 0: normal scheduling")
      ->capture_default_str()->check(CLI::Range(0, 99));
  cmd.add_flag("--no-pin", o.no_pin, "Do not pin the servo and worker threads to CPUs");
  cmd.add_option("--spin-us", o.spin_us,
                 "Sleep until this many microseconds before each deadline, then spin: lower "
                 "jitter for one busy core")
      ->capture_default_str()->check(check::range(0.0, 1000.0));
  cmd.add_flag("--mlock", o.realtime.lock_memory, "Lock all memory (mlockall) against page faults");
  cmd.add_option("--workspace-scale", o.workspace_scale,
                  "Map the device's workspace onto the scene: world metres per device metre (a 16 cm "
                  "desktop workspace over a 3 m scene: 20). Forces are not scaled: 1 N in the scene "
                  "is 1 N in the hand, so the hand feels --stiffness times this scale")->type_name("FLOAT");
  cmd.add_option("--workspace-offset", o.workspace_offset, "World point X,Y,Z of the device's origin (with --workspace-scale)");
  cmd.add_option("--workspace-rotation", o.workspace_rotation,
                 "Quaternion W,X,Y,Z turning the device's axes into the world's, for a unit set to another "
                 "basis (default: the device's z turned onto the world's up)");
  cmd.add_option("--clutch-button", o.clutch_button,
                 "Device button (0-31) that holds the clutch: re-centre the hand without moving the tool")
      ->check(CLI::Range(0, 31));
  cmd.add_option("--bubble-radius", o.bubble_radius,
                 "Rate control: beyond this device distance from its origin, m, the mapping drifts outward")
      ->check(check::non_negative());
  cmd.add_option("--bubble-gain", o.bubble_gain, "Rate control gain: world m/s per device m beyond --bubble-radius")
      ->check(check::non_negative());
  cmd.add_option("--haply-url", o.haply_url, "The Haply Inverse Service's WebSocket (--device haply)")
      ->capture_default_str();
  cmd.add_flag("--haply-allow-uncalibrated", o.haply_allow_uncalibrated,
               "Render force to an Inverse3 whose status says it is not calibrated (refused by default; "
               "calibrate it in Haply Hub instead)");
  cmd.add_option("--log-seconds", o.log_seconds,
                 "Keep only the first S seconds of the per-tick log (reserved up front; default: the "
                 "whole run, or 10 min when open-ended). Long runs: caps the log's memory")
      ->check(check::positive());
  cmd.add_option("--out", o.out_dir, "Output folder (default: runs/<name>-<extension>, e.g. runs/truck-splat)");
  cmd.add_flag("--no-plot", o.no_plot, "Do not draw run.png (needs /usr/bin/python3 with matplotlib)");
  cmd.add_flag("--quiet", o.quiet, "No progress bar or live status line");
  add_world_options(cmd, o.scene);
  add_world_cache_option(cmd, o.scene);
}

}  // namespace gshaptics::cli
