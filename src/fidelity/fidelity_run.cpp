#include "gshaptics/fidelity/fidelity_run.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <variant>

#include "gshaptics/error.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/percentile.h"
#include "gshaptics/servo/haptic_runtime.h"

namespace gshaptics {

namespace {

double median(std::vector<double> v) { return v.empty() ? NAN : percentile(std::move(v), 50); }

double min_of(const std::vector<double>& v) { return v.empty() ? NAN : *std::min_element(v.begin(), v.end()); }

double max_of(const std::vector<double>& v) { return v.empty() ? NAN : *std::max_element(v.begin(), v.end()); }

// Everything gathered for one row before it is summarised.
struct Pool {
  std::vector<double> onset, stiffness, hold, energy, energy_other, dirs, shallow, tick_us, rsd, ton, mean_force, lost, steps;
  int runs = 0, never_lost = 0, active = 0, active_other = 0;

  void add_other_mode(const PressMetrics& m) {
    energy_other.push_back(m.energy_j);
    active_other += m.energy_j < 0 ? 1 : 0;
  }

  void add_press(const PressMetrics& m, const ScriptTrace& tr) {
    ++runs;
    if (!std::isnan(m.onset_mm)) onset.push_back(m.onset_mm);
    if (!std::isnan(m.stiffness_n_per_mm)) stiffness.push_back(m.stiffness_n_per_mm);
    hold.push_back(m.hold_through_mm);
    never_lost += m.never_lost ? 1 : 0;
    energy.push_back(m.energy_j);
    active += m.energy_j < 0 ? 1 : 0;
    dirs.insert(dirs.end(), m.direction_deg.begin(), m.direction_deg.end());
    shallow.insert(shallow.end(), m.shallow_direction_deg.begin(), m.shallow_direction_deg.end());
    for (float t : tr.render_us) tick_us.push_back(double(t));
  }
  void add_slide(const SlideMetrics& m, const ScriptTrace& tr) {
    ++runs;
    if (!std::isnan(m.force_rsd)) rsd.push_back(m.force_rsd);
    if (!std::isnan(m.tangential_over_normal)) ton.push_back(m.tangential_over_normal);
    mean_force.push_back(m.mean_force);
    if (!std::isnan(m.lost_share)) lost.push_back(m.lost_share);
    if (!std::isnan(m.largest_step)) steps.push_back(m.largest_step);
    dirs.insert(dirs.end(), m.direction_deg.begin(), m.direction_deg.end());
    for (float t : tr.render_us) tick_us.push_back(double(t));
  }
  FidelityRow row(const std::string& shape, const std::string& feature, double spacing, double radius) const {
    FidelityRow r;
    r.shape = shape;
    r.feature = feature;
    r.spacing = spacing;
    r.tool_radius = radius;
    r.runs = runs;
    r.onset_mm_median = median(onset);
    r.onset_mm_max = max_of(onset);
    r.stiffness_median = median(stiffness);
    r.hold_through_min_mm = min_of(hold);
    r.never_lost = never_lost;
    r.energy_min_j = min_of(energy);
    r.active_cycles = active;
    r.energy_other_min_j = min_of(energy_other);
    r.active_cycles_other = active_other;
    r.force_rsd = median(rsd);
    r.tangential_over_normal = median(ton);
    r.mean_force = median(mean_force);
    r.lost_share_max = max_of(lost);
    r.step_max = max_of(steps);
    if (!dirs.empty()) {
      r.dir_p50 = percentile(dirs, 50);
      r.dir_p95 = percentile(dirs, 95);
      r.dir_max = max_of(dirs);
    }
    if (!shallow.empty()) r.shallow_dir_p95 = percentile(shallow, 95);
    if (!tick_us.empty()) {
      r.tick_p50_us = percentile(tick_us, 50);
      r.tick_p99_us = percentile(tick_us, 99);
    }
    return r;
  }
};

// Loading ticks (presses) or measured ticks (slides), every `step`-th, as a figure curve.
FidelityCurve curve_of(const Script& s, const ScriptTrace& tr, const std::string& shape, double spacing, int step) {
  FidelityCurve c;
  c.scenario = std::string(to_string(s.scenario));
  c.shape = shape;
  c.spacing = spacing;
  c.tool_radius = s.tool_radius;
  const bool slide = s.scenario == Scenario::kSlide;
  for (std::size_t i = 0; i < s.ticks.size(); i += std::size_t(step)) {
    const ScriptTick& t = s.ticks[i];
    if (slide ? !t.measured : !t.loading) continue;
    c.x_mm.push_back((slide ? t.path : t.delta) * 1e3);
    c.force.push_back(tr.force[i].norm());
    c.f_normal.push_back(tr.force[i].dot(s.site.normal));
  }
  return c;
}

std::string scene_file(const FidelityOptions& o, ShapeKind k, double spacing, const CaptureDefect* defect) {
  return fmt::format("{}/{}_{:g}mm_seed{}{}{}.ply", o.scene_dir, to_string(k), spacing * 1e3, o.seed,
                     defect ? "_" : "", defect ? to_string(defect->kind) : "");
}

// The scene of a shape at a spacing (with a defect patch): reused when the sidecar says it was
// made the same way.
std::string ensure_scene(const FidelityOptions& o, ShapeKind k, double spacing, const CaptureDefect* defect = nullptr) {
  const std::string path = scene_file(o, k, spacing, defect);
  SynthParams p = o.synth;
  p.spacing = spacing;
  p.seed = o.seed;
  if (defect) p.defects = {*defect};
  const SyntheticScene s = make_synthetic_scene(AnalyticShape(k), p);
  std::ifstream in(path + ".json");
  if (in && std::filesystem::exists(path)) {
    std::stringstream ss;
    ss << in.rdbuf();
    try {
      if (nlohmann::json::parse(ss.str()) == s.description()) return path;
    } catch (const nlohmann::json::exception&) {
    }
  }
  write_synthetic_scene(path, s);
  return path;
}

double p(const std::vector<double>& v, double q) { return v.empty() ? NAN : percentile(v, q); }

// The 6-DoF cases of one shape at one spacing, a row per case.
void run_wrench_cases(const FidelityOptions& o, ShapeKind kind, double spacing, const CollisionWorld& world,
                      FidelityReport& rep) {
  const std::vector<WrenchCase> cases = wrench_cases(kind, o.wrench_tools, o.wrench_sites, o.seed);
  if (cases.empty()) return;
  const bool proxy = std::holds_alternative<ProxyModelSpec>(o.renderer);
  struct Gather {
    std::vector<double> stiffness, energy, fdir, tdir, ratio, zero, levers, ticks;
    int runs = 0, never_lost = 0, active = 0;
    double deepest = NAN;
  };
  std::vector<std::pair<std::string, Gather>> groups;
  for (const WrenchCase& c : cases) {
    auto it = std::find_if(groups.begin(), groups.end(), [&](const auto& g) { return g.first == c.name; });
    if (it == groups.end()) it = groups.insert(groups.end(), {c.name, Gather{}});
    Gather& g = it->second;
    const auto renderer = make_force_renderer(renderer_spec_for(o.renderer, ProxyTool::kCompound), world);
    const Script s = wrench_script(c, o.wrench_depth, o.rate_hz);
    const ScriptTrace tr = play_script(*renderer, s, o.rate_hz, o.play);
    const WrenchMetrics m = wrench_metrics(c, s, tr, proxy, o.play.safety.tau_max);
    rep.ticks += s.ticks.size();
    ++g.runs;
    g.never_lost += m.press.never_lost ? 1 : 0;
    g.active += m.press.energy_j < 0 ? 1 : 0;
    if (!std::isnan(m.press.stiffness_n_per_mm)) g.stiffness.push_back(m.press.stiffness_n_per_mm);
    g.energy.push_back(m.press.energy_j);
    g.fdir.insert(g.fdir.end(), m.force_dir_deg.begin(), m.force_dir_deg.end());
    g.tdir.insert(g.tdir.end(), m.torque_dir_deg.begin(), m.torque_dir_deg.end());
    g.ratio.insert(g.ratio.end(), m.torque_ratio.begin(), m.torque_ratio.end());
    g.zero.insert(g.zero.end(), m.zero_lever_mm.begin(), m.zero_lever_mm.end());
    if (!std::isnan(m.analytic_lever_mm)) g.levers.push_back(m.analytic_lever_mm);
    if (!std::isnan(m.deepest_part_mm)) g.deepest = std::isnan(g.deepest) ? m.deepest_part_mm : std::max(g.deepest, m.deepest_part_mm);
    for (float t : tr.render_us) g.ticks.push_back(double(t));
  }
  for (const auto& [name, g] : groups) {
    WrenchRow r;
    r.name = name;
    r.shape = std::string(to_string(kind));
    r.spacing = spacing;
    r.runs = g.runs;
    r.never_lost = g.never_lost;
    r.active_cycles = g.active;
    r.stiffness_median = median(g.stiffness);
    r.energy_min_j = min_of(g.energy);
    r.force_dir_p95 = p(g.fdir, 95);
    r.torque_dir_p50 = p(g.tdir, 50);
    r.torque_dir_p95 = p(g.tdir, 95);
    r.torque_ratio_p5 = p(g.ratio, 5);
    r.torque_ratio_p50 = p(g.ratio, 50);
    r.torque_ratio_p95 = p(g.ratio, 95);
    r.zero_lever_p95_mm = p(g.zero, 95);
    r.analytic_lever_mm = median(g.levers);
    r.deepest_part_mm = g.deepest;
    r.tick_p99_us = p(g.ticks, 99);
    rep.wrench.push_back(r);
  }
}

// The press sites of a defect patch on the plane: its centre, then points half its radius out.
std::vector<ContactSite> defect_sites(const CaptureDefect& d, double spacing, int count) {
  const Eigen::Vector3d center = patch_center(AnalyticShape(ShapeKind::kPlane), d, spacing);
  std::vector<ContactSite> sites;
  for (int i = 0; i < count; ++i) {
    ContactSite s;  // the plane's top, normal +z
    const double a = 2 * 3.14159265358979323846 * (i - 1) / std::max(1, count - 1);
    s.point = center;
    if (i > 0) s.point += Eigen::Vector3d(std::cos(a), std::sin(a), 0) * (0.5 * d.radius);
    sites.push_back(s);
  }
  return sites;
}

// A defect row's name: the kind and the patch's radius ("hole, 4 mm").
std::string defect_label(const CaptureDefect& d) { return fmt::format("{}, {:g} mm", to_string(d.kind), d.radius * 1e3); }

// The plane (with a defect patch, or none) pressed at `sites` with every tool radius: a row each.
void press_defect_plane(const FidelityOptions& o, const CaptureDefect* d, double spacing,
                        const std::vector<ContactSite>& sites, FidelityReport& rep) {
  const AnalyticShape plane(ShapeKind::kPlane);
  const LoadedScene loaded = load_scene(ensure_scene(o, ShapeKind::kPlane, spacing, d));
  WorldConfig config;
  config.min_opacity = default_min_opacity(o.renderer);
  const CollisionWorld world = CollisionWorld::build(loaded.scene, config);
  for (double radius : o.tool_radii) {
    const auto renderer = make_force_renderer(renderer_spec_for(o.renderer, ProxyTool::kOnePart), world);
    Pool pool;
    for (const ContactSite& site : sites) {
      const Script s = press_script(plane, site, radius, o.press_depth, o.rate_hz);
      const ScriptTrace tr = play_script(*renderer, s, o.rate_hz, o.play);
      pool.add_press(press_metrics(plane, s, tr), tr);
      rep.ticks += s.ticks.size();
    }
    rep.defect.push_back(pool.row("plane", d ? defect_label(*d) : "none", spacing, radius));
  }
}

// Every defect patch on the plane at every spacing and tool radius, after the plane without
// one pressed at the same sites (the rows the defects are judged against).
void run_defect_cases(const FidelityOptions& o, FidelityReport& rep, const FidelityProgressFn& progress) {
  if (o.defects.empty()) return;
  for (double spacing : o.spacings) {
    if (progress) progress(fmt::format("plane at {:g} mm spacing: capture defects", spacing * 1e3));
    press_defect_plane(o, nullptr, spacing, defect_sites(o.defects.front(), spacing, o.defect_sites), rep);
    for (const CaptureDefect& d : o.defects) press_defect_plane(o, &d, spacing, defect_sites(d, spacing, o.defect_sites), rep);
  }
}

// The renderers that read a material map: the proxy (on either solid).
bool reads_materials(const RendererSpec& spec) { return std::holds_alternative<ProxyModelSpec>(spec); }

// The two-material plane at `spacing` with every tool radius (material_fidelity.h).
void run_material_plane(const FidelityOptions& o, double spacing, const CollisionWorld& world, FidelityReport& rep,
                        const FidelityProgressFn& progress) {
  if (!o.materials) return;
  if (progress) progress(fmt::format("plane at {:g} mm spacing: two materials", spacing * 1e3));
  for (double radius : o.tool_radii)
    for (MaterialRow& r : run_material_cases(world, renderer_spec_for(o.renderer, ProxyTool::kOnePart), spacing, radius,
                                             o.rate_hz, o.play, o.material_presses, &rep.ticks))
      rep.material.push_back(std::move(r));
}

// Every grating (and the plane without relief) dragged at every speed with every tool radius.
void run_texture_cases(const FidelityOptions& o, FidelityReport& rep, const FidelityProgressFn& progress) {
  if (o.grating_wavelengths.empty() || o.drag_speeds.empty()) return;
  if (progress) progress("gratings: texture drags");
  // Every tool radius's sphere, then the stylus (its tip standing where the smallest sphere's
  // lowest point was).
  const CompoundTool& stylus = o.wrench_tools.stylus;
  for (std::size_t t = 0; t <= o.tool_radii.size(); ++t) {
    const bool with_stylus = t == o.tool_radii.size();
    const double radius = with_stylus ? *std::min_element(o.tool_radii.begin(), o.tool_radii.end()) : o.tool_radii[t];
    const RendererSpec spec = renderer_spec_for(o.renderer, with_stylus ? ProxyTool::kCompound : ProxyTool::kOnePart);
    for (double lambda : o.grating_wavelengths) {
      std::vector<double> amplitudes = o.grating_amplitudes;
      if (std::abs(lambda - 0.002) < 1e-9) amplitudes.insert(amplitudes.begin(), 0.0);  // the plane without relief
      for (double a : amplitudes)
        for (double v : o.drag_speeds) {
          GratingParams g;
          g.wavelength = lambda;
          g.amplitude = a;
          rep.texture.push_back(
              drag_over_grating(g, spec, radius, v, o.rate_hz, o.play, &rep.ticks, with_stylus ? &stylus : nullptr));
        }
    }
  }
}

}  // namespace

PlayOptions default_play_options() {
  const RuntimeConfig c;
  PlayOptions p;
  p.inline_query = c.inline_query;
  p.latency_ticks = c.latency_ticks;
  p.safety = c.safety;
  return p;
}

std::string describe_mode(const PlayOptions& p) {
  return p.inline_query ? std::string("inline")
                        : fmt::format("decoupled, {} tick{} latency", p.latency_ticks, p.latency_ticks == 1 ? "" : "s");
}

namespace {
// The slide's path as the report names it.
std::string_view slide_path_name(ShapeKind kind) {
  switch (kind) {
    case ShapeKind::kCube: return "over an edge";
    case ShapeKind::kCorner90: return "into a wall";
    default: return "path";
  }
}
}  // namespace

FidelityOptions quick_fidelity_options() {
  FidelityOptions o;
  o.shapes = {ShapeKind::kPlane, ShapeKind::kSphere, ShapeKind::kCube, ShapeKind::kPlate2mm};
  o.spacings = {0.004};
  o.tool_radii = {0.005};
  o.press_sites = 4;
  o.push_sites = 2;
  o.wrench_sites = 1;
  o.defect_sites = 2;
  o.material_presses = 2;
  o.grating_wavelengths = {0.002};
  o.grating_amplitudes = {0.00005, 0.0001};
  o.drag_speeds = {0.05};
  return o;
}

FidelityReport run_fidelity(const FidelityOptions& o, const FidelityProgressFn& progress) {
  if (o.scene_dir.empty()) throw InputError("fidelity: scene_dir is required (where the scenes are written)");
  if (o.spacings.empty() || o.tool_radii.empty() || o.shapes.empty())
    throw InputError("fidelity: shapes, spacings and tool radii must not be empty");
  if (o.wrench && !(o.wrench_sites >= 1 && o.wrench_depth > 0))
    throw InputError("fidelity: 6-DoF cases need sites >= 1 and a depth > 0");
  if (!(o.press_sites >= 1 && o.push_sites >= 0 && o.rate_hz > 0 && o.press_depth > 0 && o.push_depth > 0))
    throw InputError("fidelity: sites >= 1, rate > 0 and depths > 0 are required");
  if (!o.defects.empty() && o.defect_sites < 1) throw InputError("fidelity: capture defects need defect_sites >= 1");
  if (o.synth.edge_sigmas > 0 &&
      std::none_of(o.shapes.begin(), o.shapes.end(), [](ShapeKind k) { return AnalyticShape(k).has_convex_edges(); }))
    throw InputError("fidelity: --edge-sigmas needs a shape with convex edges (cube, plate-2mm, plate-5mm)");
  for (const CaptureDefect& d : o.defects) d.validate("fidelity");
  for (double r : o.tool_radii)
    if (!(r > 0.002)) throw InputError("fidelity: tool radii must be > 2 mm (slides run 2 mm deep)");
  std::filesystem::create_directories(o.scene_dir);
  const auto t_start = std::chrono::steady_clock::now();
  FidelityReport rep;
  rep.options = o;
  std::map<std::string, std::vector<double>> directions;
  for (ShapeKind kind : o.shapes) {
    const AnalyticShape shape(kind);
    const std::string name(shape.name());
    const bool pushable = kind == ShapeKind::kPlate2mm || kind == ShapeKind::kPlate5mm || kind == ShapeKind::kCube;
    const bool slidable = kind == ShapeKind::kPlane || kind == ShapeKind::kSphere || kind == ShapeKind::kCube ||
                          kind == ShapeKind::kCorner90;
    const std::vector<ContactSite> sites = shape.press_sites(o.press_sites, o.seed, 0.03);
    std::vector<ContactSite> push_sites;
    for (const ContactSite& s : shape.press_sites(std::max(1, o.push_sites * 5), o.seed + 1, 0.03))
      if (s.feature == "face" && int(push_sites.size()) < o.push_sites) push_sites.push_back(s);
    for (double spacing : o.spacings) {
      if (progress) progress(fmt::format("{} at {:g} mm spacing: generating and loading", name, spacing * 1e3));
      const std::string file = ensure_scene(o, kind, spacing);
      const LoadedScene loaded = load_scene(file);
      WorldConfig config;
      config.min_opacity = default_min_opacity(o.renderer);
      const CollisionWorld world = CollisionWorld::build(loaded.scene, config);
      for (double radius : o.tool_radii) {
        if (progress) progress(fmt::format("{} at {:g} mm spacing, tool {:g} mm: {} presses{}{}", name, spacing * 1e3,
                                           radius * 1e3, sites.size(), pushable ? ", push-throughs" : "",
                                           slidable ? ", a slide" : ""));
        const auto renderer = make_force_renderer(renderer_spec_for(o.renderer, ProxyTool::kOnePart), world);
        const PlayOptions& play = o.play;
        PlayOptions other = o.play;
        other.inline_query = !play.inline_query;
        std::map<std::string, Pool> by_feature;
        bool first_curve = true;
        for (const ContactSite& site : sites) {
          const Script s = press_script(shape, site, radius, o.press_depth, o.rate_hz);
          const ScriptTrace tr = play_script(*renderer, s, o.rate_hz, play);
          const PressMetrics m = press_metrics(shape, s, tr);
          by_feature[site.feature].add_press(m, tr);
          if (o.compare_modes)
            by_feature[site.feature].add_other_mode(press_metrics(shape, s, play_script(*renderer, s, o.rate_hz, other)));
          auto& d = directions[name];
          d.insert(d.end(), m.direction_deg.begin(), m.direction_deg.end());
          rep.ticks += s.ticks.size();
          if (first_curve && site.feature == "face") {
            rep.curves.push_back(curve_of(s, tr, name, spacing, 5));
            first_curve = false;
          }
        }
        for (const auto& [feature, pool] : by_feature) rep.press.push_back(pool.row(name, feature, spacing, radius));
        if (pushable && !push_sites.empty()) {
          Pool pool;
          for (std::size_t i = 0; i < push_sites.size(); ++i) {
            const Script s = press_script(shape, push_sites[i], radius, o.push_depth, o.rate_hz);
            const ScriptTrace tr = play_script(*renderer, s, o.rate_hz, play);
            pool.add_press(press_metrics(shape, s, tr), tr);
            if (o.compare_modes) pool.add_other_mode(press_metrics(shape, s, play_script(*renderer, s, o.rate_hz, other)));
            rep.ticks += s.ticks.size();
            if (i == 0) rep.curves.push_back(curve_of(s, tr, name, spacing, 5));
          }
          rep.push.push_back(pool.row(name, "face", spacing, radius));
        }
        if (slidable) {
          const Script s = slide_script(shape, radius, o.rate_hz);
          const ScriptTrace tr = play_script(*renderer, s, o.rate_hz, play);
          Pool pool;
          pool.add_slide(slide_metrics(shape, s, tr), tr);
          rep.ticks += s.ticks.size();
          rep.slide.push_back(pool.row(name, std::string(slide_path_name(kind)), spacing, radius));
          rep.curves.push_back(curve_of(s, tr, name, spacing, 5));
        }
      }
      if (o.wrench) run_wrench_cases(o, kind, spacing, world, rep);
      if (kind == ShapeKind::kPlane && reads_materials(o.renderer)) run_material_plane(o, spacing, world, rep, progress);
    }
  }
  run_defect_cases(o, rep, progress);
  if (o.materials && reads_materials(o.renderer) &&
      std::find(o.shapes.begin(), o.shapes.end(), ShapeKind::kPlane) != o.shapes.end())
    run_texture_cases(o, rep, progress);
  for (auto& [shape, d] : directions) rep.press_directions.emplace_back(shape, std::move(d));
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return rep;
}

namespace {

std::string num(double v, const char* fmt_spec = "{:.2f}") {
  return std::isnan(v) ? "-" : fmt::format(fmt::runtime(fmt_spec), v);
}

// Stiffness ratio max/min across spacings for each (shape, feature, radius), from press rows.
std::string stiffness_ratios(const std::vector<FidelityRow>& rows) {
  std::map<std::tuple<std::string, std::string, double>, std::vector<std::pair<double, double>>> groups;
  for (const FidelityRow& r : rows) groups[{r.shape, r.feature, r.tool_radius}].emplace_back(r.spacing, r.stiffness_median);
  std::string t = "| shape | feature | tool mm | stiffness N/mm by spacing | max / min |\n|---|---|---:|---|---:|\n";
  for (const auto& [key, v] : groups) {
    std::string cells;
    double lo = INFINITY, hi = 0;
    for (const auto& [sp, k] : v) {
      cells += fmt::format("{}{:g} mm: {}", cells.empty() ? "" : ", ", sp * 1e3, num(k, "{:.3f}"));
      if (!std::isnan(k) && k > 0) lo = std::min(lo, k), hi = std::max(hi, k);
    }
    const std::string ratio = v.size() > 1 && hi > 0 && std::isfinite(lo) ? fmt::format("{:.2f}", hi / lo) : "-";
    t += fmt::format("| {} | {} | {:g} | {} | {} |\n", std::get<0>(key), std::get<1>(key), std::get<2>(key) * 1e3, cells, ratio);
  }
  return t;
}

std::string press_table(const std::vector<FidelityRow>& rows) {
  std::string t =
      "| shape | feature | spacing mm | tool mm | runs | onset mm (median / max) | stiffness N/mm (median) | "
      "hold-through mm (min) | never lost | direction error deg p50 / p95 / max | shallow (delta <= 2 mm) p95 | W min (mJ) | W < 0 | "
      "W min, other mode (mJ) | W < 0, other mode | tick us p50 / p99 |\n"
      "|---|---|---:|---:|---:|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---|\n";
  for (const FidelityRow& r : rows)
    t += fmt::format("| {} | {} | {:g} | {:g} | {} | {} / {} | {} | {} | {} / {} | {} / {} / {} | {} | {} | {} | {} | {} | {} / {} |\n",
                     r.shape, r.feature, r.spacing * 1e3, r.tool_radius * 1e3, r.runs, num(r.onset_mm_median),
                     num(r.onset_mm_max), num(r.stiffness_median, "{:.3f}"), num(r.hold_through_min_mm, "{:.1f}"),
                     r.never_lost, r.runs, num(r.dir_p50, "{:.1f}"), num(r.dir_p95, "{:.1f}"),
                     num(r.dir_max, "{:.1f}"), num(r.shallow_dir_p95, "{:.1f}"), num(r.energy_min_j * 1e3, "{:.3f}"), r.active_cycles,
                     num(r.energy_other_min_j * 1e3, "{:.3f}"), std::isnan(r.energy_other_min_j) ? std::string("-") : std::to_string(r.active_cycles_other),
                     num(r.tick_p50_us, "{:.1f}"), num(r.tick_p99_us, "{:.1f}"));
  return t;
}

std::string wrench_table(const std::vector<WrenchRow>& rows) {
  std::string t =
      "| case | spacing mm | runs | force direction error deg p95 | analytic lever mm | torque direction error deg p50 / p95 | "
      "abs tau / abs tau* p5 / p50 / p95 | lever of zero-torque cases mm p95 | stiffness N/mm | never lost | "
      "deepest part past the surface mm | W min (mJ) | W < 0 | tick us p99 |\n"
      "|---|---:|---:|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const WrenchRow& r : rows)
    t += fmt::format("| {} | {:g} | {} | {} | {} | {} / {} | {} / {} / {} | {} | {} | {} / {} | {} | {} | {} | {} |\n", r.name,
                     r.spacing * 1e3, r.runs, num(r.force_dir_p95, "{:.1f}"), num(r.analytic_lever_mm, "{:.1f}"),
                     num(r.torque_dir_p50, "{:.1f}"), num(r.torque_dir_p95, "{:.1f}"), num(r.torque_ratio_p5),
                     num(r.torque_ratio_p50), num(r.torque_ratio_p95), num(r.zero_lever_p95_mm, "{:.2f}"),
                     num(r.stiffness_median, "{:.3f}"), r.never_lost, r.runs, num(r.deepest_part_mm, "{:.2f}"),
                     num(r.energy_min_j * 1e3, "{:.3f}"), r.active_cycles, num(r.tick_p99_us, "{:.1f}"));
  return t;
}

std::string slide_table(const std::vector<FidelityRow>& rows) {
  std::string t =
      "| shape | path | spacing mm | tool mm | mean abs F N | RSD of abs F | F_t / F_n | lost % | largest step N | direction error deg p50 / p95 / max | tick us p50 / p99 |\n"
      "|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|\n";
  for (const FidelityRow& r : rows)
    t += fmt::format("| {} | {} | {:g} | {:g} | {} | {} | {} | {} | {} | {} / {} / {} | {} / {} |\n", r.shape, r.feature,
                     r.spacing * 1e3, r.tool_radius * 1e3, num(r.mean_force, "{:.3f}"), num(r.force_rsd),
                     num(r.tangential_over_normal), num(r.lost_share_max * 100, "{:.0f}"), num(r.step_max),
                     num(r.dir_p50, "{:.1f}"), num(r.dir_p95, "{:.1f}"),
                     num(r.dir_max, "{:.1f}"), num(r.tick_p50_us, "{:.1f}"), num(r.tick_p99_us, "{:.1f}"));
  return t;
}

// Where a rigid sphere of radius `tool` first touches a plane with a round hole of radius
// `hole` around the point it is pressed at: b = R - sqrt(R^2 - r^2) past the plane (NaN: the
// hole is as wide as the tool, which falls in).
double bridging_depth(double tool, double hole) {
  return hole < tool ? tool - std::sqrt(tool * tool - hole * hole) : NAN;
}

// The defect rows against the plane without a defect at the same spacing and tool.
std::string defect_table(const FidelityOptions& o, const std::vector<FidelityRow>& rows) {
  std::string t =
      "| defect | spacing mm | tool mm | runs | onset mm (median / max) | onset - without defect, mm | rigid tool's | "
      "stiffness N/mm (median) | never lost | direction error deg p50 / p95 | W min (mJ) | tick us p99 | held where the plane is |\n"
      "|---|---:|---:|---:|---|---:|---:|---:|---:|---|---:|---:|---|\n";
  for (const FidelityRow& r : rows) {
    const auto plain = std::find_if(rows.begin(), rows.end(), [&](const FidelityRow& q) {
      return q.feature == "none" && q.spacing == r.spacing && q.tool_radius == r.tool_radius;
    });
    double rigid = 0;  // how much later a rigid sphere meets the defect than the plane
    for (const CaptureDefect& d : o.defects)
      if (d.kind == DefectKind::kHole && defect_label(d) == r.feature) rigid = bridging_depth(r.tool_radius, d.radius) * 1e3;
    const double shift = plain == rows.end() ? NAN : r.onset_mm_median - plain->onset_mm_median;
    const bool held = r.never_lost == r.runs && shift >= -1 && shift <= rigid + 1;
    const std::string verdict = r.feature == "none" ? "(the reference)"
                                : held                ? "yes"
                                : std::isnan(rigid)   ? "- (the hole is as wide as the tool)"
                                                      : "**no**";
    t += fmt::format("| {} | {:g} | {:g} | {} | {} / {} | {} | {} | {} | {} / {} | {} / {} | {} | {} | {} |\n", r.feature,
                     r.spacing * 1e3, r.tool_radius * 1e3, r.runs, num(r.onset_mm_median), num(r.onset_mm_max),
                     r.feature == "none" ? "-" : num(shift), num(rigid), num(r.stiffness_median, "{:.3f}"), r.never_lost,
                     r.runs, num(r.dir_p50, "{:.1f}"), num(r.dir_p95, "{:.1f}"), num(r.energy_min_j * 1e3, "{:.3f}"),
                     num(r.tick_p99_us, "{:.1f}"), verdict);
  }
  return t;
}

std::string describe_defects(const FidelityOptions& o) {
  std::string t;
  for (const CaptureDefect& d : o.defects) {
    t += fmt::format("- **{}**, {:g} mm around the plane's centre: ", to_string(d.kind), d.radius * 1e3);
    switch (d.kind) {
      case DefectKind::kFaintPatch:
        t += fmt::format("every disc replaced by {} discs of opacity {:g}-{:g} (all under the 0.2 filter), spread half a "
                         "spacing in the plane and by the disc's jitter along the normal: together opaque to the eye;\n",
                         d.faint_layers, d.faint_opacity_min, d.faint_opacity_max);
        break;
      case DefectKind::kHole: t += "no Gaussians (the neighbours' discs still overhang its rim);\n"; break;
      case DefectKind::kLargeFlat:
        t += fmt::format("covered by large flat opaque discs, {:g} spacings wide and apart, instead of small ones;\n",
                         d.large_factor);
        break;
      case DefectKind::kInteriorClutter:
        t += fmt::format("the surface kept, and one Gaussian per disc floating {:g}-{:g} mm under it;\n",
                         d.clutter_depth_min * 1e3, d.clutter_depth_max * 1e3);
        break;
    }
  }
  return t;
}

// The default world's filter and solid in words, for the report's header.
std::string world_words(const RendererSpec& renderer) {
  const auto* proxy = std::get_if<ProxyModelSpec>(&renderer);
  const bool seen = proxy != nullptr && proxy->params.surface == ProxySurface::kSeen;
  return fmt::format("opacity > {:.4g}{}", default_min_opacity(renderer),
                     seen ? ", the proxy on the seen solid" : proxy ? ", the proxy on the ellipsoids" : "");
}

}  // namespace

void write_fidelity_markdown(const FidelityReport& rep, const std::string& path, const std::string& command,
                             const std::string& figures_prefix) {
  const FidelityOptions& o = rep.options;
  std::string md = "# Haptic fidelity: force model `" + std::string(renderer_name(o.renderer)) + "` against analytic ground truth\n\n";
  md += "Command: `" + command + "`\n\n";
  md += fmt::format(
      "{} ticks at {:g} Hz in {:.0f} s. Scenes: Gaussians on analytic surfaces (`gshaptics synth`, seed {}; "
      "flat discs, log-normal sizes around the spacing, 0.5 mm normal jitter, 3 deg tilt, 15 % below the 0.2 "
      "opacity filter, 0.3 % floaters 5-30 mm off the surface and clear of it by 2 mm{}), loaded as INRIA PLY, the force model's "
      "default world ({}, 1 sigma). The device is ideal and position-controlled: it follows the script, and "
      "the force the servo commands (the runtime's step: safety layer and execution mode included) is "
      "recorded. delta = how far the tool's surface is past the true surface. Direction error: "
      "angle between F and the nearest direction of the true normal cone (a slide: of the faces the sphere "
      "reaches, the exact god-object's constraints), over ticks with |F| >= 0.1 N. "
      "Stiffness: slope of |F| over delta in [1, 5] mm while loading. Hold-through: deepest delta up to "
      "which F points out (within 90 deg of the site normal) and stays >= 10 % of the peak reached so far. W = -sum F.v dt "
      "over the closed cycle (W < 0: the scene gave back more energy than it took). Tick: render() wall "
      "time including its collision queries.\n\n",
      rep.ticks, o.rate_hz, rep.seconds, o.seed,
      o.synth.edge_sigmas > 0
          ? fmt::format("; crisp convex edges, the discs near one narrowed to {:g} standard deviations within it",
                        o.synth.edge_sigmas)
          : "",
      world_words(o.renderer));
  PlayOptions other = o.play;
  other.inline_query = !other.inline_query;
  md += fmt::format("Execution mode: **{}**{}{}.\n\n", describe_mode(o.play),
                    o.play.inline_query == default_play_options().inline_query ? " (the runtime's default)" : "",
                    o.compare_modes ? fmt::format("; the W columns also give the same presses {}", describe_mode(other))
                                    : std::string());
  md += fmt::format("## Press ({} sites per shape: 2 cm/s to {:g} mm, hold 0.5 s, retract)\n\n", o.press_sites,
                    o.press_depth * 1e3);
  md += press_table(rep.press) + "\n";
  md += "### Stiffness across densities (1.00 = the wall does not depend on the training run)\n\n";
  md += stiffness_ratios(rep.press) + "\n";
  if (!rep.push.empty()) {
    md += fmt::format("## Push-through ({} face sites: 2 cm/s to {:g} mm past the surface, retract)\n\n",
                      o.push_sites, o.push_depth * 1e3);
    md += press_table(rep.push) + "\n";
  }
  if (!rep.slide.empty()) {
    md += "## Slide (10 cm at 5 cm/s, 2 mm past the surface; the first and last 5 mm not scored)\n\nLost %: the share of the scored path (the worst run) with abs F below 0.1 N. The tool is 2 mm past the surface all along it, so every such tick lost the surface; the direction error is scored over the other ticks only. Largest step: the largest change of the force from one tick to the next along the scored path (the worst run), N; a rigid surface's force turns smoothly at a constant depth and speed.\n\n";
    md += slide_table(rep.slide) + "\n";
  }
  if (!rep.wrench.empty()) {
    md += fmt::format(
        "## 6-DoF: compound tools and the torque ({} site(s) per case: 2 cm/s to {:g} mm past the touch point along the "
        "press axis, hold 0.3 s, retract; orientation held)\n\n",
        o.wrench_sites, o.wrench_depth * 1e3);
    md += fmt::format(
        "Tools: stylus `{}`, disc `{}`. Analytic answer (wrench_fidelity.h): the tool lifted along the press axis until "
        "it just touches the true surface; the touching parts' exact tangent points and normals; expected torque "
        "tau* = (c - x_tcp) x (abs F n). Force direction: angle between F and n (ticks with abs F >= 0.1 N). Torque: "
        "ticks with abs F >= 0.5 N, its magnitude against abs tau* clipped to the safety layer's torque limit ({:g} N m: "
        "what the hand can get); cases whose analytic lever is under 1 mm (the stylus tip-first at 0 deg, the "
        "flat disc) report the lever abs tau / abs F they got instead. Deepest part: how far the proxy's tool "
        "overlaps the true surface along the press axis at its worst tick (Gaussians stand about half their "
        "thickness proud of it, so a proxy resting on them reads slightly negative).\n\n",
        describe(o.wrench_tools.stylus), describe(o.wrench_tools.disc), o.play.safety.tau_max);
    md += wrench_table(rep.wrench) + "\n";
  }
  if (!rep.material.empty()) {
    md += fmt::format(
        "## Materials (the plane with two materials side by side; {} presses per side as above, one slide across the "
        "border)\n\n"
        "Soft for x < 0, hard for x >= 0 (`gshaptics synth plane --two-materials FILE` writes the map). Stiffness: the "
        "presses' median against the material's coupling stiffness. F_t / F_n: the slide (2 mm deep, 5 cm/s, along +x) on each "
        "side, mean -F_x over mean F_z (friction against the motion over the normal force), farther than 3 tool radii from the border, against the material's mu_k. Border step: the largest change "
        "of the commanded force in one tick within 3 tool radii of the border, against the safety layer's rate limit "
        "(a step at the limit was clipped by it).\n\n",
        o.material_presses);
    md += material_table(rep.material) + "\n";
  }
  if (!rep.texture.empty()) {
    md += "## Texture (gratings dragged 2 mm deep at constant speed; the proxy with texture gain 1)\n\n"
          "Gratings: the plane with the relief A sin(2 pi x / lambda), Gaussians every lambda / 8 across the ridges "
          "(`gshaptics synth grating --grating LAMBDA_MM,A_MM`), built in memory; the plane without relief is drawn the "
          "same way with A = 0 (lambda 2 mm). The sphere tools, then the stylus held upright (its tip, the TCP, "
          "where the smallest sphere's lowest point was), each on the force model's own surface, drag 6 cm along x, 2 mm past the mean plane (2 N at 1000 N/m). Scored: the normal force F_z over the middle 3 cm. Peak: the strongest sinusoid between 2 and 490 Hz "
          "(Hann window); held when it lies within 5 % of v / lambda and grows with A. The plane without relief holds "
          "when its RMS is under 10 % of the lambda 2 mm, A 0.1 mm grating's at the same speed and tool.\n\n";
    md += texture_table(rep.texture) + "\n";
  }
  if (!rep.defect.empty()) {
    md += fmt::format(
        "## Capture defects ({} site(s) per patch: its centre and points half its radius out; presses as above)\n\n"
        "The plane with one patch of what trained captures leave (`gshaptics synth plane --defect KIND`); the analytic "
        "plane stays the truth. Each spacing and tool first presses the plane without a defect at the same "
        "sites (\"none\"). Held where the plane is: never lost, and the onset's median within 1 mm of that "
        "plane's, or over a hole up to 1 mm beyond the depth at which a rigid sphere meets its rim (the rigid tool's "
        "column).\n\n",
        o.defect_sites);
    md += describe_defects(o) + "\n" + defect_table(o, rep.defect) + "\n";
  }
  if (!figures_prefix.empty()) {
    md += "## Figures\n\n";
    for (const char* f : {"press", "direction", "slide", "push"})
      md += fmt::format("![{}]({}{}.png)\n\n", f, figures_prefix, f);
  }
  write_file_atomically(path, md);
}

void write_fidelity_data(const FidelityReport& rep, const std::string& dir) {
  std::filesystem::create_directories(dir);
  std::map<std::string, std::string> files = {{"press", "scenario,shape,spacing_mm,tool_mm,x_mm,force_n,f_normal_n\n"},
                                              {"slide", "scenario,shape,spacing_mm,tool_mm,x_mm,force_n,f_normal_n\n"},
                                              {"push-through", "scenario,shape,spacing_mm,tool_mm,x_mm,force_n,f_normal_n\n"}};
  for (const FidelityCurve& c : rep.curves)
    for (std::size_t i = 0; i < c.x_mm.size(); ++i)
      files[c.scenario] += fmt::format("{},{},{:g},{:g},{:.4f},{:.5f},{:.5f}\n", c.scenario, c.shape, c.spacing * 1e3,
                                       c.tool_radius * 1e3, c.x_mm[i], c.force[i], c.f_normal[i]);
  write_file_atomically(dir + "/press_curves.csv", files["press"]);
  write_file_atomically(dir + "/slide_curves.csv", files["slide"]);
  write_file_atomically(dir + "/push_curves.csv", files["push-through"]);
  // Direction errors as a histogram per shape: 1-degree bins from 0 to 180.
  std::string d = "shape,bin_deg,count\n";
  for (const auto& [shape, v] : rep.press_directions) {
    std::vector<std::size_t> bins(180, 0);
    for (double x : v) ++bins[std::min<std::size_t>(179, std::size_t(std::max(0.0, x)))];
    for (std::size_t b = 0; b < bins.size(); ++b) d += fmt::format("{},{},{}\n", shape, b, bins[b]);
  }
  write_file_atomically(dir + "/press_directions.csv", d);
}

}  // namespace gshaptics
