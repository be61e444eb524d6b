#include "gshaptics/fidelity/stability.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/error.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/servo/simulated_runtime.h"

namespace gshaptics {

void judge_wall_trace(const std::vector<double>& time, const std::vector<double>& height,
                      const WallTrialOptions& options, WallTrialResult& result) {
  // Half peak-to-peak of the height in each window after the settling time.
  std::vector<double> amplitudes;
  double lo = INFINITY, hi = -INFINITY, window_end = options.settle + options.window;
  double sum = 0;
  std::size_t count = 0;
  double last_mean = 0;
  for (std::size_t i = 0; i < time.size() && i < height.size(); ++i) {
    if (time[i] < options.settle) continue;
    if (time[i] >= window_end) {
      if (lo <= hi) amplitudes.push_back(0.5 * (hi - lo));
      if (count > 0) last_mean = sum / double(count);
      lo = INFINITY;
      hi = -INFINITY;
      sum = 0;
      count = 0;
      while (time[i] >= window_end) window_end += options.window;
    }
    lo = std::min(lo, height[i]);
    hi = std::max(hi, height[i]);
    sum += height[i];
    ++count;
  }
  // A last window at least half full counts.
  if (lo <= hi && count > 0) {
    const double covered = time.empty() ? 0 : time.back() - (window_end - options.window);
    if (covered >= 0.5 * options.window || amplitudes.empty()) {
      amplitudes.push_back(0.5 * (hi - lo));
      last_mean = sum / double(count);
    }
  }
  result.mean_depth = -last_mean;
  if (amplitudes.empty()) {
    result.stable = false;
    result.first_amplitude = result.last_amplitude = result.growth = 0;
    return;
  }
  result.first_amplitude = amplitudes.front();
  result.last_amplitude = amplitudes.back();
  result.growth = result.first_amplitude > 0 ? result.last_amplitude / result.first_amplitude : 0;
  result.stable = result.last_amplitude < options.rest_amplitude ||
                  (amplitudes.size() > 1 && result.last_amplitude < options.decay * result.first_amplitude);
}

WallTrialResult run_wall_trial(HapticDevice& device, std::unique_ptr<ForceRenderer> renderer,
                               RuntimeConfig config, const WallTrialOptions& options) {
  config.duration = options.duration;
  SimulatedRuntime runtime(device, config, std::move(renderer));
  runtime.run();
  WallTrialResult r;
  const auto& records = runtime.log().records();
  r.time.reserve(records.size());
  r.height.reserve(records.size());
  r.force.reserve(records.size());
  double min_energy = 0;
  for (const TickRecord& rec : records) {
    r.time.push_back(rec.time);
    r.height.push_back(rec.position.z());
    r.force.push_back(rec.force.z());
    r.setpoint.push_back(rec.setpoint.z());
    r.user_force.push_back(rec.user_force.z());
    min_energy = std::min(min_energy, rec.energy);
  }
  judge_wall_trace(r.time, r.height, options, r);
  const RuntimeSummary s = runtime.summary();
  r.min_energy = min_energy;
  r.peak_force = s.peak_force;
  r.passivity_ticks = s.passivity_ticks;
  r.peak_damping = s.passivity_peak_damping;
  return r;
}

}  // namespace gshaptics

namespace gshaptics {

DeviceModelParams StabilityOptions::default_impedance_device() {
  DeviceModelParams p;
  p.mass = 0.2;
  p.damping = 2.0;
  p.encoder_resolution = 1e-5;
  return p;
}

DeviceModelParams StabilityOptions::default_admittance_device() {
  DeviceModelParams p;
  p.causality = Causality::kAdmittance;
  p.mass = 2.0;
  p.damping = 2.0;
  p.encoder_resolution = 1e-5;
  return p;
}

StabilityOptions quick_stability_options() {
  StabilityOptions o;
  o.shapes = {ShapeKind::kPlane};
  o.rates = {1000};
  o.delays = {0, 0.005};
  o.stiffnesses = {500, 2000, 8000, 32000, 128000};
  o.trial.duration = 1.5;
  return o;
}

namespace {

// The top of the surface under the trial (the plane's z = 0, the thin plate's upper face).
double surface_top(ShapeKind kind) {
  switch (kind) {
    case ShapeKind::kPlate2mm: return 0.001;
    case ShapeKind::kPlate5mm: return 0.0025;
    case ShapeKind::kPlane: return 0.0;
    default: throw InputError("stability: shapes are plane, plate-2mm and plate-5mm (a flat face under the tool)");
  }
}

std::string fixed(const char* fmt_spec, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt_spec, v);
  return buf;
}

}  // namespace

StabilityReport run_stability(const StabilityOptions& o, const StabilityProgressFn& progress) {
  if (o.shapes.empty() || o.stiffnesses.empty() || o.delays.empty() || o.rates.empty() || o.controls.empty())
    throw InputError("stability: shapes, stiffnesses, delays, rates and controls must not be empty");
  for (double k : o.stiffnesses)
    if (!(k > 0) || !std::isfinite(k)) throw InputError("stability: stiffnesses must be > 0 N/m");
  for (double d : o.delays)
    if (!(d >= 0) || d > 0.5) throw InputError("stability: delays must be in [0, 0.5] s");
  for (double r : o.rates)
    if (!(r > 0) || r > 10000) throw InputError("stability: rates must be in (0, 10 kHz]");
  if (!(o.push > 0) || !(o.tool_radius > 0) || !(o.trial.duration > o.trial.settle + 2 * o.trial.window))
    throw InputError("stability: push and tool radius must be > 0, and a trial must hold two windows after settling");
  std::vector<double> ks = o.stiffnesses;
  std::sort(ks.begin(), ks.end());
  const auto t_start = std::chrono::steady_clock::now();
  StabilityReport rep;
  rep.options = o;
  for (ShapeKind kind : o.shapes) {
    const double top = surface_top(kind);
    SynthParams sp;
    sp.spacing = o.spacing;
    sp.seed = o.seed;
    const SyntheticScene scene = make_synthetic_scene(AnalyticShape(kind), sp);
    const CollisionWorld world = CollisionWorld::build(scene.scene, WorldConfig{});
    const std::string shape(to_string(kind));
    for (ControlMode control : o.controls)
      for (double rate : o.rates)
        for (double delay : o.delays)
          for (bool passivity : {false, true}) {
            if (progress)
              progress(fmt::format("{}, {} control, {:g} Hz, {:g} ms round trip, passivity {}: {} stiffnesses", shape,
                                   control_mode_name(control), rate, delay * 1e3, passivity ? "on" : "off", ks.size()));
            StabilityRow row;
            row.shape = shape;
            row.control = control;
            row.rate_hz = rate;
            row.delay = delay;
            row.passivity = passivity;
            bool unstable_seen = false;
            DeviceModelParams dp =
                control == ControlMode::kAdmittance ? o.admittance_device : o.impedance_device;
            dp.delay_up = dp.delay_down = delay / 2;
            dp.hand.push = Eigen::Vector3d(0, 0, -o.push);
            dp.hand.stiffness = o.hand_stiffness;  // holds the tool where it was put down
            dp.initial_position = Eigen::Vector3d(0.013, 0.021, top + o.tool_radius + 0.0005);
            dp.hand_anchor = dp.initial_position;
            if (control == ControlMode::kImpedance)
              row.predicted = (dp.damping + dp.hand.damping) / (0.5 / rate + delay);
            for (double k : ks) {
              DeviceModel device(dp);
              RuntimeConfig c;
              c.rate_hz = rate;
              c.tool.semi_axes = Eigen::Vector3d::Constant(o.tool_radius);
              ProxyModelSpec spec;
              spec.params.stiffness = k;
              spec.params.damping = o.proxy_damping;
              c.renderer = spec;
              c.safety.ramp_time = 0;  // the trial starts at the wall
              c.safety.passivity = o.passivity;
              c.safety.passivity.enabled = passivity;
              c.control.mode = control;
              c.control.admittance = o.virtual_tool;
              // The model's sensor is exact and the hand pushes from the first tick: nothing to tare
              // (a tare would take the push for a bias) and no noise for a dead band.
              c.control.robot.tare_time = 0;
              c.control.robot.dead_band = 0;
              // A wobble of an encoder count or two is the reading, not the contact.
              WallTrialOptions judge = o.trial;
              judge.rest_amplitude = std::max(judge.rest_amplitude, 2 * dp.encoder_resolution);
              const WallTrialResult r = run_wall_trial(device, make_force_renderer(c.renderer, world), c, judge);
              rep.ticks += r.time.size();
              StabilityTrial t;
              t.shape = shape;
              t.control = control;
              t.rate_hz = rate;
              t.delay = delay;
              t.stiffness = k;
              t.passivity = passivity;
              t.stable = r.stable;
              t.growth = r.growth;
              t.last_amplitude = r.last_amplitude;
              t.min_energy = r.min_energy;
              t.peak_force = r.peak_force;
              if (k == o.trace_stiffness) {
                t.time = r.time;
                t.height = r.height;
                t.setpoint = r.setpoint;
                t.force = r.force;
              }
              rep.trials.push_back(std::move(t));
              if (!unstable_seen && r.stable) row.largest_stable = k;
              if (!unstable_seen && (!r.stable || k == ks.back())) {
                row.energy_generated = std::max(0.0, -r.min_energy);
                row.amplitude = r.last_amplitude;
                row.peak_force = r.peak_force;
              }
              if (!r.stable) unstable_seen = true;
            }
            row.all_stable = !unstable_seen;
            rep.rows.push_back(row);
          }
  }
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return rep;
}

void write_stability_traces_csv(const StabilityReport& rep, const std::string& path) {
  std::string out = "shape,control,rate_hz,delay_ms,passivity,stiffness,time_s,height_mm,setpoint_mm,force_n\n";
  for (const StabilityTrial& t : rep.trials)
    for (std::size_t i = 0; i < t.time.size(); ++i)
      out += fmt::format("{},{},{:g},{:g},{},{:g},{:.4f},{:.5f},{:.5f},{:.4f}\n", t.shape, control_mode_name(t.control),
                         t.rate_hz, t.delay * 1e3, t.passivity ? 1 : 0, t.stiffness, t.time[i], t.height[i] * 1e3,
                         t.setpoint[i] * 1e3, t.force[i]);
  write_file_atomically(path, out);
}

void write_stability_csv(const StabilityReport& rep, const std::string& path) {
  std::string out = "shape,control,rate_hz,delay_ms,passivity,stiffness,stable,growth,amplitude_mm,min_energy_mj,peak_force_n\n";
  for (const StabilityTrial& t : rep.trials)
    out += fmt::format("{},{},{:g},{:g},{},{:g},{},{:.4g},{:.4g},{:.4g},{:.4g}\n", t.shape, control_mode_name(t.control),
                       t.rate_hz, t.delay * 1e3, t.passivity ? 1 : 0, t.stiffness, t.stable ? 1 : 0, t.growth,
                       t.last_amplitude * 1e3, t.min_energy * 1e3, t.peak_force);
  write_file_atomically(path, out);
}

void write_stability_markdown(const StabilityReport& rep, const std::string& path, const std::string& command,
                              const std::string& figure, const std::string& traces_figure) {
  const StabilityOptions& o = rep.options;
  const DeviceModelParams& imp = o.impedance_device;
  const DeviceModelParams& adm = o.admittance_device;
  std::string md;
  md += "# Stability: the largest coupling stiffness that holds still\n\n";
  md += fmt::format("Generated by `{}` ({} trials, {} ticks, {:.1f} s).\n\n", command, rep.trials.size(), rep.ticks, rep.seconds);
  md += "Each trial presses a simulated device onto a ground-truth Gaussian scene through the full servo step "
        "(SimulatedRuntime: safety layer, passivity controller, the runtime's default execution mode) with the "
        "proxy renderer, whose coupling stiffness is swept. The contact is stable when its oscillation dies out "
        "(fidelity/stability.h). The safety layer runs at its defaults except the soft start, which is off: "
        "each trial starts half a millimetre above the surface.\n\n";
  md += fmt::format("- Scenes: {} Gaussians {:g} mm apart; sphere tool of {:g} mm; the hand pushes with {:g} N and holds "
                    "the tool where it was put down with {:g} N/m; coupling damping B = {:g} N s/m. A wobble below two "
                    "encoder counts counts as rest.\n",
                    [&] {
                      std::string s;
                      for (ShapeKind k : o.shapes) s += (s.empty() ? "" : ", ") + std::string(to_string(k));
                      return s;
                    }(),
                    o.spacing * 1e3, o.tool_radius * 1e3, o.push, o.hand_stiffness, o.proxy_damping);
  md += fmt::format("- Impedance device: {:g} kg, b = {:g} N s/m, encoder {:g} um. Admittance device: {:g} kg under a "
                    "{:g} kN/m position servo; virtual tool {:g} kg, {:g} N s/m.\n",
                    imp.mass, imp.damping, imp.encoder_resolution * 1e6, adm.mass, adm.position_gain * 1e-3,
                    o.virtual_tool.mass, o.virtual_tool.damping);
  md += fmt::format("- Passivity controller when on: damping cap {:g} N s/m; the observer pairs forces with the motion a "
                    "round trip later (DeviceInfo::transport_delay).\n",
                    o.passivity.max_damping);
  md += fmt::format("- Delays are round trips, half each way. Trials of {:g} s.\n\n", o.trial.duration);
  md += "`largest stable`: the stiffest swept value below which all were stable (`>=` when the whole sweep was). "
        "`predicted`: the plain sampled wall's limit on the impedance device, b / (T/2 + d) (Colgate and Schenkel "
        "1997, with the round trip d added to the hold). Energy, amplitude and peak force are those of the first "
        "unstable stiffness (or the stiffest, when none was).\n\n";
  if (!figure.empty()) md += fmt::format("![largest stable stiffness]({})\n\n", figure);
  md += "| shape | control | rate Hz | round trip ms | passivity | largest stable N/m | predicted N/m | energy generated mJ | amplitude mm | peak force N |\n";
  md += "|---|---|---:|---:|---|---:|---:|---:|---:|---:|\n";
  for (const StabilityRow& r : rep.rows)
    md += fmt::format("| {} | {} | {:g} | {:g} | {} | {}{:g} | {} | {} | {} | {} |\n", r.shape, control_mode_name(r.control),
                      r.rate_hz, r.delay * 1e3, r.passivity ? "on" : "off", r.all_stable ? ">= " : "", r.largest_stable,
                      r.predicted > 0 ? fixed("%.0f", r.predicted) : std::string("-"),
                      fixed("%.3g", r.energy_generated * 1e3), fixed("%.3g", r.amplitude * 1e3),
                      fixed("%.3g", r.peak_force));
  if (!traces_figure.empty())
    md += fmt::format("\nThe trials at {:g} N/m over time (the tool centre's height and, under admittance control, the "
                      "setpoint the robot is commanded):\n\n![traces at {:g} N/m]({})\n",
                      o.trace_stiffness, o.trace_stiffness, traces_figure);
  write_file_atomically(path, md);
}

}  // namespace gshaptics
