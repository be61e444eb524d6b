#include "gshaptics/session/run_session.h"

#ifdef GSHAPTICS_HAVE_OBJECTS
#include "gshaptics/objects/object_dynamics.h"
#endif

#include "gshaptics/collision/compound_tool.h"

#include <fmt/format.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <thread>

#include "gshaptics/error.h"
#include "gshaptics/servo/query_pool.h"
#include "gshaptics/device/replay_device.h"
#include "gshaptics/servo/tick_log.h"
#include "gshaptics/device/vendor_devices.h"
#include "gshaptics/device/workspace_mapping.h"
#include "gshaptics/sim/probe_run.h"
#include "gshaptics/sim/pose_sampler.h"
#ifdef GSHAPTICS_HAVE_HAPLY
#include "gshaptics/device/haply_device.h"
#endif

namespace gshaptics::session {

namespace {

std::atomic<int> g_signal{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void on_stop_signal(int sig) { g_signal.store(sig, std::memory_order_relaxed); }

std::string status_line(const HapticRuntime& rt, double planned) {
  const RuntimeStats& st = rt.stats();
  const double t = double(st.last_tick_ns.load() - st.start_ns.load()) * 1e-9;
  const std::uint64_t ticks = st.ticks.load();
  return fmt::format(
      "t {:6.1f}{} s | {:7.1f} Hz | jitter p99 {:5.1f} us | misses {} | query p99 {:6.1f} us | "
      "stale {} | fades {} | contacts {:5} | F {:5.2f} N",
      t, planned > 0 ? fmt::format("/{:.1f}", planned) : std::string(),
      t > 0 ? double(ticks - 1) / t : 0.0, st.jitter.percentile(99) * 1e-3, st.deadline_misses.load(),
      rt.worker().latency().percentile(99) * 1e-3, st.stale_ticks.load(), st.fades.load(),
      st.last_contacts.load(), st.last_force.load());
}

nlohmann::json to_json(const RuntimeSummary& s) {
  return {{"duration_s", s.duration_s},
          {"ticks", s.ticks},
          {"rate_hz", s.rate_hz},
          {"achieved_rate_hz", s.achieved_rate_hz},
          {"jitter_us", {{"p50", s.jitter_p50_us}, {"p99", s.jitter_p99_us}, {"max", s.jitter_max_us}}},
          {"tick_us", {{"p99", s.tick_p99_us}, {"max", s.tick_max_us}}},
          {"worker_us", {{"p50", s.query_p50_us}, {"p99", s.query_p99_us}, {"max", s.query_max_us}}},
          {"queries", s.queries},
          {"result_age_us", {{"p50", s.result_age_p50_us}, {"p99", s.result_age_p99_us}, {"max", s.result_age_max_us}}},
          {"deadline_misses", s.deadline_misses},
          {"skipped_periods", s.skipped_periods},
          {"stale_ticks", s.stale_ticks},
          {"fades", s.fades},
          {"fading_ticks", s.fading_ticks},
          {"faded_ticks", s.faded_ticks},
          {"no_result_ticks", s.no_result_ticks},
          {"watchdog_ticks", s.watchdog_ticks},
          {"invalid_pose_ticks", s.invalid_pose_ticks},
          {"outside_workspace_ticks", s.outside_workspace_ticks},
          {"force_limited_ticks", s.force_limited_ticks},
          {"rate_limited_ticks", s.rate_limited_ticks},
          {"continuous_limited_ticks", s.continuous_limited_ticks},
          {"passivity_ticks", s.passivity_ticks},
          {"passivity_peak_damping", s.passivity_peak_damping},
          {"passivity_min_energy_j", s.passivity_min_energy},
          {"results_used", s.results_used},
          {"peak_force_n", s.peak_force},
          {"peak_torque_nm", s.peak_torque},
          {"torque_limited_ticks", s.torque_limited_ticks},
          {"torque_dropped_ticks", s.torque_dropped_ticks},
          {"torque_limit_nm", s.torque_limit},
          {"passivity_damping_cap", s.passivity_damping_cap},
          {"setpoint_limited_ticks", s.setpoint_limited_ticks},
          {"braking_ticks", s.braking_ticks},
          {"sensor_saturated_ticks", s.sensor_saturated_ticks},
          {"force_limit_n", s.force_limit},
          {"force_limit_bound_by", s.force_limit_by_device ? "device" : "option"},
          {"continuous_force_limit_n", std::isfinite(s.continuous_force_limit) ? nlohmann::json(s.continuous_force_limit)
                                                                               : nlohmann::json(nullptr)}};
}

}  // namespace

StopSignals::StopSignals() {
  g_signal.store(0);
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, &old_int_);
  sigaction(SIGTERM, &sa, &old_term_);
}

StopSignals::~StopSignals() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

int StopSignals::received() noexcept { return g_signal.load(std::memory_order_relaxed); }
const std::atomic<int>& StopSignals::flag() noexcept { return g_signal; }

std::string registry_device_help(bool hardware_only) {
  std::string s;
  for (const DeviceKind& k : device_registry().kinds())
    if (!hardware_only || k.hardware) s += "; " + k.grammar + ": " + k.summary;
  return s;
}

bool is_hardware_device(const std::string& device) {
  const DeviceKind* k = device_registry().find(device);
  return k != nullptr && k->hardware;
}

void check_device_option(const std::string& device, bool allow_mouse) {
  // The viewer's streams (mouse, xr) are fed by the page; every other kind is the registry's.
  if (allow_mouse && (device == "mouse" || device == "xr")) return;
  if (device_registry().find(device) == nullptr) {
#ifndef GSHAPTICS_HAVE_HAPLY
    if (device == "haply" || device.rfind("haply:", 0) == 0)
      throw InputError("--device haply: this build has no WebSocket client (built without Boost.Beast)");
#endif
    throw InputError("--device: expected " + std::string(allow_mouse ? "'mouse', 'xr', " : "") +
                     device_registry().grammars() + ", got '" + device +
                     "' (`gshaptics devices` lists what this machine has)");
  }
  device_registry().check(device);
}

std::unique_ptr<HapticDevice> make_hardware_device(const RuntimeOptions& o) {
  DeviceOptions d;
  d.haply_url = o.haply_url;
  d.haply_allow_uncalibrated = o.haply_allow_uncalibrated;
  return open_device(o.device, d);
}

Eigen::Vector3d tool_start_point(const PreparedWorld& pw, double tool_radius) {
  const Eigen::Vector3d up = pw.world.up();
  // Fallback: above the middle of the scene, 12 tool radii over its highest Gaussian.
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  double top = -1e300;
  for (const auto& g : pw.world.gaussians()) {
    const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
    start += c;
    top = std::max(top, c.dot(up));
  }
  start /= double(std::max<std::size_t>(1, pw.world.size()));
  start += (top - start.dot(up) + 12.0 * tool_radius) * up;
  try {
    ProbeParams pp;  // (the default sites)
    pp.up = up;
    pp.tool_radius = tool_radius;
    const ProbeTrajectory traj = generate_probe_trajectory(pw.world, pp);
    double best = -2;
    for (const auto& site : traj.sites())
      if (site.normal.dot(up) > best) {
        best = site.normal.dot(up);
        start = site.surface_point + 12.0 * tool_radius * up;
      }
  } catch (const InputError&) {
    // No site on this scene: keep the point above its middle.
  }
  return start;
}

namespace {
double parse_workspace_scale(const std::string& text) {
  double v = 0;
  std::size_t used = 0;
  try {
    v = std::stod(text, &used);
  } catch (...) {
    used = 0;
  }
  if (used != text.size() || !std::isfinite(v) || !(v > 0))
    throw InputError("--workspace-scale: must be a finite number > 0, got '" + text + "'");
  return v;
}

Eigen::Quaterniond parse_workspace_rotation(const std::string& text) {
  const Eigen::Vector4d q = parse_vec4(text, "--workspace-rotation");
  if (!(q.norm() > 1e-9)) throw InputError("--workspace-rotation: '" + text + "' is not a rotation (all zero)");
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
}
}  // namespace

std::unique_ptr<HapticDevice> validate_runtime_options(const RuntimeOptions& o, bool allow_mouse) {
  check_device_option(o.device, allow_mouse);
  if (!o.workspace_scale.empty()) (void)parse_workspace_scale(o.workspace_scale);
  if (!o.workspace_offset.empty()) (void)parse_vec3(o.workspace_offset, "--workspace-offset");
  if (!o.workspace_rotation.empty()) (void)parse_workspace_rotation(o.workspace_rotation);
  // A device's library and a replay file are opened now, before the scene is loaded.
  const DeviceKind* kind = device_registry().find(o.device);
  return kind == nullptr || kind->needs_scene ? nullptr : make_hardware_device(o);
}

void wrap_in_workspace_mapping(const RuntimeOptions& o, RuntimeSetup& s, bool hardware,
                               const Eigen::Vector3d& default_offset, const Eigen::Vector3d& world_up) {
  const bool any = !o.workspace_scale.empty() || !o.workspace_offset.empty() || !o.workspace_rotation.empty() ||
                   o.clutch_button >= 0 || o.bubble_radius > 0 || o.bubble_gain > 0;
  if (!any && !hardware) return;
  if (s.mouse != nullptr)
    throw InputError("--workspace-*: the mouse device already works in world coordinates");
  WorkspaceMappingParams p;
  if (!o.workspace_scale.empty()) p.scale = parse_workspace_scale(o.workspace_scale);
  if (hardware) {
    // The device frame's z (up at the desk) becomes the world's up; the tool starts at the offset.
    p.rotation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), world_up.normalized());
    p.offset = default_offset;
  }
  if (!o.workspace_offset.empty()) p.offset = parse_vec3(o.workspace_offset, "--workspace-offset");
  if (!o.workspace_rotation.empty()) p.rotation = parse_workspace_rotation(o.workspace_rotation);
  p.clutch_button = o.clutch_button;
  p.bubble_radius = o.bubble_radius;
  p.bubble_gain = o.bubble_gain;
  s.inner = std::move(s.device);
  auto mapped = std::make_unique<MappedDevice>(*s.inner, p);
  const Eigen::AlignedBox3d& ws = s.inner->info().workspace;
  if (ws.sizes().allFinite() && ws.sizes().maxCoeff() < 1e3) s.workspace_box = mapped->mapping().world_box(ws);
  s.device = std::move(mapped);
  const Eigen::Quaterniond& r = p.rotation;
  fmt::print("workspace  device x {:.4g}, turned [{:.3f}, {:.3f}, {:.3f}, {:.3f}] (w,x,y,z), + [{:.3f}, {:.3f}, {:.3f}] "
             "-> world{}{}\n", p.scale, r.w(), r.x(), r.y(), r.z(), p.offset.x(), p.offset.y(), p.offset.z(), p.clutch_button >= 0 ? fmt::format(", clutch button {}", p.clutch_button) : "",
             p.bubble_radius > 0 ? fmt::format(", bubble {:.3g} m", p.bubble_radius) : "");
}

namespace {
void print_hardware_status(const HapticDevice& d) {
  const std::string status = d.status();
  const Eigen::AlignedBox3d& ws = d.info().workspace;
  const std::string box = ws.sizes().allFinite() && ws.sizes().maxCoeff() < 1e3
                              ? fmt::format(", workspace {:.0f} x {:.0f} x {:.0f} mm", ws.sizes().x() * 1e3,
                                            ws.sizes().y() * 1e3, ws.sizes().z() * 1e3)
                              : std::string();
  fmt::print("device     {}: {}{}, up to {:.0f} Hz ({})\n", d.info().name, status, box, d.info().max_rate_hz,
             d.info().rate_source);
}
}  // namespace

namespace {

// A kind that needs the scene (sim): the probe trajectory over it, and the device opened through
// the registry with it as the hand's path.
void open_scene_device(const RuntimeOptions& o, const SceneOptions& so, const PreparedWorld& pw, RuntimeSetup& s) {
  const ProbeTrajectory traj = make_probe_trajectory(pw.world, is_scaled(so), o.sites, o.seed, s.tool_radius, o.force,
                                                     stdout, std::nullopt, &o.tool.tool);
  s.tool_radius = traj.tool_radius();
  if (s.planned == 0) s.planned = traj.duration() + 0.5;
  s.pass = traj.duration();
  for (const ProbeSite& site : traj.sites())
    if (s.first_site < 0 || site.t_touch < s.first_site) s.first_site = site.t_touch;
  DeviceOptions d;
  d.hand_path = &traj;
  d.causality = o.control.mode == ControlMode::kAdmittance ? Causality::kAdmittance : Causality::kImpedance;
  s.device = device_registry().open(o.device, d);
}

// The viewer's streams, starting above the most upward-facing probe site on the object (or above
// the middle of the scene when none is found), so that lowering the tool touches the object.
// mouse: the browser page's drag and keys. xr: a VR controller in the page's WebXR session, 6-DoF
// targets at the headset's frame rate (72-120 Hz), interpolated to the servo rate like the mouse;
// no force before the first controller pose, and none once the controller stops reporting for
// 0.25 s or three of the page's frame intervals, whichever is longer (up to 1 s: a page at 7
// frames/s).
void open_viewer_stream(const PreparedWorld& pw, bool xr, RuntimeSetup& s) {
  if (s.tool_radius <= 0) s.tool_radius = default_tool_radius(pw.world);
  const Eigen::Vector3d start = tool_start_point(pw, s.tool_radius);
  StreamDeviceParams sp;
  sp.name = xr ? "xr controller (WebXR)" : "mouse (browser)";
  // (A busy page sends the mouse's keep-alive at 5-7/s, not 30, and an XR page runs at 7-15
  // frames/s: three periods, so one late message does not cut the force.)
  sp.timeout_periods = 3;
  if (xr) {
    sp.input_timeout = 0.25;
    sp.alive_before_first_target = false;
  }
  auto dev = std::make_unique<StreamDevice>(sp, start);
  s.mouse_start = start;
  s.mouse = dev.get();
  s.xr = xr;
  s.device = std::move(dev);
  if (xr)
    fmt::print("xr         tool radius {:.4g}; enter VR in the page; the right controller is the tool\n", s.tool_radius);
  else
    fmt::print("mouse      tool radius {:.4g}, starts at [{:.3f}, {:.3f}, {:.3f}]\n", s.tool_radius, start.x(), start.y(),
               start.z());
}

// A desktop device: opened and closed once now (a missing device is an error before the runtime
// starts), a hint when the scene is larger than its reach, and its workspace mapped into the world.
void open_hardware_device(const RuntimeOptions& o, const PreparedWorld& pw, std::unique_ptr<HapticDevice> opened,
                          RuntimeSetup& s) {
  if (s.tool_radius <= 0) s.tool_radius = default_tool_radius(pw.world);
  s.device = opened ? std::move(opened) : make_hardware_device(o);
  s.device->start(0);
  s.device->stop(0);
  print_hardware_status(*s.device);
  if (o.workspace_scale.empty()) {
    const Eigen::AlignedBox3d& ws = s.device->info().workspace;
    const double reach = ws.sizes().allFinite() && ws.sizes().maxCoeff() < 1e3 ? ws.sizes().minCoeff() : 0.12;
    const double size = robust_extent(pw.world);
    if (size > 2 * reach)
      fmt::print("hint       the scene is {:.3g} units across, the device reaches {:.3g} m: --workspace-scale {:.3g} "
                 "spans it (forces stay unscaled, so the hand feels the stiffness times that scale), or "
                 "move with --clutch-button / --bubble-radius\n", size, reach, size / reach);
  }
  wrap_in_workspace_mapping(o, s, /*hardware=*/true, tool_start_point(pw, s.tool_radius), pw.world.up());
}

// The registry's other kinds (replay:FILE): a replay says what it plays and warns of its bad rows.
void open_other_device(const RuntimeOptions& o, const PreparedWorld& pw, std::unique_ptr<HapticDevice> opened,
                       RuntimeSetup& s) {
  s.device = opened ? std::move(opened) : make_hardware_device(o);
  if (s.tool_radius <= 0) s.tool_radius = default_tool_radius(pw.world);
  if (const auto* replay = dynamic_cast<const ReplayDevice*>(s.device.get())) {
    const std::string file = o.device.substr(o.device.find(':') + 1);
    if (replay->non_finite_rows() > 0)
      fmt::print(stderr, "warning: {}: {} rows hold NaN/Inf; they are replayed as a faulty device\n", file,
                 replay->non_finite_rows());
    fmt::print("replay     {}: {:.2f} s, tool radius {:.4g}\n", file, replay->duration(), s.tool_radius);
  }
}

}  // namespace

RuntimeSetup make_runtime_setup(const RuntimeOptions& o, const SceneOptions& so, const PreparedWorld& pw,
                                bool allow_mouse, std::unique_ptr<HapticDevice> opened) {
  check_device_option(o.device, allow_mouse);
  RuntimeSetup s;
  s.tool_radius = o.tool_radius;
  if (s.tool_radius <= 0 && o.tool.given()) s.tool_radius = o.tool.tool.largest_semi_axis();
  s.planned = o.duration;
  const DeviceKind* kind = device_registry().find(o.device);
  if (kind != nullptr && kind->needs_scene)
    open_scene_device(o, so, pw, s);
  else if (o.device == "mouse" || o.device == "xr")
    open_viewer_stream(pw, o.device == "xr", s);
  else if (is_hardware_device(o.device))
    open_hardware_device(o, pw, std::move(opened), s);
  else
    open_other_device(o, pw, std::move(opened), s);
  if (!is_hardware_device(o.device)) wrap_in_workspace_mapping(o, s);
  s.config = runtime_config_from(o, s.tool_radius, s.planned);
  attach_scene_objects(s, pw, so, o.rate);
  fmt::print("runtime    {} at {:.0f} Hz, {} query, {}\n", s.device->info().name, o.rate,
             describe_execution(o.exec, false),
             s.planned > 0 ? fmt::format("{:.1f} s", s.planned) : std::string("until the device ends or Ctrl-C"));
  fmt::print("control    {}\n", describe_control(o.control, o.device == "sim"));
  std::fflush(stdout);
  return s;
}

void attach_scene_objects(RuntimeSetup& s, const PreparedWorld& pw, const SceneOptions& so, double rate_hz) {
  s.objects = scene_objects(pw, so, rate_hz);
  s.config.make_renderer = s.objects.make_renderer;
  if (!s.objects.empty())  // the objects' poses for the run's objects_log.csv
    s.objects.poses->record_into(std::make_shared<ObjectTrack>(s.objects.rest_origins.size(), runtime_log_capacity(s.config)));
}

RuntimeConfig runtime_config_from(const RuntimeOptions& o, double tool_radius, double planned) {
  RuntimeConfig rc;
  rc.rate_hz = o.rate;
  rc.inline_query = o.exec.inline_query;
  rc.latency_ticks = o.exec.latency_ticks;
  rc.duration = planned;
  rc.tool.semi_axes = Eigen::Vector3d::Constant(tool_radius);
  if (o.tool.given()) rc.tool = tool_shape_for(o.tool.tool);
  rc.renderer = o.force.spec();
  rc.safety = o.safety;
  rc.safety.f_max = o.force.f_max;
  rc.control = o.control;
  rc.realtime = o.realtime;
  rc.realtime.worker_priority = std::max(0, o.realtime.servo_priority - 10);
  rc.realtime.pin_threads = !o.no_pin;
  rc.realtime.spin_s = o.spin_us * 1e-6;
  if (o.log_seconds > 0) rc.log_capacity = std::size_t(std::ceil(o.log_seconds * o.rate));
  rc.query.cache_margin = o.candidate_cache * tool_radius;
  rc.query_threads = o.query_threads > 0 ? o.query_threads : default_query_threads(std::thread::hardware_concurrency());
  return rc;
}

bool run_live(HapticRuntime& rt, double planned, bool quiet, const std::function<std::string()>& extra) {
  StopSignals signals;
  rt.start();
  for (const auto& w : rt.warnings()) fmt::print(stderr, "warning: {}\n", w);
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  auto last_print = std::chrono::steady_clock::now();
  bool stop_sent = false;
  const auto line = [&] { return status_line(rt, planned) + (extra ? extra() : std::string()); };
  while (rt.running()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (!stop_sent && StopSignals::received() != 0) {
      rt.request_stop();
      stop_sent = true;
      fmt::print(stderr, "\n{} received: ramping the force to zero and stopping\n",
                 StopSignals::received() == SIGINT ? "SIGINT" : "SIGTERM");
    }
    const auto now = std::chrono::steady_clock::now();
    if (!quiet && (tty || now - last_print >= std::chrono::seconds(2))) {
      fmt::print(stderr, "{}{}", tty ? "\r" : "", line());
      if (!tty) fmt::print(stderr, "\n");
      last_print = now;
    }
  }
  rt.wait();
  if (!quiet && tty) fmt::print(stderr, "\r{}\n", line());
  return stop_sent;
}

namespace {
// What a run writes (objects_log.csv only with --object; a run without removes an old one).
const std::vector<std::string> kRunOutputs = {"servo_log.csv", "run_summary.json", "run.png", "objects_log.csv"};
}  // namespace

void prepare_run_out_dir(RuntimeOptions& o, const SceneOptions& so) {
  o.out_dir = prepare_out_dir(o.out_dir, so.scene, kRunOutputs);
}

namespace {
int write_outputs(const RuntimeSummary& s, const TickLog& log, const std::vector<std::string>& warnings,
                   const RuntimeOptions& o, const SceneOptions& so, const PreparedWorld& pw,
                   const RuntimeSetup& setup, bool interrupted, const std::string& command,
                   const nlohmann::json& extra);
}  // namespace

int write_run_outputs(const HapticRuntime& rt, const RuntimeOptions& o, const SceneOptions& so,
                       const PreparedWorld& pw, const RuntimeSetup& setup, bool interrupted,
                       const std::string& command, const nlohmann::json& extra) {
  return write_outputs(rt.summary(), rt.log(), rt.warnings(), o, so, pw, setup, interrupted, command, extra);
}

int write_run_outputs(const SimulatedRuntime& rt, const RuntimeOptions& o, const SceneOptions& so,
                       const PreparedWorld& pw, const RuntimeSetup& setup, const std::string& command) {
  nlohmann::json extra = {{"simulated_time", true}, {"latency_ticks", o.exec.inline_query ? 0 : o.exec.latency_ticks}};
  return write_outputs(rt.summary(), rt.log(), {}, o, so, pw, setup, false, command, extra);
}

namespace {

// run_summary.json's content (without the caller's extra keys).
nlohmann::json run_summary_json(const RuntimeSummary& s, const TickLog& log, const std::vector<std::string>& warnings,
                                const RuntimeOptions& o, const SceneOptions& so, const PreparedWorld& pw,
                                const RuntimeSetup& setup, bool interrupted, const std::vector<ContactEpisode>& episodes) {
  nlohmann::json sj;
  sj["scene"] = so.scene;
  sj["registration"] = so.registration_file;
  sj["gaussians_kept"] = pw.world.size();
  if (!so.objects.empty()) sj["objects"] = objects_json(so, pw, &setup.objects);
  sj["device"] = setup.device->info().name;
  sj["mode"] = o.exec.inline_query ? "inline" : "decoupled";
  sj["control"] = control_json(o.control);
  sj["renderer"] = std::string(renderer_name(setup.config.renderer));
  sj["tool_radius"] = setup.tool_radius;
  if (setup.config.tool.compound.count > 0) {
    nlohmann::json parts = nlohmann::json::array();
    for (const ToolPart& p : setup.config.tool.compound.view())
      parts.push_back({{"center", {p.offset.x(), p.offset.y(), p.offset.z()}},
                       {"semi_axes", {p.semi_axes.x(), p.semi_axes.y(), p.semi_axes.z()}},
                       {"rotation", {p.rotation.w(), p.rotation.x(), p.rotation.y(), p.rotation.z()}}});
    sj["tool"] = {{"spec", o.tool.spec}, {"parts", parts}};
  }
  sj["interrupted"] = interrupted;
  sj["runtime"] = to_json(s);
  sj["query_us"] = {{"p50", s.query_p50_us}, {"p99", s.query_p99_us}, {"max", s.query_max_us}};
  sj["log_ticks"] = log.records().size();
  sj["log_dropped"] = log.dropped();
  sj["warnings"] = warnings;
  const std::vector<DeviceCounter> device_counters = setup.device->counters();
  nlohmann::json dc = nlohmann::json::object();
  for (const DeviceCounter& c : device_counters) dc[c.name] = c.count;
  sj["device_counters"] = dc;
  sj["device_limits"] = {{"max_force_n", std::isfinite(setup.device->info().max_force) ? nlohmann::json(setup.device->info().max_force) : nlohmann::json(nullptr)},
                         {"max_continuous_force_n", std::isfinite(setup.device->info().max_continuous_force) ? nlohmann::json(setup.device->info().max_continuous_force) : nlohmann::json(nullptr)},
                         {"source", setup.device->info().limit_source},
                         {"max_torque_nm", std::isfinite(setup.device->info().max_torque) ? nlohmann::json(setup.device->info().max_torque) : nlohmann::json(nullptr)},
                         {"torque_source", setup.device->info().torque_limit_source}};
  nlohmann::json eps = nlohmann::json::array();
  for (const auto& e : episodes)
    eps.push_back({{"t_start", e.t_start}, {"t_end", e.t_end}, {"peak_contacts", e.peak_contacts},
                   {"peak_force", e.peak_force}, {"energy_j", e.energy_j}});
  sj["episodes"] = eps;
  return sj;
}

// The run's summary on stdout: rate and jitter, the worker, the safety layer, passivity, the
// force limit, the device's counters, the contact episodes and, for a probe that touched
// nothing, why. `ran`: the time of the last logged tick, s.
void print_run_summary(const RuntimeSummary& s, const RuntimeOptions& o, const SceneOptions& so,
                       const PreparedWorld& pw, const RuntimeSetup& setup, bool interrupted,
                       const std::vector<ContactEpisode>& episodes, double ran) {
  const std::vector<DeviceCounter> device_counters = setup.device->counters();
  fmt::print("\nticks      {} in {:.2f} s: {:.1f} Hz achieved ({:.0f} Hz set); {} deadline misses, "
             "{} periods skipped\n", s.ticks, s.duration_s, s.achieved_rate_hz, s.rate_hz,
             s.deadline_misses, s.skipped_periods);
  fmt::print("jitter     p50 {:.1f} us, p99 {:.1f} us, max {:.1f} us (wake-up lateness)\n",
             s.jitter_p50_us, s.jitter_p99_us, s.jitter_max_us);
  fmt::print("worker     {} queries: p50 {:.1f} us, p99 {:.1f} us, max {:.1f} us (query + force)\n",
             s.queries, s.query_p50_us, s.query_p99_us, s.query_max_us);
  fmt::print("age        result rendered p50 {:.0f} us, p99 {:.0f} us, max {:.0f} us after its pose\n",
             s.result_age_p50_us, s.result_age_p99_us, s.result_age_max_us);
  fmt::print("stale      {} ticks held a stale result; {} fades ({} ticks fading, {} faded)\n",
             s.stale_ticks, s.fades, s.fading_ticks, s.faded_ticks);
  fmt::print("safety     watchdog {}, invalid pose {}, outside workspace {}, force-limited {}, "
             "rate-limited {} ticks; peak force {:.2f} N\n", s.watchdog_ticks, s.invalid_pose_ticks,
             s.outside_workspace_ticks, s.force_limited_ticks, s.rate_limited_ticks, s.peak_force);
  if (setup.config.tool.compound.count > 0 || s.peak_torque > 0 || s.torque_dropped_ticks > 0)
    fmt::print("torque     peak {:.3g} N m after the safety layer (limit {:.3g} N m{}); {} ticks limited; {} ticks dropped ({})\n",
               s.peak_torque, s.torque_limit,
               setup.device->info().torque_limit_source.empty() || !(setup.device->info().max_torque <= s.torque_limit)
                   ? std::string(" from --tau-max") : ", the device's: " + setup.device->info().torque_limit_source,
               s.torque_limited_ticks, s.torque_dropped_ticks,
               setup.device->info().renders_torque ? "the device renders torque"
                                                   : "the device renders force only: torque not sent");
  fmt::print("passivity  {}: the controller added damping on {} ticks (peak {:.3g} N s/m, cap {:.3g}); lowest "
             "observed energy {:.3g} mJ\n", o.safety.passivity.enabled ? "on" : "off (observed only)", s.passivity_ticks,
             s.passivity_peak_damping, s.passivity_damping_cap, s.passivity_min_energy * 1e3);
  const DeviceInfo& di = setup.device->info();
  fmt::print("limit      {:.3g} N, bound by {}{}{}\n", s.force_limit,
             s.force_limit_by_device ? fmt::format("the device ({}; --f-max {:.3g} N)", di.limit_source, o.force.f_max)
                                     : fmt::format("--f-max{}", std::isfinite(di.max_force)
                                                                    ? fmt::format(" (the device allows {:.3g} N)", di.max_force)
                                                                    : std::string()),
             std::isfinite(s.continuous_force_limit)
                 ? fmt::format("; continuous {:.3g} N (RMS over {:.3g} s)", s.continuous_force_limit, o.safety.continuous_window)
                 : std::string(),
             s.continuous_limited_ticks > 0
                 ? fmt::format(": the continuous limit held the force down for {} ticks", s.continuous_limited_ticks)
                 : std::string());
  if (o.control.mode == ControlMode::kAdmittance)
    fmt::print("robot      setpoint held to the robot's limits on {} ticks; braked to rest on {} ticks; force sensor "
               "saturated on {} ticks{}\n", s.setpoint_limited_ticks, s.braking_ticks, s.sensor_saturated_ticks,
               s.sensor_saturated_ticks > 0 ? " (the run was stopped)" : "");
  for (const DeviceCounter& c : device_counters)
    if (c.count > 0) fmt::print("device     {}: {}\n", c.name, c.count);
  fmt::print("episodes   {} contact episodes{}\n", episodes.size(), active_episodes_note(episodes));
  if (episodes.empty() && o.device == "sim" && !interrupted) {
    if (setup.first_site > 0 && ran < setup.first_site)
      fmt::print("           the run ended at {:.1f} s, before the probe reached its first site (at {:.1f} s of a "
                 "{:.1f} s pass): give a longer --duration, or none for one pass\n",
                 ran, setup.first_site, setup.pass);
    else
      print_no_contact_hints(pw, so, setup.tool_radius);
  }
}

// Each object's last pose and how far it moved over the run (objects_log.csv's first and last
// rows), and the MuJoCo warnings, into the summary's "objects".
void add_object_travel(nlohmann::json& sj, const ObjectTrack& track) {
  if (track.rows() == 0 || !sj.contains("objects")) return;
  for (std::size_t i = 0; i < track.objects() && i < sj["objects"].size(); ++i) {
    const Eigen::Vector3d a = track.position(0, i), b = track.position(track.rows() - 1, i);
    sj["objects"][i]["final_position_m"] = {b.x(), b.y(), b.z()};
    sj["objects"][i]["moved_m"] = (b - a).norm();
    sj["objects"][i]["turned_rad"] = track.rotation(0, i).angularDistance(track.rotation(track.rows() - 1, i));
  }
  sj["objects_log_rows"] = track.rows();
#ifdef GSHAPTICS_HAVE_OBJECTS
  sj["mujoco_warnings"] = ObjectDynamics::warnings();
  sj["mujoco_errors"] = ObjectDynamics::errors();
  if (ObjectDynamics::errors() > 0) {
    sj["mujoco_last_error"] = ObjectDynamics::last_error();
    fmt::print(stderr, "warning: MuJoCo raised an error and the objects stopped moving where they were: {}\n",
               ObjectDynamics::last_error());
  }
#endif
}

int write_outputs(const RuntimeSummary& s, const TickLog& log, const std::vector<std::string>& warnings,
                   const RuntimeOptions& o, const SceneOptions& so, const PreparedWorld& pw,
                   const RuntimeSetup& setup, bool interrupted, const std::string& command,
                   const nlohmann::json& extra) {
  const auto& records = log.records();
  const std::vector<ContactEpisode> episodes = find_episodes(records, 0.1, o.control.mode == ControlMode::kAdmittance);

  const std::string out_dir = o.out_dir.empty() ? default_out_dir(so.scene) : o.out_dir;
  OutputStage stage(out_dir, kRunOutputs);
  const std::string csv = stage.path("servo_log.csv");
  const std::string summary_path = stage.path("run_summary.json");
  const std::string png = stage.path("run.png");
  // The run is over (the servo loop only filled memory): a full disk or a folder made read-only
  // meanwhile loses these files, never the run. Each failure is reported and sets exit status 4.
  std::vector<std::string> write_errors;
  const auto attempt = [&write_errors](const std::function<void()>& write) {
    try {
      write();
    } catch (const std::exception& e) {
      write_errors.push_back(e.what());
    }
  };
  attempt([&] { write_tick_log_csv(csv, records, log_columns(kServoLogColumns, o.control)); });
  const ObjectTrack* track = setup.objects.poses ? setup.objects.poses->track().get() : nullptr;
  if (track != nullptr) attempt([&] { track->write_csv(stage.path("objects_log.csv")); });

  nlohmann::json sj = run_summary_json(s, log, warnings, o, so, pw, setup, interrupted, episodes);
  for (const auto& [k, v] : extra.items()) sj[k] = v;
  if (track != nullptr) add_object_travel(sj, *track);
  attempt([&] { write_file_atomically(summary_path, sj.dump(2) + "\n"); });

  print_run_summary(s, o, so, pw, setup, interrupted, episodes, records.empty() ? 0.0 : records.back().time);
  if (log.dropped() > 0)
    fmt::print(stderr, "warning: the tick log kept the first {} ticks; {} more were not logged\n",
               records.size(), log.dropped());
  if (!write_errors.empty()) {
    for (const std::string& e : write_errors) fmt::print(stderr, "error: the run completed, but {}\n", e);
    fmt::print(stderr, "note: {} is left as it was\n", out_dir);
    return kExitOutputsLost;
  }
  const bool plotted = !o.no_plot && !records.empty() && plot_run(csv, summary_path, png, command);
  try {
    stage.commit();
  } catch (const InputError& e) {
    fmt::print(stderr, "error: the run completed, but {}\n", e.what());
    return kExitOutputsLost;
  }
  fmt::print("log        {}\nsummary    {}\n", stage.final_path("servo_log.csv"), stage.final_path("run_summary.json"));
  if (track != nullptr)
    fmt::print("objects    {} ({} dynamics steps that moved something{})\n", stage.final_path("objects_log.csv"),
               track->rows(), track->dropped() > 0 ? fmt::format(", {} more not logged", track->dropped()) : "");
  if (plotted) fmt::print("figure     {}\n", stage.final_path("run.png"));
  return o.no_plot || records.empty() || plotted ? 0 : 1;
}

}  // namespace

}  // namespace gshaptics::session
