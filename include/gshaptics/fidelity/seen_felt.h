#pragma once
/// @file
/// Seen against felt on real scenes: does the force start, and the proxy rest, where the
/// renderer shows a surface? The benchmark of issue 71 (`gshaptics seen-felt`).
///
/// For each scene, tool size and press direction it draws rays onto the seen surface
/// (scene/seen_surface.h: the 3DGS median depth over every Gaussian of the file on the ray's
/// line, seen from an eye outside all of them, as a viewer outside the scene draws it), keeps those
/// whose seen surface is within `facing_deg` of facing the ray, and presses a sphere tool of
/// radius R along each ray, from the ray's start (the eye) to `past` R beyond the seen surface,
/// then holds. The press is played by an ideal position-controlled device through the servo step
/// of a real-time run (play_script: SimulatedRuntime, safety layer and execution mode included),
/// with the force renderer of `renderer` on the default world of the scene for that renderer (the
/// scene in its file's frame, the opacity filter at default_min_opacity()).
///
/// Per ray, in tool radii R (depths of the tool's leading point, the centre + R u):
/// - felt - seen: where the proxy's leading point rests at the end, against the seen depth of the
///   parallel ray through the proxy (so sliding along a curved surface does not count as going
///   in; the ray's own seen depth when that ray sees nothing);
/// - onset - seen: the device's leading point at the first tick with |F| >= 0.1 N (NaN: none);
/// - through: felt - seen > 1 R; no force: |F| < 0.1 N on every tick while the tool ends past the
///   seen surface (felt - seen > 0; a tool with a shape can pass beside a feature thinner than
///   itself that its ray aims at, and is then never under what the eye sees).
/// Rays whose tool is held (|F| >= 0.1 N) on the first tick, caught before its start, are dropped
/// and counted. Rays whose seen point lies more than `max_kink` R behind its four neighbours'
/// (0.5 R across the ray, the lines the facing is read from) are played but not scored for where
/// the force begins and the tool rests: a line threading a slot narrower than the tool sees what
/// lies behind the slats the tool rests on (on the Truck, seed 11 from around with a 2.5 %
/// sphere: a grille whose slots read 5.4 R deeper than the slats 0.24 R off). Their through and
/// no-force rays count like the kept rays'.
///
/// Tools (SeenFeltOptions::tool): the sphere of radius R, or a tool with a shape sized by R and
/// held at a fixed orientation through the press (seen_felt_tool()). Its leading point is its
/// support point along the ray (the point of its posed parts furthest along u), which replaces
/// "the centre + R u" above; the felt point is the support point of the tool posed at the proxy's
/// TCP with the press's orientation (the proxies on the seen solid keep the device's orientation).
/// Its depth against the seen surface is the deepest over lines along the ray through the middle
/// of each part's shadow (the inner 60 %; each line seen from its own eye), not the line through
/// its leading point alone: a stylus
/// whose shaft rests on a ledge, its tip in the air, is felt at the seen surface, not early. Its
/// onset reads its whole shadow (to 0.97 of each part's radius): a force is early only when no
/// point of the tool touches what the eye sees (a disc's rim landing on a surface beside the ray
/// is a touch).
/// Rays whose tool starts with a part within R/4 of the seen surface, or below it (its shaft in a
/// wall beside the ray), are dropped as caught.
///
/// Directions: vertical presses go along the scene's down (SeenFeltOptions::down; the file frame's
/// +y, the 3DGS/COLMAP convention, by default), aimed at the middle 80 % of the kept Gaussians'
/// 1-99 percentile box; presses from around are horizontal at a random azimuth, aimed at its
/// middle 60 %. Deterministic for a seed.

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/fidelity/fidelity_run.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/scene/seen_surface.h"

namespace gshaptics {

enum class PressDirection { kVertical, kAround };
[[nodiscard]] std::string_view to_string(PressDirection d);
/// "vertical" or "around"; InputError otherwise.
[[nodiscard]] PressDirection parse_press_direction(std::string_view name);

/// The tool pressed along the rays, sized by R (a tool fraction of the extent). Sphere: radius R
/// (the issue's tool). Stylus: parse_tool_spec's "stylus:24R,R", the fidelity's 12 cm pen of 5 mm
/// radius scaled, pressed tip first with its axis tilted by SeenFeltOptions::tilt_deg from the
/// ray. Disc: "disc:4R,2R" (semi-axes 4R, 4R, R), its axis tilted by tilt_deg from the ray (at 0:
/// face first; tilted, its rim leads).
enum class SeenFeltTool { kSphere, kStylus, kDisc };
[[nodiscard]] std::string_view to_string(SeenFeltTool t);
/// "sphere", "stylus" or "disc"; InputError otherwise.
[[nodiscard]] SeenFeltTool parse_seen_felt_tool(std::string_view name);
/// The tool of `kind` at size `radius` (scene units). Sphere: CompoundTool::single.
[[nodiscard]] CompoundTool seen_felt_tool(SeenFeltTool kind, double radius);

/// What to measure. Tool sizes are fractions of the scene's robust extent (robust_extent()).
struct SeenFeltOptions {
  RendererSpec renderer;                                ///< default: the proxy
  PlayOptions play = default_play_options();           ///< the runtime's execution mode and safety layer
  std::vector<double> tool_fractions = {0.005, 0.01, 0.02};
  std::vector<PressDirection> directions = {PressDirection::kVertical, PressDirection::kAround};
  SeenFeltTool tool = SeenFeltTool::kSphere;
  /// deg: a stylus's or disc's axis against the ray, toward an azimuth that turns by the golden
  /// angle from one drawn ray to the next (ignored for the sphere)
  double tilt_deg = 30;
  int rays = 20;             ///< kept rays per configuration (scene, tool, direction)
  int max_candidates = 4000;  ///< rays drawn per configuration at most
  double facing_deg = 20;    ///< largest angle between the seen normal and -u
  /// R: largest SeenPoint::kink of the seen point behind its four neighbours 0.5 R off the ray:
  /// past it the ray's line threads a slot narrower than the tool (a grille's, seen through to
  /// what lies behind the slats), and its seen depth is no face the tool can press on. Such rays
  /// are played and count for through and no force, but not toward the kept rays and the felt
  /// and onset percentiles (SeenFeltRay::slot). A spike (the centre nearer) is kept: the tool
  /// must feel it.
  double max_kink = 1;
  double past = 4;           ///< R beyond the seen surface the device goes
  double start = 16;         ///< R before the seen surface the device starts (the eye at least that far)
  double speed = 4;          ///< R per second along the ray
  double hold = 0.3;         ///< s held at the deepest point before the proxy is read
  double rate_hz = kDefaultServoRateHz;
  double force_threshold = 0.1;  ///< N: "a force"
  std::uint64_t seed = 1;
  /// The scene's down (unit, scene frame): vertical presses go along it, presses from around
  /// perpendicular to it. Default: the 3DGS/COLMAP file frame's +y.
  Eigen::Vector3d down = Eigen::Vector3d::UnitY();
  /// When set (lo, hi; scene frame): rays are aimed at this box's middle instead of the kept
  /// Gaussians' percentile box (the rigid objects of a scene: `seen-felt --object`). Tool sizes
  /// stay fractions of the world's extent.
  std::optional<std::array<Eigen::Vector3d, 2>> aim_box;
};

/// The CI subset: 3 rays per configuration, the 1 % tool only.
[[nodiscard]] SeenFeltOptions quick_seen_felt_options();

/// One pressed ray. Depths in R.
struct SeenFeltRay {
  std::string scene;
  PressDirection direction = PressDirection::kVertical;
  double tool_fraction = 0, tool_radius = 0;  ///< fraction of the extent; scene units
  Eigen::Vector3d origin = Eigen::Vector3d::Zero(), dir = Eigen::Vector3d::Zero();  ///< the ray (eye, unit)
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< the tool's, held through the press
  double seen = 0;              ///< seen depth from the origin, scene units
  double facing_deg = 0;        ///< seen normal against -dir
  double felt_minus_seen = NAN;  ///< R
  double onset_minus_seen = NAN; ///< R; NaN: no force
  /// R; NaN: no force. Where the force began, the deepest point of the tool's whole shadow past
  /// the seen surface (over the parallel lines it started at least 0.25 R above): about 0 or more
  /// where some point of the tool touched what the eye sees (a sphere's side on a ledge beside the
  /// ray), well below 0 an invisible wall. The stylus's and the disc's onset_minus_seen is read so
  /// already; a sphere's is read on its centre line (the issue's measure), this over its shadow.
  double onset_shadow = NAN;
  /// R; NaN: no force at the end of the hold. Where the tool rests then, the deepest point of its
  /// whole shadow past the seen surface, read on lines along the ray (those it started at least
  /// 0.25 R above) and on lines along the force that holds it (into the surface, each seen from
  /// just behind the tool), the larger: about 0 or more where it rests on what the eye sees (a
  /// stylus's side against a wall the ray runs beside is seen along the force, a disc's rim on a
  /// droplet's side along the ray), well below 0 an invisible wall holding it.
  double rest_shadow = NAN;
  double peak_force = 0;        ///< N
  bool through = false, no_force = false;
  /// The seen point lies more than SeenFeltOptions::max_kink R behind its neighbours': a slot
  /// narrower than the tool. Counted for through and no force only.
  bool slot = false;
  double render_p99_us = NAN;   ///< over the ray's ticks
};

/// One configuration: a scene, a direction and a tool.
struct SeenFeltRow {
  std::string scene;
  PressDirection direction = PressDirection::kVertical;
  double tool_fraction = 0, tool_radius = 0;
  int rays = 0, through = 0, no_force = 0, caught = 0, drawn = 0;
  /// Rays in a slot narrower than the tool (SeenFeltRay::slot), played besides the kept rays;
  /// their through and no-force rays are counted in `through` and `no_force`.
  int slots = 0;
  double felt_p90 = NAN;   ///< R, p90 of felt - seen
  double onset_p10 = NAN;  ///< R, p10 of onset - seen over rays with a force
  double onset_shadow_min = NAN;  ///< R, the least SeenFeltRay::onset_shadow over rays with a force
  double rest_shadow_min = NAN;   ///< R, the least SeenFeltRay::rest_shadow over rays held at the end
  double render_p99_us = NAN;
  /// The issue's targets: <= 1 ray through, no ray without force, felt p90 <= 0.5 R, onset p10
  /// >= -1 R, and `rays` kept.
  [[nodiscard]] bool meets_targets(int wanted_rays) const;
};

struct SeenFeltReport {
  SeenFeltOptions options;
  std::vector<SeenFeltRow> rows;
  std::vector<SeenFeltRay> rays;
  double seconds = 0;
};

using SeenFeltProgressFn = std::function<void(const std::string&)>;

/// Measures one scene: `scene` (every Gaussian, the seen surface) and `world` (built from it in
/// the scene's frame: scene_to_world() must be the identity; InputError otherwise). Appends its
/// rows and rays to `report`. Throws InputError for bad options.
void measure_seen_felt(const std::string& name, const GaussianScene& scene, const CollisionWorld& world,
                       const SeenFeltOptions& options, SeenFeltReport& report, const SeenFeltProgressFn& progress = {});
/// The same with the caller's renderer (played through the servo step as above), e.g. an
/// ObjectRenderer over the static part of a scene and its rigid objects (objects/object_renderer.h):
/// `world` then holds the static part, `scene` the file as captured (the seen truth), and
/// o.renderer is not used to make one. play_script resets the renderer before each ray, which
/// puts the objects back at rest.
void measure_seen_felt(const std::string& name, const GaussianScene& scene, const CollisionWorld& world,
                       ForceRenderer& renderer, const SeenFeltOptions& options, SeenFeltReport& report,
                       const SeenFeltProgressFn& progress = {});

/// Loads each scene file (load_scene), builds its default world and measures it.
[[nodiscard]] SeenFeltReport run_seen_felt(const std::vector<std::string>& scene_files, const SeenFeltOptions& options,
                                           const SeenFeltProgressFn& progress = {});

/// The report as Markdown (the summary per scene, then every configuration, the command and the
/// figure), written atomically.
void write_seen_felt_markdown(const SeenFeltReport& report, const std::string& path, const std::string& command,
                              const std::string& figure);
/// Every ray as CSV (for tools/plot_seen_felt.py), written atomically.
void write_seen_felt_csv(const SeenFeltReport& report, const std::string& path);

}  // namespace gshaptics
