// gshaptics_proxy_bench: the proxy (god-object) renderer's tick against the paper model's on the
// same device poses (issue 38). A set's poses are the device's path in a probe run of a real
// scene (as `gshaptics simulate SCENE --up auto` runs it: proxy, inline, the default press), or a
// fidelity press (ground-truth scene, scripted device). Each pass replays the whole path through a
// fresh renderer (the proxy's state depends on the path alone, so every pass does the same work);
// a tick's time is its median over the passes, which keeps the machine's own interruptions out of
// the p99. Writes one Markdown table.

#include <fmt/format.h>

#include <array>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <regex>
#include <sstream>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/device/device_model.h"
#include "gshaptics/error.h"
#include "gshaptics/fidelity/interaction.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/force/force_model.h"
#include "gshaptics/force/material.h"
#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/percentile.h"
#include "gshaptics/scene/opacity_filter.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/session/probe_session.h"
#include "gshaptics/sim/probe_run.h"
#include "gshaptics/sim/probe_trajectory.h"

namespace gshaptics::bench {
namespace {

using Clock = std::chrono::steady_clock;

struct Pose {
  Eigen::Vector3d position, velocity;
};

struct Set {
  std::string name;
  std::unique_ptr<CollisionWorld> world;
  double tool_radius = 0;
  std::vector<Pose> poses;
  /// Where each episode starts in `poses` (the fidelity sets' presses, each from a fresh renderer
  /// as `gshaptics fidelity` plays them; a probe run is one episode). Without the restarts a
  /// tool whose teleport distance (10 reaches) exceeds the jump between two presses was dragged
  /// round the shape by the spring and timed stuck on its far side.
  std::vector<std::size_t> starts{0};
  /// Whether pose i begins a further episode (the renderers are reset before it).
  [[nodiscard]] bool restarts_at(std::size_t i) const {
    return i > 0 && std::binary_search(starts.begin(), starts.end(), i);
  }
  /// A probe run's trajectory and the renderer it was recorded with (none: a fidelity set), so
  /// a tool with a shape can record its own run of the same trajectory (record_probe).
  std::optional<ProbeTrajectory> trajectory;
  RendererSpec recorded_with;
};

// The device's poses of `trajectory` played by the simulated hand through the servo step (as
// `gshaptics simulate` runs it) with `renderer`, holding `tool` (count 0: the trajectory's sphere).
std::vector<Pose> record_probe(const CollisionWorld& world, const ProbeTrajectory& trajectory,
                               const RendererSpec& renderer, const CompoundTool& tool = {}) {
  ProbeRunParams rp;
  rp.renderer = renderer;
  rp.tool = tool;
  const ProbeRunResult run = run_probe(world, trajectory, rp);
  std::vector<Pose> poses;
  poses.reserve(run.ticks.size());
  for (const TickRecord& r : run.ticks) poses.push_back({r.position, r.velocity});
  return poses;
}

std::string scene_path(const std::string& file) {
  if (file == "truck.splat") return std::string(GSHAPTICS_DATA_DIR) + "/truck.splat";
  return std::string(GSHAPTICS_SCENES_DIR) + "/" + file;
}

// A real scene's probe run, as `gshaptics simulate SCENE --up auto [--reg-scale S]` runs it,
// recorded with the proxy on `surface`, or on the ellipsoids of the same world when
// `ellipsoid_path` (a path the seen solid's code does not shape: for A/Bs of its cost).
Set probe_set(const std::string& name, const std::string& file, double reg_scale, bool bundled, ProxySurface surface,
              bool footprint, bool ellipsoid_path) {
  Set s;
  s.name = name;
  WorldConfig cfg;
  // On the seen solid the world keeps the faint Gaussians (what a viewer draws), and the probe
  // run is recorded with that proxy, its touch points on the seen solid, as `simulate --surface
  // seen` runs it.
  if (surface == ProxySurface::kSeen) cfg.min_opacity = kSeenMinOpacity;
  if (bundled) {
    cfg.registration = load_registration_file(std::string(GSHAPTICS_DATA_DIR) + "/truck.registration.json");
  } else {
    cfg.up = parse_up_axis("auto", "up");
    cfg.registration.scale = reg_scale;
  }
  fmt::print(stderr, "proxy_bench: {}: loading {}\n", name, scene_path(file));
  s.world = std::make_unique<CollisionWorld>(CollisionWorld::build(load_scene(scene_path(file)).scene, cfg));
  s.tool_radius = default_tool_radius(*s.world);
  const double depth = std::min(press_depth_for_force(15.0, ProxyParams{}.stiffness, UserHandParams{}.stiffness),
                                3.0 * s.tool_radius);
  ProbeParams pp = default_probe_params(*s.world, s.tool_radius, 7, 1, depth);
  if (surface == ProxySurface::kSeen && !ellipsoid_path) pp.first_touch = session::seen_first_touch(*s.world, s.tool_radius);
  s.trajectory = generate_probe_trajectory(*s.world, pp);
  fmt::print(stderr, "proxy_bench: {}: recording the probe run ({:.0f} s simulated)\n", name, s.trajectory->duration());
  ProxyModelSpec spec;
  spec.params.surface = ellipsoid_path ? ProxySurface::kEllipsoids : surface;
  spec.params.seen_footprint = footprint;
  s.recorded_with = spec;
  s.poses = record_probe(*s.world, *s.trajectory, s.recorded_with);
  return s;
}

// A fidelity set named `fidelity-SHAPE-Smm-Tmm[-slide][-crisp][-seedN]`: presses to 10 mm at 8
// sites on a ground-truth shape (seed N, default 1) at Gaussian spacing S with a tool of radius
// T, or with `-slide` the fidelity run's slide (plane, sphere, cube: over its edge); with `-crisp`
// the scene's convex edges crisp (SynthParams::kCrispEdgeSigmas, as bench/FIDELITY-crisp-edges.md:
// where the seen proxy's lips and landings run).
Set fidelity_set(const std::string& name) {
  static const std::regex pattern("fidelity-(.+)-([0-9.]+)mm-([0-9.]+)mm(-slide)?(-crisp)?(-seed([0-9]+))?");
  std::smatch m;
  if (!std::regex_match(name, m, pattern))
    throw InputError("proxy_bench: set '" + name + "': expected fidelity-SHAPE-SPACINGmm-TOOLmm[-slide][-crisp][-seedN]");
  Set s;
  s.name = name;
  const AnalyticShape shape(parse_shape(m[1].str(), "proxy_bench --sets"));
  SynthParams sp;
  sp.spacing = std::stod(m[2].str()) * 1e-3;
  if (m[5].matched) sp.edge_sigmas = SynthParams::kCrispEdgeSigmas;
  if (m[7].matched) sp.seed = std::stoull(m[7].str());
  const double radius = std::stod(m[3].str()) * 1e-3;
  s.world = std::make_unique<CollisionWorld>(CollisionWorld::build(make_synthetic_scene(shape, sp).scene, WorldConfig{}));
  s.tool_radius = radius;
  s.starts.clear();
  const auto add = [&](const Script& script) {
    s.starts.push_back(s.poses.size());
    for (const ScriptTick& t : script.ticks) s.poses.push_back({t.position, t.velocity});
  };
  if (m[4].matched) add(slide_script(shape, radius, 1000));
  else
    for (const ContactSite& site : shape.press_sites(8, 1, 0.03)) add(press_script(shape, site, radius, 0.010, 1000));
  return s;
}

struct Timing {
  double p50 = 0, p99 = 0, max = 0;
};

// Each tick's median over `passes` replays of `tick` (which renders pose i and returns nothing).
// reset(true) before each pass, reset(false) before each further episode of the set (untimed).
template <typename Reset, typename Tick>
Timing time_replays(const Set& s, int passes, Reset&& reset, Tick&& tick) {
  const std::size_t n = s.poses.size();
  std::vector<std::vector<double>> us(n, std::vector<double>(std::size_t(passes)));
  for (int p = 0; p < passes; ++p) {
    reset(true);
    for (std::size_t i = 0; i < n; ++i) {
      if (s.restarts_at(i)) reset(false);
      const auto t0 = Clock::now();
      tick(i);
      us[i][std::size_t(p)] = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
    }
  }
  std::vector<double> med(n);
  for (std::size_t i = 0; i < n; ++i) med[i] = percentile(us[i], 50);
  return {percentile(med, 50), percentile(med, 99), *std::max_element(med.begin(), med.end())};
}

// A --breakdown's bands: a replay's ticks by band of their time (p50-p95 when `from_median`,
// then p95-p99 and the top 1 %), `describe(label, ticks)` for each band that holds a tick.
template <typename TickT, typename Describe>
void by_time_band(const std::vector<TickT>& ticks, bool from_median, Describe&& describe) {
  std::vector<double> us(ticks.size());
  for (std::size_t i = 0; i < ticks.size(); ++i) us[i] = ticks[i].us;
  struct Band {
    const char* label;
    double lo, hi;
  };
  const double p50 = percentile(us, 50), p95 = percentile(us, 95), p99 = percentile(us, 99);
  const std::array<Band, 3> bands{{{"p50-p95", p50, p95}, {"p95-p99", p95, p99}, {"top 1 %", p99, INFINITY}}};
  for (std::size_t b = from_median ? 0 : 1; b < bands.size(); ++b) {
    std::vector<const TickT*> in;
    for (const TickT& k : ticks)
      if (k.us >= bands[b].lo && k.us < bands[b].hi) in.push_back(&k);
    if (!in.empty()) describe(bands[b].label, in);
  }
}

// --breakdown with a tool on the seen solid: one more replay of `s` (untimed by the table), each
// tick's time with what its queries read (SeenCompoundProxy::seen_work()) and whether it began in
// contact, and per band of that replay's times (p50-p95, p95-p99, the top 1 %) the means.
template <typename Render>
void seen_breakdown(const Set& s, int parts, const ProxyRenderer& timed, Render&& render) {
  struct TickWork {
    double us;
    SeenScratch::Work work;
    bool held;  // in contact when the tick began
  };
  std::vector<TickWork> ticks(s.poses.size());
  bool held = false;
  for (std::size_t i = 0; i < s.poses.size(); ++i) {
    if (s.restarts_at(i)) held = false;
    const SeenScratch::Work before = timed.seen_compound()->seen_work();
    const auto t0 = Clock::now();
    (void)render(i);
    const double us = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
    const SeenScratch::Work& after = timed.seen_compound()->seen_work();
    ticks[i] = {us, after - before, held};
    held = timed.seen_compound()->in_contact();
  }
  by_time_band(ticks, true, [&](const char* label, const std::vector<const TickWork*>& band) {
    double t = 0, walks = 0, entries = 0, layers = 0, in = 0;
    for (const TickWork* k : band)
      t += k->us, walks += double(k->work.walks), entries += double(k->work.entries), layers += double(k->work.layers),
          in += k->held;
    const double n = double(band.size());
    fmt::print(stderr,
               "proxy_bench: {}: seen compound proxy, {}-part tool, {} ticks {}: mean {:.1f} us, {:.1f} tree walks, {:.0f} leaf "
               "entries tested, {:.0f} layers taken, {:.0f} % began in contact\n",
               s.name, parts, n, label, t / n, walks / n, entries / n, layers / n, 100 * in / n);
  });
}

// Two materials split at the world's centre along x (world frame), both textured; the second
// with a procedural noise relief at the tool's scale. No friction: the proxy moves as without the map
// (friction would change its path, and the cost with it), so the difference is what the blend
// and the texture cost.
MaterialMap split_material_map(const CollisionWorld& w, double r) {
  const Eigen::Vector3d lo = w.bounds_lo() - Eigen::Vector3d::Ones(), hi = w.bounds_hi() + Eigen::Vector3d::Ones();
  const double mid = 0.5 * (w.bounds_lo().x() + w.bounds_hi().x());
  nlohmann::json j = {
      {"frame", "world"},
      {"materials",
       {{{"name", "a"}, {"stiffness", 800}, {"texture_gain", 1}},
        {{"name", "b"}, {"stiffness", 1200}, {"texture_gain", 1},
         {"texture", {{"noise", {{"amplitude", 0.05 * r}, {"wavelength_min", 0.2 * r}, {"wavelength_max", r}}}}}}}},
      {"regions",
       {{{"material", "a"}, {"box", {{"min", {lo.x(), lo.y(), lo.z()}}, {"max", {mid, hi.y(), hi.z()}}}}},
        {{"material", "b"}, {"box", {{"min", {mid, lo.y(), lo.z()}}, {"max", {hi.x(), hi.y(), hi.z()}}}}}}}};
  return MaterialMap::parse(j, "proxy_bench --materials");
}

}  // namespace
}  // namespace gshaptics::bench

int main(int argc, char** argv) {
  using namespace gshaptics;
  using namespace gshaptics::bench;
  CLI::App app{"The proxy renderer's tick against the paper model's on the same device poses: the probe runs of "
               "real scenes (as `gshaptics simulate SCENE --up auto`) and fidelity presses. Each tick's time is "
               "its median over the passes.",
               "gshaptics_proxy_bench"};
  std::string sets = "truck,burger,halo,firepit,karangkidul,fidelity-plane-2mm-10mm,fidelity-cube-8mm-5mm";
  int passes = 5;
  std::string out;
  app.add_option("--sets", sets,
                 "Comma-separated sets: truck, burger, halo, firepit, karangkidul (probe runs) and "
                 "fidelity-SHAPE-SPACINGmm-TOOLmm[-slide][-crisp][-seedN] (8 fidelity presses, or the slide; -crisp: crisp convex edges; -seedN: the scene's seed, default 1; e.g. "
                 "fidelity-v-groove-60-2mm-10mm, fidelity-plane-2mm-10mm-slide)")->capture_default_str();
  app.add_option("--passes", passes, "Replays of each path; a tick's time is its median over them")
      ->capture_default_str()->check(CLI::Range(1, 99));
  app.add_option("--out", out, "Also write the table (Markdown) to this file");
  bool breakdown = false;
  app.add_flag("--breakdown", breakdown,
               "Also print, per set, what the proxy's slow ticks do: over one more replay, the ticks between "
               "the p95 and the p99 and the top 1 % (by that replay's times), their mean sweeps, candidates "
               "and exact first-contact searches, and how many read the shaded normal; with --stylus on the "
               "seen surface, also the stylus proxy's ticks by band (p50-p95, p95-p99, top 1 %): their tree "
               "walks, leaf entries tested and layers taken on the seen solid");
  bool stylus = false;
  bool no_overhang_falloff = false;
  app.add_flag("--no-overhang-falloff", no_overhang_falloff,
               "The one-ellipsoid proxy's shaded normal counts every disc near, overhangs too "
               "(ProxyParams::overhang_falloff off), for comparison");
  bool no_crest_hold = false;
  app.add_flag("--no-crest-hold", no_crest_hold,
               "The one-ellipsoid proxy slides off a convex edge or corner it is pressed into "
               "(ProxyParams::crest_hold off; nor are edges read), for comparison");
  std::string surface_name(proxy_surface_name(ProxyParams{}.surface));
  app.add_option("--surface", surface_name,
                 "The proxy's solid on the probe runs: seen (the surface the splats render; the world keeps "
                 "Gaussians down to 1/255 and the probe run is recorded with that proxy) or ellipsoids (the "
                 "1-sigma ellipsoids)")
      ->capture_default_str()->check(CLI::IsMember({"ellipsoids", "seen"}));
  std::string footprint_name = ProxyParams{}.seen_footprint ? "on" : "off";
  app.add_option("--seen-footprint", footprint_name,
                 "With --surface seen: the sphere's footprint (ProxyParams::seen_footprint; the probe run is "
                 "recorded with it)")
      ->capture_default_str()->check(CLI::IsMember({"on", "off"}));
  std::string path_name = "own";
  app.add_option("--path-from", path_name,
                 "The probe runs' recording: own (with the proxy timed, as `simulate` runs it: a change to the "
                 "proxy's force changes the path) or ellipsoids (with the ellipsoid proxy on the same world: the "
                 "same path whatever the seen solid's code, for A/Bs of its cost)")
      ->capture_default_str()->check(CLI::IsMember({"own", "ellipsoids"}));
  bool no_near_lists = false;
  app.add_flag("--no-near-lists", no_near_lists,
               "Compound tools' sweeps take the BVH every time (ProxyParams::near_lists off), for comparison");
  app.add_flag("--stylus", stylus,
               "Also time both models with a compound tool on the same paths: a 4-part stylus "
               "(stylus:6R,R, tilted 45 deg, its tip at the pose) against the sphere of radius R, and "
               "write a second table; on a probe run also the stylus's own run (the simulated hand "
               "holding the tilted stylus on the same trajectory) and how far the device gets from "
               "the stylus's proxy on each");
  bool materials = false;
  app.add_flag("--materials", materials,
               "Also time the one-part proxy with a material map (force/material.h): two materials split at the "
               "world's centre along x, both with texture gain 1 (the captured relief), one also with a procedural "
               "noise relief (RMS 0.05 R, wavelengths 0.2-1 R), and write a table of what materials and texture add "
               "(with --stylus, also to the stylus's proxy)");
  CLI11_PARSE(app, argc, argv);
  const ProxySurface surface = proxy_surface_from(surface_name, "--surface");
  const bool seen_footprint = footprint_name == "on";
  const bool ellipsoid_path = path_name == "ellipsoids";
  try {
    std::string table =
        "| set | Gaussians | tool radius | ticks | ticks in contact | proxy p50 / p99 / max us | paper p50 / p99 us | "
        "p99 proxy / paper | target p99 us |\n|---|---:|---:|---:|---:|---|---|---:|---:|\n";
    std::string compound_table =
        "\n| set | tool radius R | ticks with contact, paper (sphere / stylus) | paper, sphere R: p50 / p99 us | "
        "paper, stylus 6R x R (4 parts): p50 / p99 us | p99 stylus / sphere | proxy, sphere R: p50 / p99 us | "
        "proxy, stylus: p50 / p99 / max us | p99 stylus / sphere | proxy, bounding sphere 3R (same tip): p50 / p99 us | "
        "p99 stylus / bounding sphere | proxy, stylus on its own probe run: p50 / p99 / max us | device from the "
        "stylus's proxy p99, R (sphere's run / own run) |\n|---|---:|---|---|---|---:|---|---|---:|---|---:|---|---|\n";
    std::string material_table =
        "\n| set | ticks in contact | proxy p50 / p99 us | with materials and texture p50 / p99 us | p99 added us |\n"
        "|---|---:|---|---|---:|\n";
    std::string stylus_material_table =
        "\n| set | proxy, stylus: p50 / p99 us | with materials and texture p50 / p99 us | p99 added us |\n"
        "|---|---|---|---:|\n";
    std::stringstream ss(sets);
    std::string name;
    while (std::getline(ss, name, ',')) {
      Set s;
      if (name == "truck") s = probe_set(name, "truck.splat", 1.0, true, surface, seen_footprint, ellipsoid_path);
      else if (name == "burger") s = probe_set(name, "burger.splat", 1.0, false, surface, seen_footprint, ellipsoid_path);
      else if (name == "halo") s = probe_set(name, "halo.ply", 1.0, false, surface, seen_footprint, ellipsoid_path);
      else if (name == "firepit") s = probe_set(name, "firepit.ply", 1.0, false, surface, seen_footprint, ellipsoid_path);
      else if (name == "karangkidul") s = probe_set(name, "karangkidul_crop.ply", 0.01, false, surface, seen_footprint, ellipsoid_path);
      else if (name.rfind("fidelity-", 0) == 0) s = fidelity_set(name);
      else throw InputError("proxy_bench: unknown set '" + name + "'");
      const CollisionWorld& w = *s.world;
      const double r = s.tool_radius;
      fmt::print(stderr, "proxy_bench: {}: {} ticks x {} passes\n", name, s.poses.size(), passes);
      std::size_t in_contact = 0;
      ProxyParams params;
      params.overhang_falloff = !no_overhang_falloff;
      params.crest_hold = !no_crest_hold;
      params.surface = surface;
      params.seen_footprint = seen_footprint;
      ProxyRenderer proxy(w, params);
      const Timing tp = time_replays(
          s, passes,
          [&](bool pass) {
            proxy.reset();
            if (pass) in_contact = 0;
          },
          [&](std::size_t i) {
            const RenderOutput o = proxy.render(ToolEllipsoid::sphere(s.poses[i].position, r), s.poses[i].velocity, 1e-3);
            in_contact += o.counts.contacts > 0;
          });
      if (breakdown) {
        // One more replay, each tick's time with what its move did (ProxyRenderer::last_move) and
        // whether it read the shaded normal.
        struct TickWork {
          double us;
          std::uint32_t sweeps, candidates, exact;
          bool read;
        };
        std::vector<TickWork> work(s.poses.size());
        proxy.reset();
        const std::uint64_t whole_before = proxy.shading_cache().whole_reads();
        for (std::size_t i = 0; i < s.poses.size(); ++i) {
          if (s.restarts_at(i)) proxy.reset();
          const std::uint64_t reads = proxy.shading_reads();
          const auto t0 = bench::Clock::now();
          (void)proxy.render(ToolEllipsoid::sphere(s.poses[i].position, r), s.poses[i].velocity, 1e-3);
          const double us = std::chrono::duration<double, std::micro>(bench::Clock::now() - t0).count();
          const ProxyMove& m = proxy.last_move();
          work[i] = {us, m.sweeps, m.candidates, m.exact, proxy.shading_reads() != reads};
        }
        by_time_band(work, false, [&](const char* label, const std::vector<const TickWork*>& band) {
          double t = 0, sw = 0, cand = 0, ex = 0, rd = 0;
          for (const TickWork* k : band) t += k->us, sw += k->sweeps, cand += k->candidates, ex += k->exact, rd += k->read;
          const double n = double(band.size());
          fmt::print(stderr,
                     "proxy_bench: {}: {} ticks {}: mean {:.1f} us, {:.1f} sweeps, {:.0f} candidates, {:.1f} exact "
                     "searches, {:.0f} % read the shaded normal\n",
                     name, n, label, t / n, sw / n, cand / n, ex / n, 100 * rd / n);
        });
        std::size_t reads = 0;
        for (const TickWork& k : work) reads += k.read;
        {
          // What keeps the p99 above the 10 us floor: the ticks over it, readers or not,
          // and the readers' own times.
          std::size_t over_read = 0, over_other = 0;
          std::vector<double> read_us;
          for (const TickWork& k : work) {
            if (k.read) read_us.push_back(k.us);
            if (k.us > 10.0) ++(k.read ? over_read : over_other);
          }
          if (!read_us.empty())
            fmt::print(stderr,
                       "proxy_bench: {}: {} ticks over 10 us ({} read the shaded normal; 1 % is {}); reading ticks "
                       "p10 / p50 / p90 {:.1f} / {:.1f} / {:.1f} us\n",
                       name, over_read + over_other, over_read, work.size() / 100, percentile(read_us, 10),
                       percentile(read_us, 50), percentile(read_us, 90));
        }
        fmt::print(stderr, "proxy_bench: {}: the shaded normal read on {} of {} ticks ({} of them whole)\n", name,
                   reads, work.size(), proxy.shading_cache().whole_reads() - whole_before);
      }
      if (materials) {
        ProxyRenderer textured(w, params);
        textured.set_materials(MaterialField::resolve(split_material_map(w, r), w, params));
        const Timing tt = time_replays(
            s, passes, [&](bool) { textured.reset(); },
            [&](std::size_t i) {
              (void)textured.render(ToolEllipsoid::sphere(s.poses[i].position, r), s.poses[i].velocity, 1e-3);
            });
        material_table += fmt::format("| {} | {} | {:.1f} / {:.1f} | {:.1f} / {:.1f} | {:+.1f} |\n", name, in_contact,
                                      tp.p50, tp.p99, tt.p50, tt.p99, tt.p99 - tp.p99);
        fmt::print(stderr, "{}", material_table.substr(material_table.rfind("\n|", material_table.size() - 2) + 1));
      }
      ContactQuery query(w);
      ForceModel model;
      const Timing tm = time_replays(
          s, passes, [&](bool) { model.reset(); },
          [&](std::size_t i) {
            query.run(ToolEllipsoid::sphere(s.poses[i].position, r));
            (void)model.update(query.result().contacts(), s.poses[i].position, s.poses[i].velocity, 1e-3);
          });
      table += fmt::format("| {} | {} | {:.4g} | {} | {} | {:.1f} / {:.1f} / {:.0f} | {:.1f} / {:.1f} | {:.1f}x | {:.0f} |\n",
                           name, w.size(), r, s.poses.size(), in_contact, tp.p50, tp.p99, tp.max, tm.p50, tm.p99,
                           tp.p99 / std::max(tm.p99, 1e-3), std::min(50.0, std::max(2 * tm.p99, 10.0)));
      fmt::print(stderr, "{}", table.substr(table.rfind("\n|", table.size() - 2) + 1));
      if (stylus) {
        const CompoundTool tool = parse_tool_spec(fmt::format("stylus:{},{}", 6 * r, r));
        const Eigen::Quaterniond tilt(Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitY()));
        std::array<ToolEllipsoid, kMaxToolParts> parts;
        PaperRenderer sphere_r(w), stylus_r(w);
        std::size_t sphere_hits = 0, stylus_hits = 0;
        const Timing ts = time_replays(
            s, passes,
            [&](bool pass) {
              sphere_r.reset();
              if (pass) sphere_hits = 0;
            },
            [&](std::size_t i) {
              const ToolEllipsoid one = ToolEllipsoid::sphere(s.poses[i].position, r);
              sphere_hits += sphere_r.render_compound({&one, 1}, s.poses[i].position, s.poses[i].velocity,
                                                      Eigen::Vector3d::Zero(), 1e-3).counts.contacts > 0;
            });
        const Timing tc = time_replays(
            s, passes,
            [&](bool pass) {
              stylus_r.reset();
              if (pass) stylus_hits = 0;
            },
            [&](std::size_t i) {
              const int n = tool.posed(s.poses[i].position, tilt, parts);
              stylus_hits += stylus_r.render_compound({parts.data(), std::size_t(n)}, s.poses[i].position,
                                                      s.poses[i].velocity, Eigen::Vector3d::Zero(), 1e-3)
                                 .counts.contacts > 0;
            });
        // The proxy with a compound tool, its TCP on the poses of `on` (default: the set's), the
        // tool turned by `turn` (default: tilted); `past`, when given, gets the p99 of how far the
        // device's TCP is from the proxy's, in R (a replay of its own, untimed).
        const auto time_proxy = [&](const CompoundTool& t, bool with_materials = false, const Set* on = nullptr,
                                    const Eigen::Quaterniond* turn = nullptr, double* past = nullptr) {
          const Set& path = on ? *on : s;
          const Eigen::Quaterniond& q = turn ? *turn : tilt;
          ProxyParams pp;
          pp.near_lists = !no_near_lists;
          pp.surface = surface;  // (--surface seen: the seen compound proxy; it was the ellipsoids' until the fifty-sixth session)
          ProxyRenderer timed(w, pp);
          timed.set_tool(t);
          if (with_materials) timed.set_materials(MaterialField::resolve(split_material_map(w, r), w, pp));
          const auto render = [&](std::size_t i) {
            const int n = t.posed(path.poses[i].position, q, parts);
            return timed.render_compound({parts.data(), std::size_t(n)}, path.poses[i].position, path.poses[i].velocity,
                                         Eigen::Vector3d::Zero(), 1e-3);
          };
          if (past) {
            std::vector<double> apart;
            timed.reset();
            for (std::size_t i = 0; i < path.poses.size(); ++i) {
              if (path.restarts_at(i)) timed.reset();
              apart.push_back((render(i).proxy - path.poses[i].position).norm() / r);
            }
            *past = percentile(apart, 99);
          }
          if (breakdown && timed.seen_compound() && !with_materials) seen_breakdown(path, t.count, timed, render);
          return time_replays(path, passes, [&](bool) { timed.reset(); }, [&](std::size_t i) { (void)render(i); });
        };
        double past_sphere_path = NAN, past_own_path = NAN;
        const Timing tq = time_proxy(tool, false, nullptr, nullptr, &past_sphere_path);
        // The stylus on its own probe run: the same trajectory, the simulated hand holding the
        // tilted stylus (as `gshaptics simulate --tool` runs it). On the sphere's poses the hand
        // goes where the sphere let it, often far past where the stylus's body stops.
        Timing town{NAN, NAN, NAN};
        if (s.trajectory) {
          CompoundTool tilted = tool;
          for (int k = 0; k < tilted.count; ++k) {
            ToolPart& part = tilted.parts[std::size_t(k)];
            part.offset = tilt * part.offset;
            part.rotation = tilt * part.rotation;
          }
          fmt::print(stderr, "proxy_bench: {}: recording the stylus's own probe run\n", name);
          Set own;
          own.name = name + " (stylus's own run)";
          own.poses = record_probe(w, *s.trajectory, s.recorded_with, tilted);
          const Eigen::Quaterniond upright = Eigen::Quaterniond::Identity();
          town = time_proxy(tilted, false, &own, &upright, &past_own_path);
        }
        // The sphere of the stylus's overall size: its bounding sphere (radius 3R, centred at the
        // stylus's middle, so it touches with the same tip), one part through the same compound proxy.
        CompoundTool ball = CompoundTool::single(Eigen::Vector3d::Constant(3 * r));
        ball.parts[0].offset = Eigen::Vector3d(0, 0, 3 * r);
        const Timing tb = time_proxy(ball);
        if (materials) {
          const Timing tt = time_proxy(tool, true);
          stylus_material_table += fmt::format("| {} | {:.1f} / {:.1f} | {:.1f} / {:.1f} | {:+.1f} |\n", name, tq.p50, tq.p99,
                                               tt.p50, tt.p99, tt.p99 - tq.p99);
        }
        compound_table += fmt::format(
            "| {} | {:.4g} | {} / {} | {:.1f} / {:.1f} | {:.1f} / {:.1f} | {:.1f}x | {:.1f} / {:.1f} | {:.1f} / {:.1f} / {:.0f} | "
            "{:.1f}x | {:.1f} / {:.1f} | {:.1f}x | {} | {} |\n",
            name, r, sphere_hits, stylus_hits, ts.p50, ts.p99, tc.p50, tc.p99, tc.p99 / std::max(ts.p99, 1e-3), tp.p50,
            tp.p99, tq.p50, tq.p99, tq.max, tq.p99 / std::max(tp.p99, 1e-3), tb.p50, tb.p99,
            tq.p99 / std::max(tb.p99, 1e-3),
            s.trajectory ? fmt::format("{:.1f} / {:.1f} / {:.0f}", town.p50, town.p99, town.max) : std::string("-"),
            s.trajectory ? fmt::format("{:.1f} / {:.1f}", past_sphere_path, past_own_path) : fmt::format("{:.1f} / -", past_sphere_path));
      }
    }
    if (stylus) table += compound_table;
    if (materials) table += material_table;
    if (materials && stylus) table += stylus_material_table;
    fmt::print("{}", table);
    if (!out.empty()) write_file_atomically(out, table);
  } catch (const InputError& e) {
    fmt::print(stderr, "gshaptics_proxy_bench: error: {}\n", e.what());
    return 2;
  }
  return 0;
}
