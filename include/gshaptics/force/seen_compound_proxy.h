#pragma once
/// @file
/// The god-object proxy of a compound tool (collision/compound_tool.h) on the seen solid
/// (force/seen_solid.h): ProxyParams::surface == ProxySurface::kSeen with a tool of several parts.
/// It is the one-part seen proxy (seen_proxy.h) given the tool's shape: every part is an
/// ellipsoid, and a part meets the seen solid at its leading point along the push, the point of
/// its surface farthest along it (ToolEllipsoid::surface_point).
///
/// Each tick:
/// 1. Free: the proxy is the device. Each part's centre moves along its chord from the last tick's
///    pose to this one's (translation and turn), its leading point searched along the whole chord
///    (SeenSolid::push: no motion tunnels), each seen from as far behind the part as it is still
///    seen from (at most seen_window tool radii). The part met first begins a contact: its chord
///    is the contact's axis a, and its eye plane the contact's.
/// 2. In contact: the proxy keeps the device's orientation and its place across the axis (or the
///    friction cone's: Salisbury et al. 1995), and rests along a on the seen surface as seen
///    from the eye plane. Each part's leading point is searched along a from the eye plane to its
///    depth; the proxy backs off along -a by the deepest part's depth past its surface (a rigid
///    body on a height field: every part on or above the seen surface under it). When no part
///    reaches the surface, the device has come out and the contact ends.
/// 3. The parts' footprints: beside the ray through its leading point, each part reads rays
///    parallel to the push through its shadow: a ring of twelve (at 0.5, 0.7 and 0.85 of the
///    shadow ellipse's radius, 30 degrees apart), its centre, and roaming rays that sample the
///    shadow's middle (to 0.6 of its radius) in turn (a low-discrepancy sequence; six kept, those
///    that hold), one ring ray
///    and one inner ray a part a tick, free and in contact, each a line with the seen surface's
///    place on it: a thin feature anywhere under a long part is met, not only on the ring. In
///    contact every line, and in free motion the inner ones, is seen from its own eye, as far
///    behind as it is still seen from, as the leading point's ray is (a surface of faint layers
///    is met where a viewer sees it); a free ring line from just behind the part. Where
///    the part's front over such a line reaches that surface
///    it holds the part as its leading point's ray does, so a part whose leading point hangs past
///    an edge rests on the edge (a stylus lying across a cube's edge), and a free part meets an
///    edge on its side. A line whose surface lies deeper than half the part's middle semi-axis
///    under the part's front is one the part went past between its readings (a wall beside it):
///    it does not hold.
///    Where a ring line holds a part, one more line a tick bisects between it and the
///    leading point's line, so that the part rests on the edge itself and its normal is taken
///    there (six steps: to 1/64 of the distance). A footprint line that holds the part but stands
///    hardly higher than the edge those points fit (a disc proud of its neighbours) is a bump on
///    the edge: the part's normal is still taken at its tangent point on the edge.
/// 4. Wrench: the virtual coupling (Colgate, Stanley and Brown 1995) F = max(0, k e . n - b v . n) n,
///    e = x_proxy - x_device, plus friction; n is the touching parts' normals, each weighted
///    1 - (gap / band)^2 (gap: how far the part's front stands above the surface under it, band:
///    half the tool's smallest semi-axis): for a part held by its leading point's ray, the seen
///    surface's normal (SeenSolid::normal: the renderer's normal map and the seen depth's slope,
///    read on a ring of 1.5 times the part's middle semi-axis, one ray a tick after a contact's
///    first reading), for one held by its footprint (an edge under its side), the part's own
///    surface normal there (a rigid body on a sharp edge); smoothed over 5 ms. It is applied at
///    the touching parts' contact points, so a stylus lying on a wall gets the middle of its line
///    of contact, as the compound proxy on the ellipsoids does (compound_proxy.h): the torque
///    about the TCP is the force's moment, (c - x_tcp) x F.
///
/// 5. Walls across the axis (SeenProxy's, part by part: slide_across). The proxy's move across the
///    axis toward the goal is searched along a line through each part's leading side that way
///    (its surface point whose outward normal is the move's direction), seen from just inside it;
///    the nearest wall stops the move just short of it, the rest slides along that wall, and the
///    wall adds a spring across the axis along its rendered normal (at the TCP: no torque; no
///    friction). A stylus slid along a floor into a wall passed through it. A rise of the proxy
///    toward the eye plane of more than the smallest semi-axis in one tick is still the top of a
///    wall a part's ray met, not a surface to slide onto: the proxy stays where it stood (a stylus
///    slid into a wall was thrown onto its top, 78-81 N).
///
/// 6. The climb, paid for (ClimbLedger, SeenProxy's): under load the proxy rises along -a only as
///    far as its own falls, the rendered normal's lean against its slide and the hand's work pay
///    for; the hand pays through its slide against the ledger's reaction and through its turn
///    against the torque on the device (a turn that swings a part onto the surface lifts the
///    proxy through the tool's lever). A rise still owed is charged to a sliding hand; a straight
///    press keeps its level, also after a contact begun past its surface (sink()).
///
/// Not done (the compound proxy on the ellipsoids does these): the proxy does not turn against
/// the surface (a turn that would swing a part into the solid raises the proxy along a instead,
/// and no rotational coupling is rendered). A wall is met on one line per part: one whose edge
/// meets a part beside that line (a wall's top under a tilted part's underside) is a surface the
/// height field climbs.
///
/// Materials (set_materials, force/material.h), as SeenProxy reads them: each part's leading
/// point's ray weighs the materials of the layers that make its hit (SeenSolid::visit_hit_layers),
/// the touching parts' shares blend by their contact weights and are followed along the proxy's
/// path (MaterialFollower); the texture tip hangs from the touching parts down to the seen surface
/// under their leading points (their weighted mean): the relief the proxy does not ride itself.
///
/// Frame and units: world, metres as the world's; the TCP and orientation as CompoundProxy's.
/// render() does not allocate, lock, log or throw.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <span>
#include <cstdint>
#include <limits>
#include <memory>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/collision/ellipsoid_line.h"
#include "gshaptics/force/climb_ledger.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/force/friction_cone.h"
#include "gshaptics/force/material.h"
#include "gshaptics/force/proxy_params.h"
#include "gshaptics/force/seen_solid.h"
#include "gshaptics/force/virtual_coupling.h"

namespace gshaptics {

class SeenCompoundProxy {
 public:
  /// On `solid` (kept by reference: it outlives the proxy). `params` as SeenProxy reads them
  /// ("tool radii": the tool's largest semi-axis); `f_max` clamps the coupling force, N.
  /// Throws InputError for an invalid tool.
  SeenCompoundProxy(const SeenSolid& solid, const CompoundTool& tool, const ProxyParams& params,
                    double f_max = std::numeric_limits<double>::infinity());

  /// One tick: the device's TCP position (m) and orientation (tool frame -> world), its velocity
  /// (m/s) and angular velocity (rad/s), dt (s, > 0). Force and torque (about the TCP) on the
  /// device, world frame; RenderOutput::proxy is the proxy's TCP.
  RenderOutput render(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                      const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity, double dt) noexcept;
  void reset() noexcept;

  /// Materials by region (force/material.h) read from the seen solid under the touching parts, as
  /// above; nullptr: none (the proxy's own parameters). Call between ticks.
  void set_materials(std::shared_ptr<const MaterialField> field);
  /// The material blend under the contact (the proxy's own out of contact); nullptr without materials.
  [[nodiscard]] const MaterialBlend* material() const noexcept { return follower_ ? &follower_->blend() : nullptr; }

  [[nodiscard]] const CompoundTool& tool() const noexcept { return tool_; }
  [[nodiscard]] const Eigen::Vector3d& position() const noexcept { return x_; }
  [[nodiscard]] const Eigen::Vector3d& contact_normal() const noexcept { return normal_; }
  [[nodiscard]] bool in_contact() const noexcept { return in_contact_; }
  /// The parts touching at the last tick (weight > 0).
  [[nodiscard]] int touching() const noexcept { return touching_; }
  /// The Gaussians that make the seen surface under the touching parts after the last tick:
  /// each part's leading-point ray's layers up to its hit (SeenSolid::hit_contacts(), weight at
  /// least SeenSolid::kLeastContactWeight, at most kPartContacts a part), tagged with the part;
  /// Contact::k_min holds the layer's weight, not a K_min. A part held by its footprint alone
  /// reports none. Empty out of contact.
  [[nodiscard]] std::span<const Contact> contacts() const noexcept { return {contacts_.data(), contact_count_}; }
  static constexpr std::size_t kPartContacts = 32;
  /// What this proxy's queries on the seen solid have read since it was made (SeenScratch::Work,
  /// cumulative): a benchmark takes the difference across a tick.
  [[nodiscard]] const SeenScratch::Work& seen_work() const noexcept { return scratch_.work; }

 private:
  // The touching parts' layers (part_layers_) into contacts_, after contact() set weight_.
  void gather_contacts() noexcept;
  static constexpr int kRingRays = seen_footprint::kRays;
  // Inner lines, read one a tick beside the ring's (their own turn, so the ring's refresh, which
  // the edge search leans on, stays kRingRays ticks), never an edge search's start: the shadow's
  // centre one turn in kInnerTurns, and roaming lines the others. A roaming line is placed by a
  // low-discrepancy sequence over the whole shadow (the R2 sequence, Roberts 2018, mapped onto
  // the ellipse by area, out to kRoamFraction of its radius), so a thin feature anywhere under the
  // part is met within a few dozen readings, and is written into the roaming slot that holds
  // least (a feature found stays in memory while the part is over it). Out to the rim: a droplet
  // under a disc's rim, beyond the ring's outermost lines (0.85), let the disc down 9 R past what
  // the eye sees on fruitdrops while the roaming lines stopped at 0.6 (bench/RESULTS.md).
  static constexpr int kInnerTurns = 4;
  static constexpr int kRoamLines = 6;
  static constexpr double kRoamFraction = 0.95;
  static constexpr int kRoamRefresh = 16;  // ticks: the part's travel a roaming line allows for, as refresh()
  // Middle semi-axes a roaming line reads ahead of the part's front in free motion (the ring's:
  // kRingLook). At kRingLook a stylus tip beside a raised edge under a tenth of its shadow went
  // 7.9 R into it on the Truck before a roaming line met the edge (bench/RESULTS.md, the
  // hundred-and-second session).
  static constexpr double kRoamLook = 4.0;
  static constexpr int kCentreLine = kRingRays;
  static constexpr int kRoamLine = kCentreLine + 1;  // the first roaming slot
  static constexpr int kReadLines = kRoamLine + kRoamLines;
  static constexpr int kEdgeSlot = kReadLines;  // the edge searches' two lines (search_edge)
  static constexpr int kLines = kReadLines + 2;
  static constexpr double kRingLook = 1.0;      // middle semi-axes: rays look this far behind the front
  static constexpr double kRingSink = 0.5;      // middle semi-axes: a surface deeper under the front does not hold
  static constexpr double kRingAxisCos = 0.9986;  // cos 3 deg: a chord turning more forgets the footprint
  // One part's footprint: lines parallel to `axis`, each through `foot`, with the seen surface's
  // coordinate along the axis on it (`at`; +inf: none found).
  // Lines [0, kRingRays) are the ring, then the centre, the roaming lines, and the edge searches' two.
  struct Ring {
    Eigen::Vector3d axis = Eigen::Vector3d::Zero();
    std::array<Eigen::Vector3d, kLines> foot{};
    std::array<double, kLines> at{};
    std::array<SeenLineMemo, kReadLines> memo{};  // the read lines' last searches (line_surface)
    std::array<double, kReadLines> eye{};  // and their eyes' distances (push()'s eye guess; 0: none)
    std::array<std::uint32_t, kRoamLines> stamp{};  // the roaming slots' readings, by `roam`
    int next = 0, next_inner = 0;  // the ring's next line, and the inner turn
    std::uint32_t roam = 0;        // the roaming sequence's next index
  };
  // A footprint line to read: its slot, and its offset across the axis from the part's centre.
  struct LineRead {
    int slot = 0;
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  };
  // The two lines part j (posed as `part`, its footprint along u) reads this tick: the ring's
  // next, and the centre or a roaming line (into the roaming slot that holds least on `part`).
  // Advances the turns.
  std::array<LineRead, 2> next_lines(int j, const ToolEllipsoid& part, const Eigen::Vector3d& u) noexcept;
  // How many ticks apart footprint line k is read (a roaming line: the travel it allows for).
  static constexpr int refresh(int k) noexcept {
    return k < kRingRays ? kRingRays : k == kCentreLine ? kInnerTurns : kRoamRefresh;
  }
  // A search for the edge a part rests on by its footprint: bisection between a holding
  // footprint line (its surface under the part) and the part's leading point's line (none), both
  // points across the axis, kEdgeSteps lines at once; the last line that met the surface is the
  // search's edge line (the source line itself when none between did: a part resting with that
  // line on the edge, which before was no edge, and the part held on that line's own normal, up
  // to 30 deg off, at 2 and 4 mm spacing). Two searches a part, from two holding lines 60
  // degrees or more apart around the shadow, give the edge's direction, and the part rests on
  // the edge at its own tangent point there (edge_gap). The second search, left with no line to
  // start from, keeps its last point while that lies under the part and the part has moved less
  // than kEdgeSpan middle semi-axes across the axis since: the edge does not move under a resting
  // part (dropped, the part fell back on a footprint line's own normal, 30 deg off, for the first
  // 50 ms of a press at 2 mm spacing; kept without the bound, a sliding part kept an edge made of
  // stale points, and the stylus's p50 render time on halo's probe run rose 15 %).
  static constexpr int kEdgeSteps = 6;
  static constexpr int kEdgeLine = kLines;  // Hold::line of a part resting on the edge's tangent point
  static constexpr double kEdgeSnap = 0.1;  // smallest semi-axes: a line this near the edge's gap lies on the edge
  // Smallest semi-axes: a line this far above the edge's fit is the rim's top (a crisp edge's
  // searches end down its shoulder, 0.125 under the top at 8 mm spacing, seeds 7 and 11: held on
  // its own line 2.5 mm beside the tangent point, the stylus leaned 30 deg along the edge).
  static constexpr double kRimTop = 0.2;
  static constexpr double kSnapSpan = 0.5;  // middle semi-axes: the edge points' least span to snap onto
  static constexpr double kEdgeSpan = 0.2;  // middle semi-axes: two edge lines closer give no direction
  struct EdgeSearch {
    int source = -1;  // the footprint line it started from (-1: none)
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // the part's centre when it ran
  };
  // Part j's footprint judged at the device's depth: the line nearest the surface (`line`, -1:
  // none; kEdgeLine: the edge's tangent point) and its gap, every line's gap (+inf: does not
  // hold), and the nearest footprint line proper (`source`, its gap `nearest`).
  struct LineChoice {
    int line = -1;
    double gap = std::numeric_limits<double>::infinity();
    double nearest = std::numeric_limits<double>::infinity();
    int source = -1;
    std::array<double, kLines> gaps{};
  };
  [[nodiscard]] static bool apart(int r1, int r2) noexcept {  // 60 degrees or more around the shadow
    if (r1 < 0 || r2 < 0) return true;
    const int d = (r1 > r2 ? r1 - r2 : r2 - r1) % kRingRays;
    return (d < kRingRays - d ? d : kRingRays - d) >= 2;
  }
  // What holds a part after hold(): how far its front stands above the surface under it, where
  // (its contact point), and whether a footprint line (not its leading point's ray) holds it.
  struct Hold {
    double gap = std::numeric_limits<double>::infinity();
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
    bool by_ring = false;
    int line = -1;  // the footprint line that holds it (by_ring; kEdgeLine: the edge's tangent point)
  };

  // The parts posed at (x, q) into parts_.
  void pose(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept;
  // Free: the parts' chords from the last pose to (x, q); true when one meets the seen solid
  // (the contact's axis and eye plane are set).
  bool begin_contact(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept;
  // The seen surface's place along u (unit) on the line through `front`, read from `back` behind
  // it to `ahead` past it, seen from the line's own eye: as far behind as the line is still seen
  // from (SeenSolid::push; at most seen_window of part j's middle semi-axes), so the faint layers
  // a viewer composites in front of it count, while a surface behind the eye (an overhang above
  // the part) does not. +inf: none. Line `slot` of part j's ring keeps what the search reads
  // first: its last answer (at; +inf: none) and its last eye (eye; SeenSolid::push's guesses, only
  // the cost depends on them), and its last search (memo), the answer while the line and its
  // window decide it (a resting part's lines).
  double line_surface(int j, int slot, const Eigen::Vector3d& front, const Eigen::Vector3d& u, double back,
                      double ahead) noexcept;
  // How far past its surface a part's footprint may find it and still begin a contact, m: kRingSink
  // middle semi-axes for a part that moved `len` this tick, kLate for one at rest.
  double begin_sink(int j, double len) const noexcept;
  // Free: part j's next two footprint lines (next_lines) along its chord u (its centre `from`,
  // moving `len`), and how far the part moves before its footprint meets the surface (+inf: not
  // within the chord): by the ring's lines, and by the inner lines.
  std::array<double, 2> free_ring(int j, const ToolEllipsoid& from, const Eigen::Vector3d& u, double len,
                                  bool leaving) noexcept;
  // In contact: the goal's place across the axis, the proxy's move toward it searched part by
  // part (`resting`: the parts posed at the proxy): a line through each part's surface point that
  // way, seen from its centre and searched from kWallDepth of its middle semi-axis inside it; the
  // nearest wall stops the move kWallGap short of it, and what is left slides along that wall
  // (one more search). Sets wall_ (the wall's rendered normal across the axis; zero: none).
  Eigen::Vector3d slide_across(const Eigen::Vector3d& goal,
                               const std::array<ToolEllipsoid, kMaxToolParts>& resting) noexcept;
  static constexpr double kWallGap = 1e-3;    // middle semi-axes (SeenProxy's, in its R)
  static constexpr double kWallDepth = 0.1;   // middle semi-axes
  static constexpr double kWallLook = 0.25;   // middle semi-axes: a wall's line reads this far ahead first
  static constexpr double kSlideMin = 1e-4;   // smallest semi-axes: a shorter move is not searched
  // In contact: the proxy along the axis over the goal's place across it, the device's depth;
  // false when no part reaches the surface.
  bool hold(const Eigen::Vector3d& device, const Eigen::Vector3d& goal, const Eigen::Quaterniond& q) noexcept;
  // What holds each part of the proxy hold() just placed (`back`: how far it backed off along -a
  // from the device's depth; per part, its leading point's surface `at` and depth `depth` there
  // and its footprint's choice `lines`): held_ and under_.
  // How far the proxy backs off along -a: the most any part is past its surfaces (`past`, from
  // its leading point's ray and its footprint), less what it was past them when the contact began
  // beyond its own motion (sunk_, set at the contact's first tick; where that is less than
  // kRingSink middle semi-axes, brought back to zero at kClimbTick smallest semi-axes a tick).
  [[nodiscard]] double sink(const std::array<double, kMaxToolParts>& past) noexcept;
  // How far the proxy backs off along -a from the device's place `y` in contact: `back`, unless
  // that rises it past where it stood by more than the rise allowance of its `slide` across the
  // axis (seen_footprint::rise_allowance; `ahead`: how far y is past the proxy along a), and
  // under load by more than ledger_ says is paid for (ClimbLedger::rise_room of `lateral`, the
  // proxy's move across the axis, m).
  [[nodiscard]] double climb(double back, double ahead, double slide, const Eigen::Vector3d& lateral) const noexcept;
  void record_holds(const std::array<LineChoice, kMaxToolParts>& lines, const std::array<double, kMaxToolParts>& at,
                    const std::array<double, kMaxToolParts>& depth, double back) noexcept;
  // In contact: part j's next two footprint lines (next_lines) through its shadow (parts_ posed
  // at the resting proxy), read from above its front to `reach` past it.
  void read_ring(int j, double reach) noexcept;
  // Part j's edge search `which` (0, 1) afresh from footprint line `source` (-1: none; dropped),
  // on `part` posed at the resting proxy.
  void search_edge(int j, int which, int source, const ToolEllipsoid& part) noexcept;
  // Restarts those of part j's two searches whose lines no longer hold (LineChoice `c`), on the
  // part posed at the resting proxy (`resting`).
  void update_edges(int j, const LineChoice& c, const ToolEllipsoid& resting) noexcept;
  // Part j's footprint, with parts_ posed at the device's depth (`resting`: the part at the proxy).
  [[nodiscard]] LineChoice nearest_line(int j, const ToolEllipsoid& resting) const noexcept;
  // Part j's leading point's ray from the eye plane (parts_ posed at the device's depth): its
  // hit's depth from the eye plane (+inf: none within the band past it), `depth` the point's.
  // The last search is kept while the ray's line stays where it was (kSameLine; SeenLineMemo).
  double leading_ray(int j, double band, double& depth) noexcept;
  // Part j's edge across `axis` (unit): how far apart its two points lie across the axis (m; 0
  // when it has no two readings or was read along another axis), `along` the unit direction
  // from the first to the second.
  [[nodiscard]] double edge_span(int j, const Eigen::Vector3d& axis, Eigen::Vector3d& along) const noexcept;
  // How far `part` (part j, posed) stands above the edge its two edge lines found, at its own
  // tangent point on it (set: `contact`): the point of the part whose normal is across the edge,
  // in the plane through the edge along `axis`; +inf when there is no edge or it passes beside.
  [[nodiscard]] double edge_gap(const ToolEllipsoid& part, int j, const Eigen::Vector3d& axis,
                                Eigen::Vector3d& contact) const noexcept;
  // Whether part j (posed at the proxy), held by a footprint line with `gap` (m), rests on its
  // edge: the edge's points span kSnapSpan middle semi-axes or more, and the line stands at most
  // kEdgeSnap smallest semi-axes below the edge's fit at the part's tangent point or kRimTop above
  // it (the rim's top over a fit through points down its shoulder); then `point` is that tangent
  // point.
  [[nodiscard]] bool rests_on_edge(int j, double gap, Eigen::Vector3d& point) const noexcept;
  // How far a part (part j, posed; `exit`: its exits along the ring's axis) stands above footprint
  // line k's surface along `axis`, at its front over the line (set: `front`); < 0: past it; +inf
  // when the line is not under the part, was read along another axis, or has no surface.
  [[nodiscard]] double ring_gap(const ExitAlong& exit, int j, int k, const Eigen::Vector3d& axis,
                                Eigen::Vector3d& front) const noexcept;
  void forget_ring(int j, const Eigen::Vector3d& axis) noexcept;
  // The touching parts' weighted normal (`target`, unit) and contact point (world), the seen
  // surface's normal read under those its leading point's ray holds; `normal`: the force's last
  // (which way a part faces the contact). False when no part touches.
  bool contact(Eigen::Vector3d& target, Eigen::Vector3d& lever_point, const Eigen::Vector3d& normal) noexcept;
  void release() noexcept;
  // With materials: part j's shares from its leading ray's fresh `hit` (the layers on scratch_).
  void read_part_shares(int j, const SeenHit& hit) noexcept;
  // With materials, in contact: the touching parts' shares blended by their weights (held_) into
  // target_shares_ (false: none of them has a share), the blend followed at the proxy.
  void apply_material(const Eigen::Vector3d& contact_point) noexcept;

  static constexpr double kNormalTau = 0.005;   // s (SeenProxy's)
  static constexpr double kNormalPath = 0.5;    // smallest semi-axes
  static constexpr double kNormalReuse = 0.05;  // smallest semi-axes
  static constexpr double kNormalEye = 8;       // middle semi-axes
  static constexpr double kGuessMargin = 0.25;  // smallest semi-axes
  static constexpr double kEyeMargin = 0.25;    // smallest semi-axes
  static constexpr double kContactBand = 0.5;   // the smallest semi-axis (CompoundProxy's)
  // How much nearer than the ring's lines and the edge an inner line's surface must be to hold
  // the part (smallest semi-axes): below it, the rim of an edge read a little high (the stylus
  // across a cube edge: 0.2 turns the force 21-34 deg at two of 12 seeds); above it, a raised
  // patch under the middle (halo, 0.38) is passed (bench/RESULTS.md, hundred-and-fourth session).
  static constexpr double kInnerBand = 0.3;
  // Of the inner lines, the nearest holds; the one holding the part keeps it while it is within
  // kInnerKeep smallest semi-axes of the nearest (lines re-read on one raised patch trade places
  // by less: taking the nearest each tick, the stylus across a crisp edge turned 5.8 deg at seed
  // 6; taking the first within the band, 14 deg at seed 1: bench/RESULTS.md, hundred-and-eighth
  // session).
  static constexpr double kInnerKeep = 0.1;

  const SeenSolid* solid_;
  CompoundTool tool_;
  ProxyParams params_;
  double radius_ = 0, min_axis_ = 0;  // the tool's largest and smallest semi-axes
  double reach_ = 0;  // the farthest any part's surface reaches from the TCP
  // The outward normal, across the axis, of a wall whose top the tool was refused this tick
  // (kMaxClimb; zero: none).
  Eigen::Vector3d wall_ = Eigen::Vector3d::Zero();
  static constexpr double kMaxClimb = seen_footprint::kMaxClimb;  // smallest semi-axes
  SeenScratch scratch_;
  VirtualCoupling coupling_;
  FrictionCone friction_;
  FrictionStep friction_step_;
  std::array<ToolEllipsoid, kMaxToolParts> parts_{};
  std::array<double, kMaxToolParts> middle_{};    // each part's middle semi-axis
  std::array<Hold, kMaxToolParts> held_{};
  std::array<Ring, kMaxToolParts> rings_{};
  std::array<std::array<EdgeSearch, 2>, kMaxToolParts> edges_{};
  std::array<SeenLineMemo, kMaxToolParts> leading_{};  // each part's leading point's last search
  static constexpr double kSameLine = 1e-9;  // smallest semi-axes: a line that has not moved
  Eigen::Vector3d x_ = Eigen::Vector3d::Zero(), last_device_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero();       // the force's, smoothed
  bool fresh_normal_ = false;  // a contact began: its first reading sets normal_
  Eigen::Vector3d seen_normal_ = Eigen::Vector3d::Zero();  // the seen surface's last reading
  Eigen::Vector3d axis_ = Eigen::Vector3d::Zero(), eye_ = Eigen::Vector3d::Zero();
  SeenNormalReading normal_reading_;
  int touching_ = 0;
  // Each part's leading ray's layers at its last search (kept with its line's memo) and the
  // touching parts' together (contacts()).
  std::array<std::array<Contact, kPartContacts>, kMaxToolParts> part_layers_{};
  std::array<std::size_t, kMaxToolParts> part_layer_count_{};
  std::array<Contact, kPartContacts * kMaxToolParts> contacts_{};
  std::size_t contact_count_ = 0;
  std::array<double, kMaxToolParts> weight_{};  // each part's contact weight at the last tick (0: not touching)
  // How far the seen surface under each part's leading point lies below the part's front after
  // hold() (0: its ray holds it; deeper where its footprint holds it; < 0: above it, a rise not yet
  // paid for, ClimbLedger; +inf: none), and the touching
  // parts' mean of it (to one smallest semi-axis): the relief the proxy does not render, which
  // the texture tip reads.
  std::array<double, kMaxToolParts> under_{};
  double tip_under_ = 0;
  ClimbLedger ledger_;  // the proxy's own steps against the coupling, and the hand's payments (SeenProxy's)
  double deficit_ = 0;  // m: how far the parts' surfaces would back the proxy off beyond where it climbed
  std::array<double, kMaxToolParts> free_eye_{};  // m: each part's last free push's eye (a guess; 0: none)
  // Each part's motion along its chord in the tick its contact began (begin_contact), and how
  // much deeper than its surfaces it holds for the contact (sink()).
  std::array<double, kMaxToolParts> entry_motion_{}, sunk_{};
  std::array<bool, kMaxToolParts> fading_{};  // sunk_ brought back to the surface as a ramp (sink())
  static constexpr double kSunkSlack = seen_footprint::kSunkSlack;  // smallest semi-axes
  double own_share_ = 0;  // the touching parts' weight held by footprints (own normals), of all
  bool started_ = false, in_contact_ = false;
  std::unique_ptr<MaterialFollower> follower_;  // set_materials (nullptr: none)
  std::array<MaterialField::Weights, kMaxToolParts> part_shares_{};  // each part's last hit's material shares
  std::array<bool, kMaxToolParts> part_held_{};  // whether part_shares_[j] holds a hit's shares
  MaterialField::Weights target_shares_{};
};

}  // namespace gshaptics
