#pragma once
/// @file
/// The solid the splats render, as the hand meets it: seen from an eye behind the tool along
/// the push u, a point y is inside when the Gaussians whose peaks along the ray lie between the
/// eye and y composite to a transmittance of 1/2 or less, i.e. their optical depth
/// sum_i -log1p(-alpha_i) reaches ln 2 (../shared/DESIGN.md Sec. 2d; the 3DGS compositing of
/// Kerbl et al. 2023, alpha_i = min(0.99, o_i exp(-r_i^2 / 2)), alpha below 1/255 skipped).
///
/// With the eye behind the tool, the first such point along its approach is the 3DGS median
/// depth a viewer looking along the approach sees: what is felt is what is seen. The eye is the
/// caller's; eye_distance() puts it as far back as the tool is still seen from (SeenProxy: at
/// most seen_window tool radii), so a proxy resting in a faint layer keeps the layer in front of
/// its eye and small steps cannot creep through it, while a surface behind the tool (the floor
/// it lifts off) never holds it. Each query searches the whole segment, so no motion tunnels. Volume haptics with a proxy on
/// opacity (Lundin, Ynnerman and Gudmundsson 2002) is the classical ground; the normal is the
/// one the renderer shades the seen surface with (its normal map along kNormalRays parallel rays).
///
/// Frame and units: the world's (CollisionWorld), lengths in world units. Built once (allocates);
/// the queries are const, allocation-free and use the caller's SeenScratch.

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <optional>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <span>
#include <vector>

#include "gshaptics/broadphase/wide_bvh.h"
#include "gshaptics/huge_pages.h"
#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/collision/ellipsoid_line.h"

namespace gshaptics {

/// Per-caller working memory of SeenSolid queries (one per renderer / thread).
struct SeenScratch {
  explicit SeenScratch(std::size_t capacity = 8192) { layers.resize(capacity); }
  struct Layer {
    double t;    ///< peak depth along the ray
    double tau;  ///< -log1p(-alpha)
    std::uint32_t entry;  ///< the Gaussian (SeenSolid's slot)
  };
  std::vector<Layer> layers;
  std::size_t gathered = 0;
  bool overflow = false;  ///< more layers than capacity: the query answered conservatively
  /// What the queries on this scratch have read since it was made, cumulative (a reader takes
  /// differences across a call): tree walks (one per range gathered), leaf entries the walks
  /// tested, and layers they took. For benchmarks' breakdowns (`gshaptics_proxy_bench
  /// --breakdown`); counting costs three increments in loops that already touch the scratch.
  struct Work {
    std::uint64_t walks = 0, entries = 0, layers = 0;
    /// What was read between two readings of the counters (`after - before`).
    friend Work operator-(const Work& after, const Work& before) noexcept {
      return {after.walks - before.walks, after.entries - before.entries, after.layers - before.layers};
    }
  } work;
};

/// A blocking point along a ray.
struct SeenHit {
  bool hit = false;
  double t = 0;  ///< depth of the blocking point from the ray's origin (>= t0)
  std::uint32_t layers = 0;  ///< layers in the window at the hit
  /// normal_ray() only: the rendered normal's sum along the ray, sum_k T_k alpha_k n_k over the
  /// layers of its window up to the hit (SeenSolid::normal); zero otherwise.
  Eigen::Vector3d shade = Eigen::Vector3d::Zero();
};

/// A line's last search on a SeenSolid (first_inside() or push()), kept to answer the next one
/// on the same line without searching: the first crossing along a fixed line seen from a fixed
/// eye does not depend on the window searched around it, so a crossing found past the last
/// window's start stays while the new window holds it, and none up to the last window's end
/// stays none up to any end short of it. What SeenProxy's footprint rays and SeenCompoundProxy's
/// leading points and footprint lines keep while the proxy rests (the device pressing on, the
/// proxy held by static friction). Depths are along the line from its origin.
struct SeenLineMemo {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d u = Eigen::Vector3d::Zero();
  double eye = 0, from = 0, reach = 0;
  double t = std::numeric_limits<double>::infinity();  ///< the crossing (+inf: none up to reach)
  bool valid = false;

  /// The crossing along o + t dir seen from eye_t, searched over [from_t, reach_t], into t_out
  /// when the last search decides it (the line's origin and eye within `same`, its direction to
  /// rounding); false when it must be searched.
  bool reuse(const Eigen::Vector3d& o, const Eigen::Vector3d& dir, double eye_t, double from_t, double reach_t,
             double same, double& t_out) const noexcept {
    if (!valid || (o - origin).squaredNorm() > same * same || (dir - u).squaredNorm() > 1e-24 ||
        std::fabs(eye_t - eye) > same)
      return false;
    if (std::isfinite(t)) {
      if (!(t > from && t >= from_t && t <= reach_t)) return false;
    } else if (!(reach_t <= reach && from_t >= from)) {
      return false;
    }
    t_out = t;
    return true;
  }
  /// A search's answer (t: +inf when none).
  void keep(const Eigen::Vector3d& o, const Eigen::Vector3d& dir, double eye_t, double from_t, double reach_t,
            double t_found) noexcept {
    origin = o;
    u = dir;
    eye = eye_t;
    from = from_t;
    reach = reach_t;
    t = t_found;
    valid = true;
  }
  void forget() noexcept { valid = false; }
};

/// The footprint and the rise bound the seen proxies share: SeenProxy (a sphere; lengths in its
/// radius R) and SeenCompoundProxy (parts; lengths in the tool's smallest semi-axis). One place,
/// so the sphere and the compound tool cannot drift apart.
namespace seen_footprint {
/// Footprint ray k lies at kRadius[k % 3] of the shadow's radius from the centre line, at
/// 360 / kRays * k degrees; one ray is read a tick.
inline constexpr int kRays = 12;
inline constexpr double kRadius[3] = {0.5, 0.7, 0.85};
/// A footprint ray met later than its refresh and this does not hold (the ray was read up to
/// kRays ticks ago).
inline constexpr double kLate = 0.05;
/// A new contact's surface deeper behind than its motion and this was entered before the contact.
inline constexpr double kSunkSlack = 1e-3;
/// The slope a sliding rigid body climbs tick by tick (tan 76 deg), and the rise a tick over it:
/// the footprint's lateness spread over one turn of its rays.
inline constexpr double kClimbSlope = 4.0;
inline constexpr double kClimbTick = kLate / kRays;
/// A rise of more than this in one tick is the top of a wall, not a surface slid onto.
inline constexpr double kMaxClimb = 1.0;
/// The farthest the proxy moves across its axis in one tick (slide_along_walls' `max_len`): a
/// proxy left far behind its goal (a tool jammed by a wall while the device goes on) catches up
/// at this a tick (R per ms: metres a second for millimetre tools, past any hand's speed), and
/// the walls' search, whose cost grows with its line, reads no further a tick (the seen stylus
/// held in halo's probe run searched lines 16-32 middle semi-axes long on most ticks).
inline constexpr double kMaxSlide = 1.0;

/// How far the resting proxy may rise along its axis in one tick (same unit as `slide`): a rigid
/// body rises onto a bump over the part of its shadow the bump is in, while the seen height field
/// of its leading point and footprint rises at once; bounding the rise by the slope of the
/// `slide` across the axis plus kClimbTick `scale` turns that into a ramp, not a force step.
/// `slide`: the move across the axis this tick (>= 0); `scale`: R or the smallest semi-axis.
[[nodiscard]] constexpr double rise_allowance(double slide, double scale) noexcept {
  return kClimbSlope * slide + kClimbTick * scale;
}

/// Footprint ray k's direction around the push, rad: 2 pi k / kRays.
[[nodiscard]] inline double ray_angle(int k) noexcept { return 2 * std::numbers::pi * k / kRays; }

/// Footprint ray k's offset across the push from a part's centre line, m (world frame): on
/// `shadow` (the part's shadow along the push, shadow_along), kRadius[ring] of the way to its
/// boundary in direction ray_angle(k). The seen proxies read ring kRadius[k % 3] (ring < 0);
/// the probe planner reads every ring at every direction. Never allocates, locks, logs or throws.
[[nodiscard]] inline Eigen::Vector3d ray_offset(const ToolShadow& shadow, int k, int ring = -1) noexcept {
  return kRadius[ring < 0 ? k % 3 : ring] * shadow.boundary(ray_angle(k));
}

/// How far past its surface a footprint ray may find it and still begin a contact, m, beyond the
/// tool's motion since the ray was read: kLate `unit` for a tool at rest (it moved `len` < kSunkSlack
/// `rest_unit` this tick: the direction of its chord is the device's noise, and a surface its
/// footprint is already past was not met along it), `moving` `unit` for one in motion.
/// SeenProxy: unit = rest_unit = R, moving = kLate (one rule); SeenCompoundProxy: unit = the
/// part's middle semi-axis, rest_unit = the tool's smallest, moving = its kRingSink.
[[nodiscard]] constexpr double begin_lateness(double len, double rest_unit, double unit, double moving) noexcept {
  return (len >= kSunkSlack * rest_unit ? moving : kLate) * unit;
}
}  // namespace seen_footprint

class SeenSolid {
 public:
  /// How many rays the normal reads (normal(), normal_ray()).
  static constexpr int kNormalRays = 4;
  static_assert(kNormalRays % 2 == 0, "the rays come in opposite pairs");
  /// Every Gaussian of `world` whose opacity reaches 1/255 (build the world with
  /// WorldConfig::min_opacity below the default to keep faint layers). Scales are the world's
  /// semi-axes divided by its sigma. Builds its own BVH over each Gaussian's alpha = 1/255 box
  /// (binned SAH, leaves of 2, collapsed four-wide: broadphase/wide_bvh.h). Throws
  /// std::length_error for a tree deeper than Bvh::kMaxDepth (the SAH falls back to the median
  /// where centroids do not spread, so a real scene stays far under it).
  /// `world` must outlive the solid (hit_contacts() reads its Gaussians).
  explicit SeenSolid(const CollisionWorld& world);

  [[nodiscard]] std::size_t size() const noexcept { return entries_.size(); }
  /// The four-wide BVH over the entries' alpha = 1/255 boxes (its leaves index the entries).
  [[nodiscard]] const WideBvh& tree() const noexcept { return bvh_; }
  /// The median over its Gaussians of the middle of their three scales (world units; 0 when
  /// empty): the in-plane size of a typical disc. A normal's ring narrower than that reads one
  /// or two discs and carries their tilts (normal_ring() widens it to this).
  [[nodiscard]] double typical_scale() const noexcept { return typical_scale_; }
  /// The normal's ring, in a tool's (middle) semi-axis or the typical scale, whichever is larger
  /// (bench/RESULTS.md, fiftieth session: 1 let the noise of a few discs through, 2 reached across
  /// a groove's line onto the other face; sixty-fourth: discs wider than the tool).
  static constexpr double kNormalSpan = 1.5;
  /// The radius h of the normal's ring (normal()) for a tool of (middle) semi-axis `semi_axis`:
  /// kNormalSpan times the larger of it and typical_scale(). World units. What SeenProxy and
  /// SeenCompoundProxy read their normals on.
  [[nodiscard]] double normal_ring(double semi_axis) const noexcept {
    return kNormalSpan * std::max(semi_axis, typical_scale_);
  }

  /// The first t in [t0, t1] at which o + t u (u unit) is inside, seen from the eye at
  /// o + t_back u (t_back <= t0): the optical depth of the layers peaking in [t_back, t] reaches
  /// ln 2. No hit when there is none. t0 when it is already reached at t0 (or `scratch`
  /// overflowed: scratch.overflow is set; blocked where it stands). `t_guess`: where the hit
  /// likely is (a resting proxy's last hit); the layers up to it are read first and those past it
  /// only when needed. The answer does not depend on it, only the cost.
  SeenHit first_inside(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double t_back, double t0, double t1,
                       SeenScratch& scratch, double t_guess = std::numeric_limits<double>::quiet_NaN()) const noexcept;

  /// How far behind `c` along -u (u unit) the eye of a push along u is: the farthest point, up
  /// to `max_back`, from which c is still seen (the layers between composite to a transmittance
  /// above 1/2), i.e. just in front of the nearest surface behind c. 0 when scratch overflows.
  double eye_distance(const Eigen::Vector3d& c, const Eigen::Vector3d& u, double max_back,
                      SeenScratch& scratch) const noexcept;

  /// eye_distance() and first_inside() of a push in one pass over the layers: the tool's centre
  /// `c`, its leading point `lead` ahead along u, moving `len`. Sets `eye` to the eye's distance
  /// behind c (m); the hit's t is from the leading point, in [0, len]. A surface that the layers
  /// behind the leading point already make holds the tool where it stands (t = 0), unless it is
  /// `leaving` (moving away from the surface it last rested on: the shell it lifts off from).
  /// When no layer peaks ahead of c within lead + len, there is no hit and the eye is not
  /// searched (`eye` = 0): the layers behind c alone never make a surface seen from the eye.
  /// `t_guess`: where the hit likely is (first_inside()'s: the layers ahead up to it are read
  /// first, those past it only when needed; the answer does not depend on it, only the cost).
  /// On entry `eye` is where the eye likely is (the same line's last `eye`; 0: no guess): after
  /// its first range (kFirstStage of max_back, so a surface just behind stays cheap to find), the
  /// look back reads up to kEyeGuessMargin times the guess in one traversal, rather than in ranges
  /// growing x4. Ignored unless in (0, max_back): a line nothing hid keeps the ranges growing x4,
  /// so a surface come behind it is found near. Again only the cost depends on it.
  SeenHit push(const Eigen::Vector3d& c, const Eigen::Vector3d& u, double lead, double max_back, double len,
               bool leaving, double& eye, SeenScratch& scratch,
               double t_guess = std::numeric_limits<double>::quiet_NaN()) const noexcept;
  /// push()'s look back with an eye guess g reads its second range up to g kEyeGuessMargin behind
  /// c (a line moved since it found its eye finds it a little nearer or farther).
  static constexpr double kEyeGuessMargin = 1.25;

  /// The seen surface's outward normal (unit, n . u < 0) at `point` (on the surface for a push
  /// along u), from kNormalRays rays parallel to u on a ring of radius h around `point`, evenly
  /// spaced (searched within +-`reach` of `point`, each seen from `back` before `point`'s depth).
  /// It is the mean of two unit readings of the same rays, whose errors come from different
  /// defects of a capture:
  /// - the normal the renderer shades the surface with, the normal map of 2DGS / RaDe-GS style
  ///   rendering (Huang et al. 2024; Zhang et al. 2024), composited like colour: along a ray each
  ///   Gaussian's peaks over parallel rays lie on its depth plane u^T Sigma_i^-1 (x - mu_i) = 0,
  ///   with normal n_i = -Sigma_i^-1 u / |Sigma_i^-1 u|; the reading is the sum of T_k alpha_k n_k
  ///   over the layers from the ray's window (`reach` before the point) up to the seen depth
  ///   (T_k: the transmittance in front of layer k, from the eye; the layers in front of the
  ///   window, a face that hides the ray's point from the eye or a floater, are not the surface
  ///   there and add no normal). It
  ///   carries the discs' tilts: on a plane of discs tilted 3 deg at random, a few discs under a
  ///   small ring lean it by as much, and along a slide the lean acts as friction;
  /// - the slope of the seen depth itself, by central differences over the ring's opposite pairs. It
  ///   carries the depth jitter of the discs that make each point.
  /// Where a ray sees no surface, the normal map of the rays that do (-u when none does). A ray
  /// past a crease (past_crease) is left out of both readings. Where the point lies on a convex
  /// crease along an axis (crest_weight(): a cube's edge or corner under the tool), the rays each
  /// side read different faces, and a rigid sphere resting on the crease is pushed back along
  /// the push (the god-object's answer at a convex vertex, Zilles and Salisbury 1995): that
  /// axis's slope is turned to 0 by the weight, the plane facing the push, which holds both
  /// rays' depths. Limit: an edge pushed obliquely along its line reads the push's direction
  /// too (a rigid sphere would slide along the edge). Each ray is seen from `back`
  /// before the point's depth and searched from there or from `reach` before, whichever is
  /// nearer: never from behind the eye. `phase` (rad) turns the ring about u (ray k at
  /// 2 pi k / kNormalRays + phase from u.unitOrthogonal(); SeenNormalReading reads a resting spot
  /// at several).
  /// Measured against the analytic normals in bench/RESULTS.md (fiftieth and fifty-sixth sessions).
  Eigen::Vector3d normal(const Eigen::Vector3d& point, const Eigen::Vector3d& u, double h, double reach, double back,
                         SeenScratch& scratch, double phase = 0) const noexcept;
  /// normal() one ray at a time (a caller may spread them over ticks): ray k (0 to kNormalRays - 1) of the
  /// reading at `point`, its hit's t from the ray's origin and its shade; normal_from() then
  /// combines them (h: the ring's radius; the same `phase` throughout). normal() is exactly
  /// normal_from() of the kNormalRays normal_ray()s.
  SeenHit normal_ray(const Eigen::Vector3d& point, const Eigen::Vector3d& u, int k, double h, double reach,
                     double back, SeenScratch& scratch, double phase = 0) const noexcept;
  [[nodiscard]] static Eigen::Vector3d normal_from(const Eigen::Vector3d& u, const std::array<SeenHit, kNormalRays>& hits,
                                                  double h, double phase = 0) noexcept;
  /// Whether a reading's rays (normal_ray()s at `phase`) meet anything but a smooth face within h:
  /// a ray that sees no surface, a ray past a crease (past_crease) or an axis on a convex crest
  /// (crest_weight() > 0). normal_from()'s answer there hangs on how the ring's axes lie across
  /// the crease, so SeenNormalReading reads such a spot with one turn of the ring only.
  [[nodiscard]] static bool creased(const Eigen::Vector3d& u, const std::array<SeenHit, kNormalRays>& hits, double h,
                                    double phase = 0) noexcept;
  /// Which rays of a normal reading (opposite pairs at +-h across u, t from the point's depth, along
  /// the unit u) lie past a crease within h. Per axis, two measures a ray each, which a smooth
  /// surface (a tilt, a curvature) makes alike on both sides and a crease does not: the one-sided
  /// depth slope from the point (a crease ahead makes one steep: they differ by more than
  /// kCreaseSlope), and the ray's shade slope (shade_slope) less that depth slope (a ray that
  /// reads a face its chord does not run along, a groove's other face a few mm shallower: they
  /// differ by more than kCreaseShade). The ray whose measure is over twice the other's is past
  /// it; normal_from() leaves it out of both readings and takes that axis's slope on the other
  /// side.
  [[nodiscard]] static std::array<bool, kNormalRays> past_crease(const Eigen::Vector3d& u,
                                                                 const std::array<SeenHit, kNormalRays>& hits,
                                                                 double h) noexcept;
  /// The slope dt/dx along the unit `e` (across the unit u) of the surface a shade `n` faces out
  /// of, t the depth along u: n.e / (-n.u); +inf where n is edge-on or faces away.
  [[nodiscard]] static double shade_slope(const Eigen::Vector3d& n, const Eigen::Vector3d& u,
                                          const Eigen::Vector3d& e) noexcept;
  /// How much an axis's two sides must differ to be a crease, not curvature (past_crease; tan
  /// 27 deg: a surface whose curvature radius is over 2 h / 0.5 reads central).
  static constexpr double kCreaseSlope = 0.5;
  /// How much an axis's two shade-less-depth slopes must differ to be a crease (past_crease; tan
  /// 45 deg): a 60-degree groove's other face read near its line differs by 1.04-2.19 over the
  /// line's turns in `SeenSolid.TheNormalsRaysLook...`; the sparse discs of a curved surface (8 mm
  /// apart on a 50 mm cylinder, h 15 mm) by up to about 0.5.
  static constexpr double kCreaseShade = 1.0;
  /// How surely the point of a normal reading lies on a convex crease along one of its axes (its
  /// depths one each side, `up` and `down`, over h; a ray that sees nothing within h counts 1:
  /// the surface falls at least that far), 0 to 1: both sides fall away together by more than
  /// kCreaseSlope (1 from 1.5 kCreaseSlope on), and neither by over kCrestRatio times the other
  /// (1 up to kCrestRatio - 0.5; past_crease flags the steeper side from 2 on). An edge or a
  /// corner of the surface under the point pressed within about 11 deg of its bisector (fading
  /// out by 18 deg on a 90-degree edge), or the top of an object narrower than about
  /// 2 h / kCreaseSlope.
  [[nodiscard]] static double crest_weight(double up, double down) noexcept {
    const double low = std::min(up, down), high = std::max(up, down);
    if (!(low > 0)) return 0;
    const double together = std::clamp((up + down - kCreaseSlope) / (0.5 * kCreaseSlope), 0.0, 1.0);
    const double alike = std::clamp((kCrestRatio - high / low) / 0.5, 0.0, 1.0);
    return together * alike;
  }
  /// The ratio of a crest's two sides' falls at which crest_weight() reaches 0 (past_crease's
  /// own "over twice the other"); it is 1 up to kCrestRatio - 0.5.
  static constexpr double kCrestRatio = 2.0;
  /// The shade (SeenHit::shade) of `hit`, the last first_inside() answer on `scratch`: the sum of
  /// T_k alpha_k n_k over its layers peaking at t_from or later (T_k over every layer in front).
  /// Zero when it did not hit or scratch overflowed.
  [[nodiscard]] Eigen::Vector3d shade(const Eigen::Vector3d& u, const SeenHit& hit, const SeenScratch& scratch,
                                      double t_from = -std::numeric_limits<double>::infinity()) const noexcept;
  /// A wall's outward normal across `axis` (unit) where a line along the unit `u` met it (`hit`,
  /// the last first_inside() answer on `scratch`): shade()'s normal with its part along `axis`
  /// removed (along the axis the seen proxies' height field holds them); -u across the axis where
  /// the shade faces away or lies along the axis. The seen proxies' walls across their contact's
  /// axis (SeenProxy, SeenCompoundProxy).
  [[nodiscard]] Eigen::Vector3d wall_normal(const Eigen::Vector3d& u, const Eigen::Vector3d& axis, const SeenHit& hit,
                                            const SeenScratch& scratch) const noexcept;
  /// The least weight T_k alpha_k of a layer hit_contacts() reports (what 8-bit colour can show).
  static constexpr double kLeastContactWeight = 1.0 / 255;
  /// The layers of `hit` (visit_hit_layers()) of weight w >= kLeastContactWeight, in depth order, as contacts
  /// of the tool's part `part` written to the front of `out` (at most out.size() of them): the
  /// world's Gaussian (index, slot, opacity, centre) with Contact::k_min = w, its share of what
  /// the eye sees at the hit. Returns how many were written. No allocation. What the seen proxies
  /// report as the touched Gaussians (SeenProxy::contacts(), SeenCompoundProxy::contacts()).
  std::size_t hit_contacts(const SeenHit& hit, const SeenScratch& scratch, std::uint8_t part,
                           std::span<Contact> out) const noexcept {
    std::size_t n = 0;
    const std::span<const CollisionGaussian> gaussians = world_->gaussians();
    visit_hit_layers(hit, scratch, [&](std::uint32_t slot, double w) {
      if (w < kLeastContactWeight || n == out.size()) return;
      const CollisionGaussian& g = gaussians[slot];
      Contact& c = out[n++];
      c.index = g.source_index;
      c.slot = slot;
      c.opacity = g.opacity;
      c.part = part;
      c.k_min = w;
      c.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
    });
    return n;
  }
  /// The layers that make `hit`, the last first_inside() answer on `scratch`, as the renderer
  /// weighs them: `visit(slot, w)` for each, in depth order, with `slot` the Gaussian's position
  /// in CollisionWorld::gaussians() and w = T_k alpha_k (T_k: the transmittance in front of it;
  /// the weights sum to 1 - T, at least 1/2). What a material under the seen surface is read
  /// from (SeenProxy). Nothing when it did not hit or scratch overflowed. No allocation.
  template <class Visit>
  void visit_hit_layers(const SeenHit& hit, const SeenScratch& scratch, Visit&& visit) const {
    if (!hit.hit || scratch.overflow) return;
    double transmittance = 1;
    const std::size_t end = std::min<std::size_t>(hit.layers, scratch.gathered);
    for (std::size_t k = 0; k < end; ++k) {
      const SeenScratch::Layer& l = scratch.layers[k];
      const double alpha = -std::expm1(-l.tau);
      visit(slots_[l.entry], transmittance * alpha);
      transmittance *= 1 - alpha;
    }
  }

 private:
  struct Entry {
    double mean[3];
    double m[9];  // whitening diag(1/s) R^T, row-major: |W (x - mean)| is the Mahalanobis distance
    double opacity;
    double log_reach;  // ln(255 opacity): alpha >= 1/255 iff half the squared Mahalanobis distance is <= this
  };
  // A ball holding the entry's alpha >= 1/255 ellipsoid (its centre rounded to float, its
  // radius padded for that): 16 bytes read per entry before its whitening, which most entries
  // of a leaf the ray passes never need.
  struct Bound {
    float center[3];
    float radius;
  };
  static Bound bound_of(const Entry& e, double radius) noexcept;
  // Sorts layers by depth, ties by their Gaussians' slots in the world.
  void sort_by_depth(std::vector<SeenScratch::Layer>::iterator first,
                     std::vector<SeenScratch::Layer>::iterator last) const noexcept;
  // push()'s look behind c: how many stages it read (at most kStages, their layers' spans in
  // scratch in `behind`, the last one's from the eye on) and the eye's distance behind c
  // (max_back when nothing hides c). `shared_zero`: a look ahead took the layers peaking at c.
  // push()'s staged reads: at most kStages ranges growing x4, the first kFirstStage of the whole
  // (behind c: of max_back; ahead: of what lies past the guess).
  static constexpr int kStages = 4;
  static constexpr double kFirstStage = 1.0 / 64;
  struct Span {
    std::size_t first, last;
  };
  // push()'s first read: the layers ahead of c up to `split`, then past it in ranges growing x4
  // until one holds a layer (`near`, `stage`: how far, and the next range), sorted at the start of
  // scratch, how many returned; when `guessed`, the look back's first stage in the same traversal,
  // its `around` layers after them (none when not read).
  // Where stage `stage` of a look over [from, to] ends: from + (to - from) kFirstStage 4^stage, the
  // last stage (kStages - 1 on) at `to`. push()'s range `stage` past the guess is
  // stage_end(split, end, stage + 1); the look back's, without a guess, stage_end(0, max_back, st).
  static double stage_end(double from, double to, int stage) noexcept {
    return stage + 1 >= kStages ? to : std::min(to, from + (to - from) * std::ldexp(kFirstStage, 2 * stage));
  }
  // The look back's reach, max_back behind c, and the eye guess's end of its second stage
  // (`guess`; ignored unless past the first's end): stage st ends as stage_end(0, max_back, st), or
  // with a guess at guess 4^(st - 1) from the second on; the last (kStages - 1 on) at max_back.
  struct BackLook {
    double max_back, guess = 0;
    [[nodiscard]] double end(int st) const noexcept {
      if (st > 0 && st + 1 < kStages && guess > stage_end(0.0, max_back, 0))
        return std::min(max_back, guess * std::ldexp(1.0, 2 * (st - 1)));
      return stage_end(0.0, max_back, st);
    }
  };
  std::size_t read_ahead(const Eigen::Vector3d& c, const Eigen::Vector3d& u, const BackLook& back, double split,
                         double end, bool guessed, double& near, int& stage, std::optional<std::size_t>& around,
                         SeenScratch& scratch) const noexcept;
  // The look back from c; `around`: how many layers of its first stage push() read already, at
  // the end of scratch (none: not read).
  int look_back(const Eigen::Vector3d& c, const Eigen::Vector3d& u, const BackLook& back, bool shared_zero,
                std::optional<std::size_t> around, std::array<Span, kStages>& behind, double& eye,
                SeenScratch& scratch) const noexcept;
  // The layers peaking in [ta, tb] into scratch (after the ones there when `append`).
  static Eigen::Vector3d normal_ray_origin(const Eigen::Vector3d& point, const Eigen::Vector3d& u, int k,
                                           double h, double phase) noexcept;
  // Where ray k of a normal reading lies from its point: the unit 2 pi k / kNormalRays around u
  // from u.unitOrthogonal() towards u x that.
  static Eigen::Vector3d ring_direction(const Eigen::Vector3d& u, int k, double phase = 0) noexcept;
  // ring_direction() of rays 0 to kNormalRays / 2 - 1: one per opposite pair (read once a reading).
  using RingAxes = std::array<Eigen::Vector3d, kNormalRays / 2>;
  static RingAxes ring_axes(const Eigen::Vector3d& u, double phase = 0) noexcept;
  // past_crease() along those axes.
  static std::array<bool, kNormalRays> past_crease(const Eigen::Vector3d& u, const RingAxes& axes,
                                                   const std::array<SeenHit, kNormalRays>& hits, double h) noexcept;
  // normal_from() before on_crest(): the shade and the depth's slope, rays past a crease left out.
  static Eigen::Vector3d shaded_normal(const Eigen::Vector3d& u, const RingAxes& axes,
                                       const std::array<SeenHit, kNormalRays>& hits, double h) noexcept;
  // The normal `n` with each axis's slope turned toward 0 by its crest_weight() (the rigid
  // sphere's on a convex crease).
  static Eigen::Vector3d on_crest(const Eigen::Vector3d& u, const RingAxes& axes,
                                  const std::array<SeenHit, kNormalRays>& hits, double h, const Eigen::Vector3d& n) noexcept;
  void gather(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double ta, double tb, SeenScratch& scratch,
              bool append = false) const noexcept;
  // Appends the layers of [ta, tb], a range that shares its end `shared` with one gathered
  // before (those peaking exactly there are not taken twice).
  void gather_more(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double ta, double tb, double shared,
                   SeenScratch& scratch) const noexcept;
  // (In huge pages: a tick reads a few hundred entries scattered over the scene, and on a virtual
  // machine each 4 KiB page's TLB miss walks two page tables; gshaptics/huge_pages.h.)
  internal::HugePageVector<Entry> entries_;  // BVH slot order
  internal::HugePageVector<Bound> bounds_;   // per entry
  internal::HugePageVector<std::uint32_t> slots_;  // per entry: its Gaussian's slot in the world
  const CollisionWorld* world_;
  WideBvh bvh_;  // over the entries' alpha >= 1/255 boxes (the binary SAH tree, collapsed)
  double typical_scale_ = 0;
};

/// A seen proxy's move across its contact's axis, stopped by walls (SeenProxy::slide_across,
/// SeenCompoundProxy::slide_across): `step` (world, metres; across the axis) is searched along
/// its direction u by `nearest_wall(u, moved, len, wall)`, which returns how far along u, from the
/// proxy moved by `moved`, the first wall stops it (>= len: none within the step's length len)
/// and sets that wall's unit normal. The proxy goes there, and what is left of the step slides
/// along that wall, searched again: a second wall stops it (no third search). Steps no longer
/// than `min_len` are not searched; a step longer than `max_len` is cut to it, in its direction
/// (the rest is left to the next ticks: seen_footprint::kMaxSlide). Returns how far the proxy
/// moved and the last wall it met (zero: none). The god-object's constrained move (Zilles and
/// Salisbury 1995) on the seen solid.
struct WallSlide {
  Eigen::Vector3d moved = Eigen::Vector3d::Zero();
  Eigen::Vector3d wall = Eigen::Vector3d::Zero();
};
template <typename NearestWall>
[[nodiscard]] WallSlide slide_along_walls(Eigen::Vector3d step, double min_len, double max_len,
                                          NearestWall&& nearest_wall) noexcept {
  WallSlide s;
  const double whole = step.norm();
  if (whole > max_len) step *= max_len / whole;
  for (int pass = 0; pass < 2; ++pass) {
    const double len = step.norm();
    if (!(len > min_len)) break;
    const Eigen::Vector3d u = step / len;
    Eigen::Vector3d wall = Eigen::Vector3d::Zero();
    const double t = nearest_wall(u, s.moved, len, wall);
    if (t >= len) {
      s.moved += step;
      break;
    }
    s.moved += t * u;
    s.wall = wall;
    step = std::max(0.0, len - t) * u;
    step -= step.dot(wall) * wall;
  }
  return s;
}

/// SeenSolid::normal() spread over ticks for a proxy resting on the solid (SeenProxy,
/// SeenCompoundProxy): a contact's first reading takes its rays at once; a later one starts once
/// the point has moved `reuse` from the last reading and takes one ray a tick (the solid does not
/// move, so the rays of a reading fixed at its start give the same normal ticks later, and no
/// tick pays for them all). While the point stays within `reuse` of a spot, the spot is read
/// again with the ring turned (phase(): kPhases turns, 4 kNormalRays rays in all), one ray a tick
/// as a moving point's readings are, and its normal is the mean of its readings: on sparse discs
/// a ring of four rays reads two or three of them and carries their tilts and facets (the seen
/// cylinder's presses at 8 mm spacing erred 5.1 deg at p95 with one turn, 2.7 with four;
/// bench/RESULTS.md, ninety-first session). A reading at a new spot starts unturned; a spot whose
/// rays meet a crease, an edge or a gap (SeenSolid::creased) is read with one turn only (turned
/// off the crease the crest's reading weakened: the seen cube's edge presses at 8 mm spacing went
/// from 0.0 to 4.4 deg at p95). No allocation.
class SeenNormalReading {
 public:
  /// A new contact: the next update() reads at once.
  void forget() noexcept {
    fresh_ = false;
    pending_ = -1;
    settling_ = false;
  }
  /// One tick at `point` (on the seen surface for a push along the unit `u`), on a ring of radius
  /// `h` (searched within +-h), seen from `back` before the point (SeenSolid::normal). Returns
  /// the last whole reading (unit, outward).
  const Eigen::Vector3d& update(const SeenSolid& solid, const Eigen::Vector3d& point, const Eigen::Vector3d& u,
                                double h, double back, double reuse, SeenScratch& scratch) noexcept;
  [[nodiscard]] const Eigen::Vector3d& normal() const noexcept { return normal_; }
  /// True from the first turned reading of a spot until a reading at a new spot: its normal
  /// differs from the spot's first by the ring's turn alone, not by relief met along a slide,
  /// so a proxy resting there (not sliding this tick) takes it over time; a sliding one smooths
  /// over its path.
  [[nodiscard]] bool settling() const noexcept { return settling_; }
  /// How many turns of the ring a spot is read with.
  static constexpr int kPhases = 4;
  /// The ring's turn (rad about u) of a spot's i-th reading: 0, 1/2, 1/4, 3/4 of the ring's own
  /// period 2 pi / kNormalRays (each halves the largest gap the readings before left).
  [[nodiscard]] static double phase(int i) noexcept;

 private:
  // A reading `n` at a new spot `at` (its first, unturned): the spot's normal and sum.
  const Eigen::Vector3d& start_spot(const Eigen::Vector3d& at, const Eigen::Vector3d& n, bool creased) noexcept;
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero(), at_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();  // the spot's readings summed
  bool fresh_ = false, refining_ = false, settling_ = false;
  int pending_ = -1;  // the next ray of a reading under way (-1: none)
  int spot_readings_ = 0, next_phase_ = 0;
  Eigen::Vector3d pending_at_ = Eigen::Vector3d::Zero();
  double pending_back_ = 0, pending_h_ = 0, pending_phase_ = 0;
  std::array<SeenHit, SeenSolid::kNormalRays> hits_{};
};

}  // namespace gshaptics
