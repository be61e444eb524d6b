#include "gshaptics/fidelity/seen_felt.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <optional>
#include <random>

#include "gshaptics/error.h"
#include "gshaptics/fidelity/fidelity_run.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/percentile.h"
#include "gshaptics/sim/pose_sampler.h"
#include "gshaptics/collision/ellipsoid_line.h"

namespace gshaptics {

std::string_view to_string(PressDirection d) { return d == PressDirection::kVertical ? "vertical" : "around"; }

PressDirection parse_press_direction(std::string_view name) {
  if (name == "vertical") return PressDirection::kVertical;
  if (name == "around") return PressDirection::kAround;
  throw InputError(fmt::format("seen-felt: unknown direction '{}' (vertical, around)", name));
}

std::string_view to_string(SeenFeltTool t) {
  switch (t) {
    case SeenFeltTool::kStylus: return "stylus";
    case SeenFeltTool::kDisc: return "disc";
    case SeenFeltTool::kSphere: break;
  }
  return "sphere";
}

SeenFeltTool parse_seen_felt_tool(std::string_view name) {
  for (SeenFeltTool t : {SeenFeltTool::kSphere, SeenFeltTool::kStylus, SeenFeltTool::kDisc})
    if (name == to_string(t)) return t;
  throw InputError(fmt::format("seen-felt: unknown tool '{}' (sphere, stylus, disc)", name));
}

CompoundTool seen_felt_tool(SeenFeltTool kind, double radius) {
  switch (kind) {
    case SeenFeltTool::kStylus: return parse_tool_spec(fmt::format("stylus:{},{}", 24 * radius, radius));
    case SeenFeltTool::kDisc: return parse_tool_spec(fmt::format("disc:{},{}", 4 * radius, 2 * radius));
    case SeenFeltTool::kSphere: break;
  }
  return CompoundTool::single(Eigen::Vector3d::Constant(radius));
}

SeenFeltOptions quick_seen_felt_options() {
  SeenFeltOptions o;
  o.rays = 3;
  o.max_candidates = 400;
  o.tool_fractions = {0.01};
  return o;
}

bool SeenFeltRow::meets_targets(int wanted_rays) const {
  return rays >= wanted_rays && through <= 1 && no_force == 0 && felt_p90 <= 0.5 && onset_p10 >= -1.0;
}

namespace {

void validate(const SeenFeltOptions& o) {
  const bool ok = o.rays > 0 && o.max_candidates >= o.rays && o.facing_deg > 0 && o.facing_deg < 90 && o.max_kink > 0 && o.past > 0 &&
                  o.start > 0 && o.speed > 0 && o.hold >= 0 && o.rate_hz > 0 && o.force_threshold > 0 &&
                  o.tilt_deg >= 0 && o.tilt_deg < 90 && !o.tool_fractions.empty() && !o.directions.empty() && std::abs(o.down.norm() - 1) < 1e-6;
  if (!ok)
    throw InputError("seen-felt: invalid options (rays, candidates, angles, speeds and tools must be positive, the "
                     "tilt within [0, 90) deg)");
  for (double f : o.tool_fractions)
    if (!(f > 0 && f < 0.5)) throw InputError(fmt::format("seen-felt: tool fraction {} outside (0, 0.5)", f));
}

constexpr double kGoldenAngle = 2.399963229728653;  // rad, pi (3 - sqrt 5)

/// One configuration's frame: where rays are drawn, the tool, and the draw.
struct RayDraw {
  Eigen::Vector3d lo, hi;  // the kept Gaussians' 1-99 percentile box
  double radius = 0;
  PressDirection direction = PressDirection::kVertical;
  std::mt19937_64 rng;
};

// The seen surface as a viewer outside the scene draws it along a ray: every Gaussian on the
// ray's line counts, those behind the ray's start too (a ray starts R outside the kept
// Gaussians' percentile box, and the floaters beyond it are drawn all the same). The eye stands
// past every Gaussian's centre, `back` behind the ray's origin; depths are from the origin.
struct Viewer {
  const SeenSurface* seen = nullptr;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // of the box of every Gaussian's centre
  double span = 0;  // that box's diagonal plus its largest Gaussian's reach

  Viewer(const SeenSurface& s, const GaussianScene& scene) : seen(&s) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
    double widest = 0;
    for (std::size_t i = 0; i < scene.size(); ++i) {
      const Eigen::Vector3d m = scene.means[i].cast<double>();
      lo = lo.cwiseMin(m);
      hi = hi.cwiseMax(m);
      widest = std::max(widest, double(scene.scales[i].maxCoeff()));
    }
    if (scene.size() > 0) {
      centre = 0.5 * (lo + hi);
      span = (hi - lo).norm() + 4 * widest;  // alpha >= 1/255 lies within 3.3 sigma of a centre
    }
  }
  [[nodiscard]] double back(const Eigen::Vector3d& origin) const { return (origin - centre).norm() + span; }
  [[nodiscard]] SeenDepth median_depth(const Eigen::Vector3d& origin, const Eigen::Vector3d& u) const {
    const double b = back(origin);
    SeenDepth d = seen->first_seen(origin - b * u, u);
    d.depth -= b;
    return d;
  }
  // median_depth() along parallel lines from `eyes` (overwritten with the eyes moved back) at once.
  void median_depths(std::vector<Eigen::Vector3d>& eyes, const Eigen::Vector3d& u, std::vector<SeenDepth>& out) const {
    std::vector<double> b(eyes.size());
    for (std::size_t i = 0; i < eyes.size(); ++i) eyes[i] -= (b[i] = back(eyes[i])) * u;
    out.resize(eyes.size());
    seen->first_seen_parallel(eyes, u, out);
    for (std::size_t i = 0; i < eyes.size(); ++i) out[i].depth -= b[i];
  }
  // The same lines seen from `eyes` themselves (a viewer inside the scene): what lies behind an
  // eye does not count.
  void depths_from(const std::vector<Eigen::Vector3d>& eyes, const Eigen::Vector3d& u, std::vector<SeenDepth>& out) const {
    out.resize(eyes.size());
    seen->first_seen_parallel(eyes, u, out);
  }
  [[nodiscard]] std::optional<SeenPoint> surface_point(const Eigen::Vector3d& origin, const Eigen::Vector3d& u,
                                                       double h) const {
    const double b = back(origin);
    std::optional<SeenPoint> p = seen->surface_point(origin - b * u, u, h);
    if (p) p->depth -= b;
    return p;
  }
};

// A ray of the configuration: aimed at a random point of the box's middle (80 % across for
// vertical rays, 60 % for rays from around), its eye `start` R outside the box; unit u.
std::pair<Eigen::Vector3d, Eigen::Vector3d> draw_ray(RayDraw& d, const Eigen::Vector3d& down, double start) {
  std::uniform_real_distribution<double> uni(0, 1);
  const Eigen::Vector3d size = d.hi - d.lo;
  const double share = d.direction == PressDirection::kVertical ? 0.8 : 0.6;
  Eigen::Vector3d aim;
  for (int k = 0; k < 3; ++k) aim[k] = d.lo[k] + size[k] * ((1 - share) / 2 + share * uni(d.rng));
  Eigen::Vector3d u = down;
  if (d.direction == PressDirection::kAround) {
    const double phi = 2 * std::numbers::pi * uni(d.rng);
    const Eigen::Vector3d a = down.unitOrthogonal(), b = down.cross(a);
    u = std::cos(phi) * a + std::sin(phi) * b;
  }
  double back = 1e300;  // distance from the aim to the box's boundary along -u
  for (int k = 0; k < 3; ++k) {
    if (u[k] > 1e-12) back = std::min(back, (aim[k] - d.lo[k]) / u[k]);
    if (u[k] < -1e-12) back = std::min(back, (d.hi[k] - aim[k]) / -u[k]);
  }
  return {aim - (back + start * d.radius) * u, u};
}

// The tool held through one press: its parts, orientation and leading point (its support along
// the ray, relative to the TCP).
struct PressedTool {
  CompoundTool tool;  // count 0: the sphere of radius `radius` (the one-part proxy's own tool)
  double radius = 0;
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d lead = Eigen::Vector3d::Zero();  // the support point along u, from the TCP
  [[nodiscard]] double lead_depth(const Eigen::Vector3d& u) const { return lead.dot(u); }
};

// The tool of the options for a ray along u, its axis tilted toward the azimuth `phi` about u.
PressedTool pressed_tool(const SeenFeltOptions& o, double radius, const Eigen::Vector3d& u, double phi) {
  PressedTool t;
  t.radius = radius;
  if (o.tool == SeenFeltTool::kSphere) {
    t.lead = radius * u;
    return t;
  }
  t.tool = seen_felt_tool(o.tool, radius);
  const Eigen::Vector3d a = u.unitOrthogonal(), b = u.cross(a);
  const double tilt = o.tilt_deg * std::numbers::pi / 180;
  // The stylus points back up the ray from its tip; a disc's axis lies along the ray.
  const Eigen::Vector3d axis = (o.tool == SeenFeltTool::kStylus ? -1.0 : 1.0) * std::cos(tilt) * u +
                               std::sin(tilt) * (std::cos(phi) * a + std::sin(phi) * b);
  t.orientation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), axis);
  std::array<ToolEllipsoid, kMaxToolParts> parts{};
  const int n = t.tool.posed(Eigen::Vector3d::Zero(), t.orientation, parts);
  double best = -INFINITY;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = parts[std::size_t(i)].surface_point(u);
    if (p.dot(u) > best) {
      best = p.dot(u);
      t.lead = p;
    }
  }
  return t;
}

// The press along a ray: the tool's leading point from `from` to `to` (depths from the origin)
// at `speed`, then a hold.
Script press_along(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, const PressedTool& tool, double from,
                   double to, const SeenFeltOptions& o) {
  Script s;
  s.scenario = Scenario::kPress;
  s.tool_radius = tool.radius;
  s.tool = tool.tool;
  s.max_delta = to - from;
  const double v = o.speed * tool.radius, dt = 1.0 / o.rate_hz;
  const auto moving = static_cast<std::size_t>(std::ceil((to - from) / (v * dt)));
  const auto holding = static_cast<std::size_t>(std::ceil(o.hold / dt));
  s.ticks.reserve(moving + holding + 1);
  for (std::size_t k = 0; k <= moving + holding; ++k) {
    ScriptTick t;
    t.time = double(k) * dt;
    const double lead = std::min(to, from + v * t.time);
    t.position = origin + (lead - tool.lead_depth(u)) * u;
    t.orientation = tool.orientation;
    t.velocity = k < moving ? Eigen::Vector3d(v * u) : Eigen::Vector3d::Zero();
    t.loading = k < moving;
    t.measured = true;
    s.ticks.push_back(t);
  }
  return s;
}

// How deep a tool with a shape, posed with its TCP at `tcp`, lies below the seen surface along
// u: the largest front depth of a part minus the seen depth, over lines along u through the
// middle of the tool's shadow (per part: the line through its leading point, and lines on a
// Vogel spiral over its shadow out to `fraction` of its radius, uniform by area, the centre's
// among them: spiral_lines()), each line seen from its own eye (Viewer; LineSet::from_outside false: from
// its foot on the plane through origin). Scene units; > 0: below the
// seen surface. Nullopt when no line sees a surface. A stylus resting on a ledge with its shaft
// (its tip above the ground) gives 0, which a measure at its tip alone would count as early. The
// rim of a part is left out as a sphere's sides are (its measure reads its centre's line): a tip
// grazing a wall beside it by a tenth of its radius would read as the wall's whole height through.
// The onset reads the whole shadow (kOnsetFraction: short of the rim itself, where a line is
// tangent to the part): a force is early only when no point of the tool touches what the eye sees,
// and a disc's or a stylus's rim landing on a surface beside the ray is a touch. Of those lines it
// counts only the ones the tool started at least kStartClearance R above (LineSet::came): one it
// started past lies beside a wall, or behind what the eye sees before the ray's start.
constexpr double kMeasureFraction = 0.6, kOnsetFraction = 0.97;
struct LineSet {
  double fraction = kMeasureFraction;  // of each part's shadow radius
  double came = NAN;                   // how far the tool has come along u since its start (NaN: every line)
  double clearance = 0;                // how far above its seen surface the tool must have started on a line
  bool from_outside = true;            // each line's eye outside the scene (Viewer); false: its foot on the origin's plane
};

// How many spiral lines read a part's shadow out to `fraction` of its radius: as many as put them
// kLineSpacing of the part's smallest semi-axis apart (by area; at least 96, at most 32768). The
// readings are maxima over lines, so a feature thinner than the lines are apart can hide between
// them: at 0.35 R the Truck stylus's early onsets (-3.0 / -12.3 / -13.9 R) were a wire between
// the lines, at 0.1 R one stayed at -2.8 R, at 0.05 R and at 0.035 R every reading of that
// configuration agrees within 0.03 R (bench/RESULTS.md, the hundred-and-second session): the
// measure has converged there. A stylus part's shadow (R by 2.2 R) takes about 2,600 lines, a
// sphere's 1,200, a disc's 17,000, read at once (SeenSurface::first_seen_parallel).
constexpr double kLineSpacing = 0.05;
int spiral_lines(const ToolEllipsoid& part, const ToolShadow& shadow, double fraction) {
  const double spacing = kLineSpacing * part.semi_axes.minCoeff();
  const double area = std::numbers::pi * std::abs(shadow.l.determinant()) * fraction * fraction;
  return int(std::clamp(std::ceil(area / (spacing * spacing)), 96.0, 32768.0));
}

std::optional<double> depth_below_seen(const Viewer& seen, const PressedTool& tool, const Eigen::Vector3d& tcp,
                                       const Eigen::Vector3d& origin, const Eigen::Vector3d& u,
                                       const LineSet& lines = {}) {
  std::array<ToolEllipsoid, kMaxToolParts> parts{};
  const int n = tool.tool.posed(tcp, tool.orientation, parts);
  // The line along u through p, which leaves the part at p + exit u: its eye q, on the plane
  // through origin, and the part's leading crossing from q; all read at once.
  std::vector<Eigen::Vector3d> eyes;
  std::vector<double> fronts;
  const auto add_line = [&](const Eigen::Vector3d& p, double exit) {
    const Eigen::Vector3d q = p - (p - origin).dot(u) * u;
    eyes.push_back(q);
    fronts.push_back(exit + (p - q).dot(u));
  };
  for (int k = 0; k < n; ++k) {
    const ToolEllipsoid& e = parts[std::size_t(k)];
    const ToolShadow shadow = shadow_along(e, u);
    const int count = spiral_lines(e, shadow, lines.fraction);
    for (int i = 0; i < count; ++i) {  // a Vogel spiral on the unit disc, mapped onto the shadow
      const double rho = std::sqrt(i / double(count - 1)), phi = kGoldenAngle * i;
      const Eigen::Vector3d p = e.center + shadow.at(lines.fraction * rho * Eigen::Vector2d(std::cos(phi), std::sin(phi)));
      add_line(p, exit_along(e, p, u));
    }
    add_line(e.surface_point(u), 0.0);  // the leading point: its line is tangent there
  }
  std::vector<SeenDepth> seen_depths;
  if (lines.from_outside)
    seen.median_depths(eyes, u, seen_depths);
  else
    seen.depths_from(eyes, u, seen_depths);
  std::optional<double> deepest;
  for (std::size_t i = 0; i < fronts.size(); ++i) {
    const SeenDepth& sd = seen_depths[i];
    const double front = fronts[i];
    if (!sd.hit || std::isnan(front)) continue;
    if (!std::isnan(lines.came) && !(front - lines.came - sd.depth <= -lines.clearance)) continue;
    deepest = std::max(deepest.value_or(-INFINITY), front - sd.depth);
  }
  return deepest;
}

// How far the tool with its TCP at `tcp` is past the seen surface (scene units). A sphere: its
// leading point against the seen depth of the parallel ray through it (the ray's own seen depth
// when that one sees nothing), so sliding along a curved surface does not count as going in. A
// tool with a shape: depth_below_seen(), or the sphere's reading when no line of it sees a surface.
// (The onset is read against the ray's own seen depth instead: score_ray.)
double depth_past_seen(const Viewer& seen, const SeenPoint& hit, const PressedTool& tool, const Eigen::Vector3d& tcp,
                       const SeenFeltRay& ray) {
  if (tool.tool.count > 0)
    if (const std::optional<double> below = depth_below_seen(seen, tool, tcp, ray.origin, ray.dir)) return *below;
  const Eigen::Vector3d rel = tcp + tool.lead - ray.origin;
  const SeenDepth beside = seen.median_depth(ray.origin + rel - rel.dot(ray.dir) * ray.dir, ray.dir);
  return rel.dot(ray.dir) - (beside.hit ? beside.depth : hit.depth);
}

// The sphere of `tool` (count 0) as a one-part tool, for the readings over its shadow.
PressedTool as_shape(const PressedTool& tool) {
  PressedTool t = tool;
  t.tool = CompoundTool::single(Eigen::Vector3d::Constant(tool.radius));
  return t;
}

// `tool` itself when it has a shape, else its sphere as one (as_shape()).
PressedTool shaped(const PressedTool& tool) { return tool.tool.count > 0 ? tool : as_shape(tool); }

/// R: how far every part of a tool with a shape must start above the seen surface.
constexpr double kStartClearance = 0.25;

// The lines of a tool's whole shadow along the ray that it started at least kStartClearance R
// above (their seen surface), for the TCP at `tcp` having come from `start`: the onset's and the
// rest's reading along the ray.
LineSet whole_shadow(const Eigen::Vector3d& start, const Eigen::Vector3d& tcp, const SeenFeltRay& ray) {
  return LineSet{kOnsetFraction, (tcp - start).dot(ray.dir), kStartClearance * ray.tool_radius};
}

/// R: how far behind the tool's rearmost point along the force the lines of rest_along_force()
/// start (their eyes): close enough that what the tool did not come through is not read.
constexpr double kRestEyeBack = 1;

// How far the tool `shape` (shaped()) resting with its TCP at `tcp` is past the seen surface
// along `n` (unit; against the force that holds it): depth_below_seen() over its whole shadow
// (kOnsetFraction) on lines along n, each seen from kRestEyeBack R behind the tool's rearmost point
// along them. A wall the tool is pressed against from the side is seen so, where lines along the
// ray run beside it. Scene units; nullopt when no line sees a surface.
std::optional<double> rest_along_force(const Viewer& seen, const PressedTool& shape, const Eigen::Vector3d& tcp,
                                       const Eigen::Vector3d& n) {
  std::array<ToolEllipsoid, kMaxToolParts> parts{};
  const int count = shape.tool.posed(tcp, shape.orientation, parts);
  double rear = INFINITY;
  for (int k = 0; k < count; ++k) rear = std::min(rear, parts[std::size_t(k)].surface_point(-n).dot(n));
  const Eigen::Vector3d eye = tcp + (rear - tcp.dot(n) - kRestEyeBack * shape.radius) * n;
  return depth_below_seen(seen, shape, tcp, eye, n, LineSet{.fraction = kOnsetFraction, .from_outside = false});
}

// Where the tool rests with its TCP at `tcp` (from `start`), held by `force` (N): the larger of
// its whole shadow's depth past the seen surface along the ray (the lines it started at least
// kStartClearance R above, as the onset's) and along the force (rest_along_force()). Scene units;
// NaN when the force is under `threshold` or no line sees a surface.
double rest_shadow(const Viewer& seen, const PressedTool& tool, const Eigen::Vector3d& start, const Eigen::Vector3d& tcp,
                   const Eigen::Vector3d& force, const SeenFeltRay& ray, double threshold) {
  if (!(force.norm() >= threshold)) return NAN;
  const PressedTool shape = shaped(tool);
  const std::optional<double> along_ray =
      depth_below_seen(seen, shape, tcp, ray.origin, ray.dir, whole_shadow(start, tcp, ray));
  const std::optional<double> along_force = rest_along_force(seen, shape, tcp, -force.normalized());
  if (!along_ray && !along_force) return NAN;
  return std::max(along_ray.value_or(-INFINITY), along_force.value_or(-INFINITY));
}

// The onset, the TCP at `tcp` (from `start`) where the force first reaches the threshold, against
// the ray's own seen depth: a tool with a shape over its whole shadow (the sphere's reading when no
// line of it sees a surface), a sphere on its centre line; onset_shadow the larger of that and the
// whole shadow's (a sphere's rim on a ledge beside the ray). R.
void score_onset(const Viewer& seen, const SeenPoint& hit, const PressedTool& tool, const Eigen::Vector3d& start,
                 const Eigen::Vector3d& tcp, SeenFeltRay& ray) {
  const double r = ray.tool_radius;
  const std::optional<double> shadow =
      depth_below_seen(seen, shaped(tool), tcp, ray.origin, ray.dir, whole_shadow(start, tcp, ray));
  const double centre = ((tcp + tool.lead - ray.origin).dot(ray.dir) - hit.depth) / r;
  ray.onset_minus_seen = tool.tool.count > 0 && shadow ? *shadow / r : centre;
  ray.onset_shadow = shadow ? std::max(ray.onset_minus_seen, *shadow / r) : ray.onset_minus_seen;
}

/// Plays one kept ray and scores it; false when the tool was caught before its start (a tool
/// with a shape: also when some line of its whole shadow starts less than kStartClearance R above
/// the seen surface).
bool score_ray(ForceRenderer& renderer, const Viewer& seen, const SeenPoint& hit, const PressedTool& tool,
               SeenFeltRay& ray, const SeenFeltOptions& o) {
  const double r = ray.tool_radius;
  const double from = std::max(0.0, hit.depth - o.start * r);
  const Script script = press_along(ray.origin, ray.dir, tool, from, hit.depth + o.past * r, o);
  if (tool.tool.count > 0) {
    // A tool with a shape may start with a part already inside what the eye sees, its rim too: a
    // stylus's tip started in a sheet seen edge-on beside the ray (a few tenths of R thick, the
    // eye sees its near end only) was held by it 12.7 R short of the ray's seen surface, where a
    // roaming footprint line of the proxy came to lie inside the sheet (bench/RESULTS.md, the
    // hundredth session). Every line a measure reads counts, the felt depth's (kMeasureFraction)
    // and the onset's and the rest's (kOnsetFraction): a thin sheet one set passes between is
    // met by the other.
    const Eigen::Vector3d& start = script.ticks.front().position;
    for (const double fraction : {kMeasureFraction, kOnsetFraction}) {
      const std::optional<double> below = depth_below_seen(seen, tool, start, ray.origin, ray.dir, LineSet{fraction});
      if (below && *below > -kStartClearance * r) return false;
    }
  }
  const ScriptTrace trace = play_script(renderer, script, o.rate_hz, o.play);
  const std::size_t first = std::min<std::size_t>(trace.force.size(), std::size_t(o.play.latency_ticks) + 2);
  for (std::size_t i = 0; i < first; ++i)
    if (trace.force[i].norm() >= o.force_threshold) return false;
  std::vector<double> us;
  for (std::size_t i = 0; i < trace.force.size(); ++i) {
    const double f = trace.force[i].norm();
    ray.peak_force = std::max(ray.peak_force, f);
    if (std::isnan(ray.onset_minus_seen) && f >= o.force_threshold)
      score_onset(seen, hit, tool, script.ticks.front().position, script.ticks[i].position, ray);
    us.push_back(trace.render_us[i]);
  }
  ray.render_p99_us = percentile(us, 99);
  ray.felt_minus_seen = depth_past_seen(seen, hit, tool, trace.proxy.back(), ray) / r;
  ray.rest_shadow = rest_shadow(seen, tool, script.ticks.front().position, trace.proxy.back(), trace.force.back(), ray, o.force_threshold) / r;
  // No force where a surface is seen: the tool ends past the seen surface under it. (A stylus's
  // tip aimed at a feature thinner than itself can pass beside it: its middle never comes under
  // anything the eye sees, and nothing is the right force there.)
  ray.no_force = ray.peak_force < o.force_threshold && ray.felt_minus_seen > 0;
  ray.through = ray.felt_minus_seen > 1.0;
  return true;
}

SeenFeltRow summarise(const std::vector<SeenFeltRay>& rays, const std::vector<SeenFeltRay>& slots, SeenFeltRow row) {
  std::vector<double> felt, onset, us;
  for (const SeenFeltRay& r : slots) {
    ++row.slots;
    row.through += r.through ? 1 : 0;
    row.no_force += r.no_force ? 1 : 0;
  }
  for (const SeenFeltRay& r : rays) {
    ++row.rays;
    row.through += r.through ? 1 : 0;
    row.no_force += r.no_force ? 1 : 0;
    felt.push_back(r.felt_minus_seen);
    if (!std::isnan(r.onset_minus_seen)) onset.push_back(r.onset_minus_seen);
    if (!std::isnan(r.onset_shadow)) row.onset_shadow_min = std::fmin(r.onset_shadow, row.onset_shadow_min);
    if (!std::isnan(r.rest_shadow)) row.rest_shadow_min = std::fmin(r.rest_shadow, row.rest_shadow_min);
    us.push_back(r.render_p99_us);
  }
  if (!felt.empty()) row.felt_p90 = percentile(felt, 90);
  if (!onset.empty()) row.onset_p10 = percentile(onset, 10);
  if (!us.empty()) row.render_p99_us = percentile(us, 99);
  return row;
}

/// One configuration: draws rays until `rays` are kept or `max_candidates` are drawn.
void measure_configuration(const Viewer& seen, ForceRenderer& renderer, RayDraw draw, SeenFeltRow row,
                           const SeenFeltOptions& o, SeenFeltReport& report) {
  std::vector<SeenFeltRay> kept, slots;
  const double cos_facing = std::cos(o.facing_deg * std::numbers::pi / 180);
  while (int(kept.size()) < o.rays && row.drawn < o.max_candidates) {
    ++row.drawn;
    const auto [origin, u] = draw_ray(draw, o.down, o.start);
    const std::optional<SeenPoint> hit = seen.surface_point(origin, u, 0.5 * draw.radius);
    if (!hit || hit->depth < o.start * draw.radius || -hit->normal.dot(u) < cos_facing) continue;
    SeenFeltRay ray;
    ray.scene = row.scene;
    ray.direction = row.direction;
    ray.tool_fraction = row.tool_fraction;
    ray.tool_radius = draw.radius;
    ray.origin = origin;
    ray.dir = u;
    ray.seen = hit->depth;
    ray.facing_deg = std::acos(std::clamp(-hit->normal.dot(u), -1.0, 1.0)) * 180 / std::numbers::pi;
    const PressedTool tool = pressed_tool(o, draw.radius, u, kGoldenAngle * row.drawn);
    ray.orientation = tool.orientation;
    if (!score_ray(renderer, seen, *hit, tool, ray, o)) {
      ++row.caught;
      continue;
    }
    // A slot narrower than the tool: its seen depth is what lies behind the slats the tool rests on.
    ray.slot = hit->kink > o.max_kink * draw.radius;
    (ray.slot ? slots : kept).push_back(ray);
  }
  report.rows.push_back(summarise(kept, slots, row));
  report.rays.insert(report.rays.end(), kept.begin(), kept.end());
  report.rays.insert(report.rays.end(), slots.begin(), slots.end());
}

}  // namespace

void measure_seen_felt(const std::string& name, const GaussianScene& scene, const CollisionWorld& world,
                       const SeenFeltOptions& o, SeenFeltReport& report, const SeenFeltProgressFn& progress) {
  std::unique_ptr<ForceRenderer> renderer = make_force_renderer(o.renderer, world);
  measure_seen_felt(name, scene, world, *renderer, o, report, progress);
}

void measure_seen_felt(const std::string& name, const GaussianScene& scene, const CollisionWorld& world,
                       ForceRenderer& renderer, const SeenFeltOptions& o, SeenFeltReport& report,
                       const SeenFeltProgressFn& progress) {
  validate(o);
  if (!world.scene_to_world().is_identity())
    throw InputError(fmt::format("seen-felt: {}: the world must be in the scene's own frame", name));
  const SeenSurface surface(scene);
  const Viewer seen(surface, scene);
  RayDraw draw;
  robust_box(world, draw.lo, draw.hi);
  const double extent = (draw.hi - draw.lo).maxCoeff();
  if (o.aim_box) {
    draw.lo = (*o.aim_box)[0];
    draw.hi = (*o.aim_box)[1];
  }
  for (PressDirection direction : o.directions) {
    for (double fraction : o.tool_fractions) {
      draw.radius = fraction * extent;
      draw.direction = direction;
      draw.rng.seed(o.seed * 1000003u + std::uint64_t(direction == PressDirection::kAround) * 7919u +
                    std::uint64_t(std::llround(fraction * 1e5)));
      SeenFeltRow row;
      row.scene = name;
      row.direction = direction;
      row.tool_fraction = fraction;
      row.tool_radius = draw.radius;
      measure_configuration(seen, renderer, draw, row, o, report);
      if (progress) {
        const SeenFeltRow& r = report.rows.back();
        progress(fmt::format("{:<11} {:<8} R = {:.1f} %: {}/{} through, {} no force, felt p90 {:+.2f} R, onset p10 "
                             "{:+.2f} R ({} drawn, {} caught, {} in slots)",
                             name, to_string(direction), fraction * 100, r.through, r.rays, r.no_force, r.felt_p90,
                             r.onset_p10, r.drawn, r.caught, r.slots));
      }
    }
  }
}

SeenFeltReport run_seen_felt(const std::vector<std::string>& files, const SeenFeltOptions& o,
                             const SeenFeltProgressFn& progress) {
  validate(o);
  if (files.empty()) throw InputError("seen-felt: no scene given");
  const auto t0 = std::chrono::steady_clock::now();
  SeenFeltReport report;
  report.options = o;
  for (const std::string& file : files) {
    const LoadedScene loaded = load_scene(file);
    WorldConfig config;
    config.min_opacity = default_min_opacity(o.renderer);
    const CollisionWorld world = CollisionWorld::build(loaded.scene, config);
    measure_seen_felt(std::filesystem::path(file).filename().string(), loaded.scene, world, o, report, progress);
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

namespace {

std::string cell(const SeenFeltRow& r) {
  return fmt::format("{}/{}, {}", r.through, r.rays, r.no_force);
}

std::string number(double v, const char* f = "{:+.2f}") { return std::isnan(v) ? std::string("-") : fmt::format(fmt::runtime(f), v); }

std::string tool_description(const SeenFeltOptions& o) {
  switch (o.tool) {
    case SeenFeltTool::kStylus:
      return fmt::format("styluses (stylus:24R,R: R the rod's radius; tip first, the axis {:g} deg from the ray)",
                         o.tilt_deg);
    case SeenFeltTool::kDisc:
      return fmt::format("discs (disc:4R,2R: R the half thickness; the axis {:g} deg from the ray)", o.tilt_deg);
    case SeenFeltTool::kSphere: break;
  }
  return "sphere tools of radius R";
}

std::string summary_table(const SeenFeltReport& rep) {
  const SeenFeltOptions& o = rep.options;
  std::string md = "| scene |";
  std::string rule = "|---|";
  for (PressDirection d : o.directions)
    for (double f : o.tool_fractions) {
      md += fmt::format(" {}, R = {:g} % |", to_string(d), f * 100);
      rule += "---|";
    }
  md += " earliest onset, p10 | configurations meeting the targets |\n" + rule + "---:|---:|\n";
  std::vector<std::string> scenes;
  for (const SeenFeltRow& r : rep.rows)
    if (scenes.empty() || scenes.back() != r.scene) scenes.push_back(r.scene);
  for (const std::string& s : scenes) {
    md += "| " + s + " |";
    double earliest = NAN;
    int met = 0, configs = 0;
    for (const SeenFeltRow& r : rep.rows) {
      if (r.scene != s) continue;
      md += fmt::format(" {} |", cell(r));
      if (!std::isnan(r.onset_p10)) earliest = std::isnan(earliest) ? r.onset_p10 : std::min(earliest, r.onset_p10);
      met += r.meets_targets(o.rays) ? 1 : 0;
      ++configs;
    }
    md += fmt::format(" {} R | {}/{} |\n", number(earliest, "{:+.1f}"), met, configs);
  }
  return md;
}

std::string detail_table(const SeenFeltReport& rep) {
  std::string md =
      "| scene | direction | R (% / units) | rays | through | no force | felt - seen p90 (R) | onset - seen p10 (R) | "
      "onset over the shadow, least (R) | rest over the shadow, least (R) | caught | in a slot | drawn | render p99 (us) | targets |\n"
      "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
  for (const SeenFeltRow& r : rep.rows)
    md += fmt::format("| {} | {} | {:g} / {:.4g} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", r.scene,
                      to_string(r.direction), r.tool_fraction * 100, r.tool_radius, r.rays, r.through, r.no_force,
                      number(r.felt_p90), number(r.onset_p10), number(r.onset_shadow_min), number(r.rest_shadow_min), r.caught, r.slots, r.drawn, number(r.render_p99_us, "{:.1f}"),
                      r.meets_targets(rep.options.rays) ? "met" : "missed");
  return md;
}

}  // namespace

void write_seen_felt_markdown(const SeenFeltReport& rep, const std::string& path, const std::string& command,
                              const std::string& figure) {
  const SeenFeltOptions& o = rep.options;
  int through = 0, no_force = 0, rays = 0, met = 0;
  for (const SeenFeltRow& r : rep.rows) {
    through += r.through;
    no_force += r.no_force;
    rays += r.rays;
    met += r.meets_targets(o.rays) ? 1 : 0;
  }
  std::string md = "# Seen against felt on real scenes\n\n";
  md += fmt::format(
      "Generated by `{}` ({:.0f} s). Force model `{}`, {}; {} pressed along rays at {:g} R/s from {:g} R "
      "before the seen surface (the 3DGS median depth over every Gaussian of the file) to {:g} R past it, held {:g} s, "
      "through the servo step of a real-time run. Rays kept where the seen surface is within {:g} deg of facing the "
      "ray; {} per configuration wanted. A ray whose seen point lies more than {:g} R behind its four neighbours' "
      "mean, 0.5 R across the ray (\"in a slot\": a slot narrower than the tool, seen through to what lies behind "
      "the slats it rests on), is played besides them and counts for through and no force only. Cells: rays through (felt more than 1 R past the seen surface) / rays, and "
      "rays with no force at all. The onset is read where the force first reaches {:g} N: a sphere's on its centre "
      "line, a stylus's or a disc's over its whole shadow. \"Onset over the shadow\" (every configuration) reads a "
      "sphere's over its shadow too, against every parallel line it started at least {:g} R above: about 0 where some "
      "point of the tool touched what the eye sees (its side on a ledge beside the ray), well below 0 an invisible "
      "wall. \"Rest over the shadow\" reads the tool where it rests at the end of the hold, over its whole shadow on "
      "the lines along the ray it started {:g} R above and on lines along the force that holds it, each seen from {:g} R "
      "behind the tool, the larger: about 0 or more where it rests on what the eye sees (a stylus's side against a "
      "wall the ray runs beside is seen along the force), well below 0 an invisible wall.\n\n",
      command, rep.seconds, renderer_name(o.renderer), describe_mode(o.play), tool_description(o), o.speed, o.start, o.past, o.hold,
      o.facing_deg, o.rays, o.max_kink, o.force_threshold, kStartClearance, kStartClearance, kRestEyeBack);
  md += fmt::format("In all, {} of {} rays go more than 1 R through and {} feel nothing; {} of {} configurations meet "
                    "the targets (at most 1 ray through, none without force, felt - seen p90 <= 0.5 R, onset p10 >= "
                    "-1 R, all rays kept).\n\n",
                    through, rays, no_force, met, rep.rows.size());
  md += summary_table(rep) + "\n";
  if (!figure.empty()) md += fmt::format("![felt and onset against seen]({})\n\n", figure);
  md += "## Every configuration\n\n" + detail_table(rep);
  write_file_atomically(path, md);
}

void write_seen_felt_csv(const SeenFeltReport& rep, const std::string& path) {
  std::string csv =
      "scene,direction,tool_fraction,tool_radius,ox,oy,oz,ux,uy,uz,seen,facing_deg,felt_minus_seen,onset_minus_seen,"
      "peak_force,through,no_force,render_p99_us,tool,tilt_deg,onset_shadow_minus_seen,rest_shadow_minus_seen,slot\n";
  for (const SeenFeltRay& r : rep.rays)
    csv += fmt::format("{},{},{:g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.3f},{:.4f},{:.4f},{:.4f},{},{},{:.2f},{},{:g},{:.4f},{:.4f},{}\n",
                       r.scene, to_string(r.direction), r.tool_fraction, r.tool_radius, r.origin.x(), r.origin.y(),
                       r.origin.z(), r.dir.x(), r.dir.y(), r.dir.z(), r.seen, r.facing_deg, r.felt_minus_seen,
                       r.onset_minus_seen, r.peak_force, int(r.through), int(r.no_force), r.render_p99_us,
                       to_string(rep.options.tool), rep.options.tool == SeenFeltTool::kSphere ? 0.0 : rep.options.tilt_deg,
                       r.onset_shadow, r.rest_shadow, int(r.slot));
  write_file_atomically(path, csv);
}

}  // namespace gshaptics
