#include "gshaptics/session/report_session.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <pthread.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <thread>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/error.h"
#include "gshaptics/servo/interruptions.h"
#include "gshaptics/servo/realtime_thread.h"

namespace gshaptics::session {

namespace {

// `out` must be a Markdown file; its folder, "." when it has none.
std::filesystem::path report_folder(const std::string& out, const std::string& command) {
  const std::filesystem::path path(out);
  if (path.extension() != ".md") throw InputError(command + ": --out " + out + ": expected a .md file");
  return path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
}

// The report's data folder: `data_dir` when given, else beside the report in a folder named after
// it in lower case (bench/FIDELITY-paper.md: bench/fidelity-paper/), so two reports never share one.
std::string report_data_dir(const std::string& out, const std::string& data_dir) {
  if (!data_dir.empty()) return data_dir;
  std::string stem = std::filesystem::path(out).stem().string();
  std::transform(stem.begin(), stem.end(), stem.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return (std::filesystem::path(out).parent_path() / stem).string();
}

}  // namespace

FidelityOptions fidelity_options_from(const FidelityCommandOptions& o) {
  FidelityOptions fo = o.quick ? quick_fidelity_options() : FidelityOptions{};
  fo.renderer = o.force.spec();
  fo.play.safety.f_max = o.force.f_max;
  fo.play.safety.passivity = o.passivity;
  fo.seed = o.seed;
  fo.synth = o.synth;
  if (!o.shapes.empty()) {
    fo.shapes.clear();
    for (const std::string& name : o.shapes) fo.shapes.push_back(parse_shape(name, "--shape"));
  }
  if (!o.spacings_mm.empty()) {
    fo.spacings.clear();
    for (double mm : o.spacings_mm) fo.spacings.push_back(mm * 1e-3);
  }
  if (o.wrench_sites == 0) fo.wrench = false;
  if (o.wrench_sites > 0) fo.wrench_sites = o.wrench_sites;
  if (!o.defects.empty()) fo.defects.clear();
  for (const std::string& spec : o.defects)
    if (spec != "none") fo.defects.push_back(parse_capture_defect(spec, "--defect"));
  if (o.defect_sites > 0) fo.defect_sites = o.defect_sites;
  fo.wrench_tools.stylus = parse_tool_spec(o.stylus);
  fo.wrench_tools.disc = parse_tool_spec(o.disc);
  fo.play.inline_query = o.exec.inline_query;
  fo.play.latency_ticks = o.exec.latency_ticks;
  fo.scene_dir = o.scene_dir;
  return fo;
}

namespace {

// " --force-model M" and the force options: as given on the command line, or (a library call)
// the surface's (where it is not the default) from the parameters.
std::string force_command_line(const ForceModelOptions& f) {
  std::string text = " --force-model " + std::string(renderer_name(f.model));
  if (!f.given.empty()) {
    for (std::size_t i = 0; i < f.given.size(); ++i) {
      if (f.given[i] == "--force-model") {
        ++i;  // (its value; the model is named above)
        continue;
      }
      text += " " + f.given[i];
    }
    return text;
  }
  if (f.model != RendererKind::kProxy) return text;
  if (f.proxy.surface != ProxyParams{}.surface) text += " --surface " + std::string(proxy_surface_name(f.proxy.surface));
  if (f.proxy.surface == ProxySurface::kSeen) {
    if (f.proxy.seen_window != ProxyParams{}.seen_window) text += fmt::format(" --seen-window {:g}", f.proxy.seen_window);
    if (!f.proxy.seen_footprint) text += " --seen-footprint off";
  }
  return text;
}

}  // namespace

std::string fidelity_command_line(const FidelityCommandOptions& o) {
  std::string command = "gshaptics fidelity" + force_command_line(o.force);
  if (o.seed != FidelityOptions{}.seed) command += fmt::format(" --seed {}", o.seed);
  if (o.quick) command += " --quick";
  if (o.exec.inline_query != RuntimeConfig{}.inline_query) command += o.exec.inline_query ? " --inline" : " --decoupled";
  if (o.exec.latency_ticks != 1) command += fmt::format(" --latency {}", o.exec.latency_ticks);
  if (!o.shapes.empty()) command += fmt::format(" --shape {}", fmt::join(o.shapes, ","));
  if (!o.spacings_mm.empty()) command += fmt::format(" --spacing {}", fmt::join(o.spacings_mm, ","));
  if (o.wrench_sites >= 0) command += fmt::format(" --wrench-sites {}", o.wrench_sites);
  if (o.synth.floater_share != SynthParams{}.floater_share)
    command += fmt::format(" --floater-share {:g}", o.synth.floater_share);
  if (o.synth.edge_sigmas != SynthParams{}.edge_sigmas) command += fmt::format(" --edge-sigmas {:g}", o.synth.edge_sigmas);
  if (!o.defects.empty()) command += fmt::format(" --defect {}", fmt::join(o.defects, ","));
  if (o.defect_sites > 0) command += fmt::format(" --defect-sites {}", o.defect_sites);
  return command;
}

void run_fidelity_command(const FidelityCommandOptions& o) {
  const FidelityOptions fo = fidelity_options_from(o);
  const std::filesystem::path folder = report_folder(o.out, "fidelity");
  const std::string data_dir = report_data_dir(o.out, o.data_dir);
  std::filesystem::create_directories(folder);
  const FidelityReport rep = run_fidelity(fo, [](const std::string& line) { fmt::print(stderr, "fidelity   {}\n", line); });
  write_fidelity_data(rep, data_dir);
  std::string prefix;
  if (!o.no_plot) {
    const std::string model(renderer_name(o.force.model));
    if (run_python(find_tool_script("plot_fidelity.py"), {data_dir, data_dir, model}, "fidelity"))
      prefix = std::filesystem::relative(data_dir, folder).string() + "/fidelity_";
  }
  write_fidelity_markdown(rep, o.out, fidelity_command_line(o), prefix);
  fmt::print("fidelity   {} ticks in {:.0f} s; report {}; curves in {}\n", rep.ticks, rep.seconds, o.out, data_dir);
}

std::vector<std::string> seen_felt_default_scenes() {
  const char* env = std::getenv("GSHAPTICS_SCENES");
  const std::string dir = env && *env ? std::string(env) : std::string(GSHAPTICS_SOURCE_DIR) + "/../shared/data/scenes";
  std::vector<std::string> found;
  for (const char* name : {"truck.splat", "burger.splat", "skull.splat", "unicorn.ply", "halo.ply", "firepit.ply",
                           "guitar.compressed.ply", "biker.ply", "donut.ply", "fruitdrops.ply"}) {
    const std::string p = dir + "/" + name;
    if (std::filesystem::exists(p)) found.push_back(p);
  }
  return found;
}

SeenFeltOptions seen_felt_options_from(const SeenFeltCommandOptions& o) {
  SeenFeltOptions so = o.quick ? quick_seen_felt_options() : SeenFeltOptions{};
  so.renderer = o.force.spec();
  so.play.safety.f_max = o.force.f_max;
  so.play.inline_query = o.exec.inline_query;
  so.play.latency_ticks = o.exec.latency_ticks;
  so.seed = o.seed;
  so.tool = parse_seen_felt_tool(o.tool);
  so.tilt_deg = o.tilt_deg;
  if (o.rays > 0) {
    so.rays = o.rays;
    so.max_candidates = std::max(so.max_candidates, 20 * o.rays);
  }
  if (!o.tools_percent.empty()) {
    so.tool_fractions.clear();
    for (double pct : o.tools_percent) so.tool_fractions.push_back(pct / 100);
  }
  if (!o.directions.empty()) {
    so.directions.clear();
    for (const std::string& d : o.directions) so.directions.push_back(parse_press_direction(d));
  }
  return so;
}

namespace {

std::string seen_felt_command_line(const SeenFeltCommandOptions& o, const std::vector<std::string>& scenes) {
  std::string command = "gshaptics seen-felt" + force_command_line(o.force);
  if (o.quick) command += " --quick";
  if (o.rays > 0) command += fmt::format(" --rays {}", o.rays);
  if (!o.tools_percent.empty()) command += fmt::format(" --tool-percent {}", fmt::join(o.tools_percent, ","));
  if (!o.directions.empty()) command += fmt::format(" --direction {}", fmt::join(o.directions, ","));
  if (o.tool != SeenFeltCommandOptions{}.tool) {
    command += fmt::format(" --tool-shape {}", o.tool);
    if (o.tilt_deg != SeenFeltOptions{}.tilt_deg) command += fmt::format(" --tool-tilt {:g}", o.tilt_deg);
  }
  if (o.seed != SeenFeltOptions{}.seed) command += fmt::format(" --seed {}", o.seed);
  for (const ObjectSpec& spec : o.objects.objects) command += fmt::format(" --object {}", spec.text);
  if (!o.scenes.empty())
    for (const std::string& s : scenes) command += fmt::format(" {}", std::filesystem::path(s).filename().string());
  return command;
}

// `seen-felt --object`: the one scene with its rigid objects (SeenFeltCommandOptions::objects).
SeenFeltReport seen_felt_on_objects(const std::vector<std::string>& scenes, const SceneOptions& objects,
                                    const SeenFeltOptions& o, const SeenFeltProgressFn& progress) {
  if (scenes.size() != 1) throw InputError("seen-felt: --object needs exactly one scene");
  const auto t0 = std::chrono::steady_clock::now();
  SceneOptions so = objects;
  so.scene = scenes[0];
  if (so.min_opacity == kModelMinOpacity) so.min_opacity = default_min_opacity(o.renderer);
  const PreparedWorld pw = prepare_world(so, /*quiet=*/true, stderr);
  const SceneObjects bodies = scene_objects(pw, so, o.rate_hz, stderr);
  // The rays aim at the objects as they rest: the box of their Gaussians' centres.
  SeenFeltOptions aimed = o;
  std::array<Eigen::Vector3d, 2> box{Eigen::Vector3d::Constant(1e300), Eigen::Vector3d::Constant(-1e300)};
  for (const GaussianScene& g : pw.objects)
    for (const Eigen::Vector3f& m : g.means) {
      box[0] = box[0].cwiseMin(m.cast<double>());
      box[1] = box[1].cwiseMax(m.cast<double>());
    }
  aimed.aim_box = box;
  const std::unique_ptr<ForceRenderer> renderer = bodies.make_renderer(pw.world, o.renderer, QueryOptions{});
  SeenFeltReport report;
  report.options = aimed;
  const LoadedScene captured = load_scene(so.scene);  // the seen truth: the file as captured
  measure_seen_felt(std::filesystem::path(so.scene).filename().string(), captured.scene, pw.world, *renderer, aimed,
                    report, progress);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

}  // namespace

void run_seen_felt_command(const SeenFeltCommandOptions& o) {
  const SeenFeltOptions so = seen_felt_options_from(o);
  const std::filesystem::path folder = report_folder(o.out, "seen-felt");
  const std::vector<std::string> scenes = o.scenes.empty() ? seen_felt_default_scenes() : o.scenes;
  if (scenes.empty())
    throw InputError("seen-felt: no scene given and none of the shared scenes found (set GSHAPTICS_SCENES)");
  const std::string data_dir = report_data_dir(o.out, o.data_dir);
  const SeenFeltProgressFn progress = [](const std::string& line) { fmt::print(stderr, "seen-felt  {}\n", line); };
  const SeenFeltReport rep = o.objects.objects.empty() ? run_seen_felt(scenes, so, progress)
                                                       : seen_felt_on_objects(scenes, o.objects, so, progress);
  std::filesystem::create_directories(data_dir);
  const std::string csv = (std::filesystem::path(data_dir) / "seen_felt_rays.csv").string();
  write_seen_felt_csv(rep, csv);
  std::string figure;
  if (!o.no_plot) {
    const std::string png = (std::filesystem::path(data_dir) / "seen_felt.png").string();
    if (run_python(find_tool_script("plot_seen_felt.py"), {csv, png}, "seen-felt"))
      figure = std::filesystem::relative(png, folder).string();
  }
  write_seen_felt_markdown(rep, o.out, seen_felt_command_line(o, scenes), figure);
  int through = 0, rays = 0, no_force = 0;
  for (const SeenFeltRow& r : rep.rows) through += r.through, rays += r.rays, no_force += r.no_force;
  fmt::print("seen-felt  {} scenes, {} rays in {:.0f} s: {} through, {} without force; report {}\n", scenes.size(), rays,
             rep.seconds, through, no_force, o.out);
}

StabilityOptions stability_options_from(const StabilityCommandOptions& o) {
  StabilityOptions so = o.quick ? quick_stability_options() : StabilityOptions{};
  const StabilityOptions& given = o.sweep;
  so.push = given.push;
  if (!o.quick || given.trial.duration != StabilityOptions{}.trial.duration) so.trial.duration = given.trial.duration;
  so.impedance_device.mass = given.impedance_device.mass;
  so.impedance_device.damping = given.impedance_device.damping;
  so.passivity.max_damping = given.passivity.max_damping;
  if (!o.shapes.empty()) {
    so.shapes.clear();
    for (const std::string& s : o.shapes) so.shapes.push_back(parse_shape(s, "stability"));
  }
  if (!o.stiffnesses.empty()) so.stiffnesses = o.stiffnesses;
  if (!o.delays_ms.empty()) {
    so.delays.clear();
    for (double d : o.delays_ms) so.delays.push_back(d * 1e-3);
  }
  if (!o.rates.empty()) so.rates = o.rates;
  so.trace_stiffness = given.trace_stiffness;
  if (so.trace_stiffness > 0 &&
      std::find(so.stiffnesses.begin(), so.stiffnesses.end(), so.trace_stiffness) == so.stiffnesses.end())
    so.stiffnesses.push_back(so.trace_stiffness);
  if (o.control == "impedance") so.controls = {ControlMode::kImpedance};
  if (o.control == "admittance") so.controls = {ControlMode::kAdmittance};
  return so;
}

namespace {

// The command line that reproduces the sweep, for its report.
std::string stability_command_line(const StabilityCommandOptions& o) {
  std::string c = "gshaptics stability";
  if (o.quick) c += " --quick";
  if (o.control != "both") c += " --control " + o.control;
  for (const std::string& s : o.shapes) c += " --shape " + s;
  for (double r : o.rates) c += fmt::format(" --rate {:g}", r);
  for (double d : o.delays_ms) c += fmt::format(" --delay {:g}", d);
  for (double k : o.stiffnesses) c += fmt::format(" --stiffness {:g}", k);
  if (o.sweep.push != StabilityOptions{}.push) c += fmt::format(" --push {:g}", o.sweep.push);
  if (o.sweep.trace_stiffness > 0) c += fmt::format(" --trace-stiffness {:g}", o.sweep.trace_stiffness);
  return c;
}

}  // namespace

void run_stability_command(const StabilityCommandOptions& o) {
  const StabilityOptions so = stability_options_from(o);
  const std::filesystem::path folder = report_folder(o.out, "stability");
  const std::string data_dir = report_data_dir(o.out, o.data_dir);
  const StabilityReport rep = run_stability(so, [](const std::string& line) { fmt::print(stderr, "stability  {}\n", line); });
  std::filesystem::create_directories(data_dir);
  const std::string csv = (std::filesystem::path(data_dir) / "stability_trials.csv").string();
  write_stability_csv(rep, csv);
  std::string figure;
  if (!o.no_plot) {
    const std::string png = (std::filesystem::path(data_dir) / "stability.png").string();
    if (run_python(find_tool_script("plot_stability.py"), {csv, png}, "stability"))
      figure = std::filesystem::relative(png, folder).string();
  }
  std::string traces_figure;
  if (so.trace_stiffness > 0) {
    // The traced trials side by side: impedance and admittance at one stiffness.
    const std::string traces = (std::filesystem::path(data_dir) / "stability_traces.csv").string();
    write_stability_traces_csv(rep, traces);
    fmt::print("traces     {}\n", traces);
    const std::string png = (std::filesystem::path(data_dir) / "stability_traces.png").string();
    if (!o.no_plot && run_python(find_tool_script("plot_stability_traces.py"), {traces, png}, "stability"))
      traces_figure = std::filesystem::relative(png, folder).string();
  }
  write_stability_markdown(rep, o.out, stability_command_line(o), figure, traces_figure);
  for (const StabilityRow& r : rep.rows)
    fmt::print("{:<9} {:<10} {:>5g} Hz {:>4g} ms  passivity {:<3}  largest stable {}{:g} N/m{}\n", r.shape,
               control_mode_name(r.control), r.rate_hz, r.delay * 1e3, r.passivity ? "on" : "off",
               r.all_stable ? ">= " : "", r.largest_stable,
               r.predicted > 0 ? fmt::format(" (predicted {:.0f})", r.predicted) : std::string());
  fmt::print("stability  {} trials, {} ticks in {:.1f} s; report {}; trials {}\n", rep.trials.size(), rep.ticks,
             rep.seconds, o.out, csv);
}

void run_latency_command(const LatencyCommandOptions& o) {
  const long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
  const int cpu = o.cpu >= 0 ? o.cpu : int(std::max(1L, ncpu) - 1);
  if (ncpu > 0 && cpu >= ncpu)
    throw InputError(fmt::format("--cpu {}: this machine has CPUs 0-{}", cpu, ncpu - 1));
  std::string warning;
  InterruptionProfile p;
  std::thread t([&] {
    if (int e = pin_thread_to_cpu(pthread_self(), cpu); e != 0)
      warning += fmt::format("pinning to CPU {} refused: {}; ", cpu, std::strerror(e));
    if (o.priority > 0) {
      if (int e = set_fifo_priority(pthread_self(), o.priority); e != 0)
        warning += fmt::format("SCHED_FIFO {} refused: {} (grant CAP_SYS_NICE or an rtprio limit); ",
                               o.priority, std::strerror(e));
    }
    p = measure_interruptions(MonotonicClock::instance(), o.seconds, o.threshold_us);
  });
  t.join();
  if (!warning.empty()) fmt::print(stderr, "warning: {}measured anyway\n", warning);
  const double tick_hit = p.hit_probability(1000.0);
  if (o.json) {
    fmt::print(
        "{{\"cpu\": {}, \"priority\": {}, \"seconds\": {:.6f}, \"threshold_us\": {}, \"count\": {}, "
        "\"per_second\": {:.1f}, \"median_us\": {:.2f}, \"p99_us\": {:.2f}, \"max_us\": {:.2f}, "
        "\"lost_fraction\": {:.5f}, \"hit_probability_10us\": {:.5f}, \"hit_probability_50us\": {:.5f}, "
        "\"hit_probability_1ms\": {:.5f}}}\n",
        cpu, o.priority, p.seconds, p.threshold_us, p.count, p.per_second, p.median_us, p.p99_us, p.max_us,
        p.lost_fraction, p.hit_probability(10), p.hit_probability(50), tick_hit);
    return;
  }
  fmt::print("CPU {} ({}), {:.2f} s spinning on the clock, gaps over {:g} us:\n", cpu,
             o.priority > 0 ? fmt::format("SCHED_FIFO {}", o.priority) : std::string("normal scheduling"),
             p.seconds, p.threshold_us);
  if (p.count == 0) {
    fmt::print("  none: this CPU ran the thread without a break\n");
    return;
  }
  fmt::print("  {} gaps, {:.0f} per second; median {:.1f} us, p99 {:.1f} us, max {:.1f} us; {:.2f} % of the time lost\n",
             p.count, p.per_second, p.median_us, p.p99_us, p.max_us, 100 * p.lost_fraction);
  fmt::print("  a computation of 10 us is hit with probability {:.2f} %, one of 50 us {:.2f} %: a latency\n"
             "  percentile rarer than that includes a gap (for `gshaptics_bench`, compare its \"median of passes\")\n",
             100 * p.hit_probability(10), 100 * p.hit_probability(50));
  fmt::print("  a 1 kHz servo tick is hit {:.1f} % of the time; the longest gap is {:.0f} % of its 1 ms budget\n",
             100 * tick_hit, p.max_us / 10.0);
}

namespace {

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

std::string find_tool_script(const std::string& name) {
  if (name == "plot_probe_run.py")
    if (const char* env = std::getenv("GSHAPTICS_PLOT_SCRIPT")) return env;
  for (const std::string& p : {std::string(GSHAPTICS_SOURCE_DIR) + "/tools/" + name,
                              std::string(GSHAPTICS_INSTALL_DATADIR) + "/" + name})
    if (std::filesystem::exists(p)) return p;
  return "";
}

bool run_python(const std::string& script, const std::vector<std::string>& args, const std::string& command) {
  if (script.empty()) throw InputError(command + ": the plotting script is not found in tools/ (use --no-plot)");
  const char* py = std::getenv("GSHAPTICS_PYTHON");
  std::string cmdline = shell_quote(py ? py : "/usr/bin/python3") + " " + shell_quote(script);
  for (const std::string& a : args) cmdline += fmt::format(" {}", shell_quote(a));  // (not " " + string&&: GCC 12's -Wrestrict false positive, GCC bug 105329)
  if (std::system(cmdline.c_str()) != 0) {
    fmt::print(stderr, "error: plotting failed ({}); the data files are written. Install "
                       "python3-matplotlib or pass --no-plot\n", cmdline);
    return false;
  }
  return true;
}

}  // namespace gshaptics::session
