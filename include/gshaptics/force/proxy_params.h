#pragma once
/// @file
/// The proxy's parameters: one set that every part of the god-object reads, the one-ellipsoid
/// proxy (ProxyRenderer, ProxySolver, ProxyNormal, VirtualCoupling) and the compound proxy of a
/// tool with a shape (CompoundProxy) alike. Nothing is copied field by field between them.
///
/// A few fields serve one kind of tool only (tool_specific_proxy_fields()): the device-side
/// shading, the corner normal, the overhang falloff and the read-ahead budget serve the
/// one-ellipsoid proxy; the rotational coupling, the sub-rotations, the near lists and the face
/// average serve the compound proxy. check_proxy_params_apply() refuses such a field set away
/// from its default for a tool it does not serve, so no option is silently ignored.

#include <cstddef>
#include <span>
#include <string_view>

#include "gshaptics/force/floater_rule.h"
#include "gshaptics/force/shaded_normal.h"

namespace gshaptics {

/// The solid the proxy is held against.
enum class ProxySurface {
  /// The Gaussians' exact k-sigma ellipsoids (../shared/DESIGN.md Sec. 2b), with the opacity filter and
  /// the floater rule: exact against the ellipsoids, not the surface a renderer shows.
  kEllipsoids,
  /// The seen solid (force/seen_solid.h): where the Gaussians composite to a transmittance of
  /// 1/2 along the push, as a viewer looking along it sees them: SeenProxy for one-part tools,
  /// SeenCompoundProxy for tools with a shape.
  kSeen,
};

/// The --surface value naming `s`: "ellipsoids" or "seen".
[[nodiscard]] std::string_view proxy_surface_name(ProxySurface s) noexcept;
/// The surface a --surface value names ("ellipsoids" or "seen"); InputError naming `who` otherwise.
[[nodiscard]] ProxySurface proxy_surface_from(std::string_view name, std::string_view who);

/// Parameters of the proxy (god-object) renderer, every tool. SI units; "tool radii" are the
/// one-ellipsoid tool's bounding radius, or a compound tool's largest semi-axis (its smallest
/// semi-axis where a field says so).
struct ProxyParams {
  double stiffness = 1000.0;  ///< k_c, N/m: coupling spring (a desktop device renders 1-3 N/mm)
  /// b_c, N s/m, along the contact normal while in contact. A sampled spring of stiffness k with
  /// one tick T of delay is passive for b > k T / 2 (0.5 N s/m at 1000 N/m and 1 kHz).
  double damping = 1.0;
  double mu_s = 0.0;          ///< static friction coefficient (0: off)
  double mu_k = 0.0;          ///< kinetic friction coefficient (<= mu_s)
  bool opacity_stiffness = false;  ///< k_c scaled by the smoothed opacity of the blocking Gaussians
  double tau_opacity = 0.02;  ///< s, time constant of that smoothing
  int substeps = 4;           ///< sweeps per tick (first contact, then slides on up to 3 planes), [1, 16]
  /// When the proxy is wedged between Gaussian-scale bumps it steps up this many tool radii
  /// (at most twice a tick) and slides on: it glides over the shell's noise (0: never).
  double lift = 0.05;
  /// Kernel width of the shaded normal, in tool radii (or in the blocking Gaussians' middle
  /// semi-axis when that is larger); a compound tool's part reads it in its smallest semi-axis
  /// (or the Gaussians' spacing where they are sparser).
  double shading_kernel = 0.5;
  /// How far the shaded normal's support reaches past the Gaussians that touch the tool, in q
  /// (kShadingTail, shaded_normal()): a term left out weighs under exp(-tail / 2) of theirs.
  double shading_tail = kShadingTail;
  /// How many Gaussians a shaded normal reading visits at most (kMaxKernelVisits): a denser
  /// support is read from an even sample of its slots. 0: every Gaussian of the support.
  std::size_t shading_visits = kMaxKernelVisits;
  /// The shaded normal is recomputed once the proxy moved this many tool radii (a compound
  /// tool's part: this many of the field's scale there, the larger of its smallest semi-axis and
  /// the Gaussians' spacing under the tool).
  double shading_reuse = 0.05;
  /// ... or sooner where the field turns fast: a reading is kept only while the normal would
  /// turn by at most this many degrees at the rate it turned between the last two readings
  /// (down to 1/25 of shading_reuse; ShadedNormalCache::set_turn_tolerance). Round a convex
  /// edge the field turns tens of degrees per mm, and a normal held over 5 % of the tool made
  /// the force depend on the path (presses that gave back more energy than they took). 0: off.
  double shading_turn = 1.0;
  /// One-ellipsoid tool. Steps (Gaussians visited or fitted) a tick may spend preparing the next
  /// shaded normal while the proxy slides steadily, so the tick it is due does not pay for a whole
  /// reading (about 1700 steps, 70 us, for a 10 mm tool on 2 mm spacing);
  /// ShadedNormalCache::read_ahead (on a fast slide a tick may spend more: the reading's even
  /// share of the ticks left). A reading within this budget, or on a very slow or wandering
  /// motion, is made whole when due. 0: every reading whole, when due.
  std::size_t shading_budget = 384;
  /// One-ellipsoid tool. Where the field turns slowly (shading_turn does not bind), the shaded
  /// normal is also read where the device would rest, the device lifted along the normal to the
  /// proxy's level, at most this many tool radii from the proxy, and blended with the proxy's
  /// reading while the two agree (ProxyNormal::kDeviceShadingFrom / To degrees). The frictionless
  /// proxy slides off the Gaussians' rims into the hollows between them, and on a curved face the
  /// field read there belongs to another place than the one the hand presses: on the 8 mm-spacing
  /// fidelity cylinder with a 10 mm tool, direction p95 3.8 -> 2.3-2.6 degrees over seeds 1-18
  /// (bench/RESULTS.md, thirty-second session). 0: off (the proxy's reading alone).
  double device_shading = 0.2;
  /// One-ellipsoid tool. Where the patch under the tool is a clean convex corner (three faces:
  /// EdgeNormal's corner test), the force turns to the patch's support normal (edge_normal.h,
  /// blended over 3-6 degrees of disagreement): the direction that best separates the tool from
  /// the corner's Gaussians, which stays in the corner's normal cone where the shaded field of
  /// the face the proxy rests on tilts out of it (fidelity seeds 1-18: every cube corner cell
  /// within 4.0 degrees p95, were up to 8.9, but seed 12's fin; bench/RESULTS.md, thirty-fourth
  /// session). false: the shaded field everywhere.
  bool corner_normal = true;
  /// One-ellipsoid tool. Pressed into a clean convex edge or corner of the Gaussians (EdgeNormal's
  /// tests), with the spring inside the feature's normal cone and the device moving along the
  /// spring, the god-object holds where it rests and the force acts along the spring: a
  /// god-object on a polyhedron stays on the edge or vertex while two or three of its
  /// constraints are active (Zilles & Salisbury 1995). Without it the frictionless proxy rolls
  /// off the bumpy crest the discs' rims make, at a depth that depends on the training run: the
  /// fidelity cube's edge and corner stiffness varied 1.05-1.31x across densities, and now reads
  /// the faces' (bench/RESULTS.md, sixty-sixth session). A slide over the edge (the device moving
  /// across the spring) and a compound tool are unchanged. false: the proxy slides off.
  bool crest_hold = true;
  /// One-ellipsoid tool. Where a disc of the other face overhangs a convex edge and blocks the
  /// tool beside it (a fin), the shaded normal leaves out that face's discs behind the plane of
  /// the face under the tool (front_face, FreeBall::face; fidelity seeds 1-30, 8 mm cube, 5 mm
  /// tool: edges p95 23.5 -> 3.8 degrees, corners 29.7 -> 2.5; bench/RESULTS.md, thirty-seventh
  /// session). false: every disc near counts.
  bool overhang_falloff = true;
  double teleport = 10.0;     ///< a device jump of more tool radii than this in one tick re-places the proxy
  /// A Gaussian that no other kept Gaussian comes near (a floater, as trained scenes have in free
  /// space) does not block the proxy, so the tool is not caught on specks in mid-air. "Near" is
  /// overlapping by default, or within `isolation_gap` (below). A Gaussian with such a
  /// neighbour (a surface, a bump on it) always blocks.
  bool pass_isolated = true;
  /// How near, in tool radii, another Gaussian must come to make one part of a surface (but no
  /// nearer than the Gaussian's own middle semi-axis: a floater a few of its sizes off a surface
  /// stays a floater). 0 (default): only an overlapping one; the sparse surfaces of small trained
  /// objects then count as floaters (fruitdrops: the tool passes the outer Gaussians at 2 of 7
  /// probe sites). 1 holds there, but on the bundled Truck pressed 2 m under its roof it lets
  /// the proxy find its way into the cab, so it is not the default (bench/RESULTS.md).
  double isolation_gap = 0.0;
  /// Floaters come in small clumps too: a clump of at most this many Gaussians overlapping one
  /// another, with no other Gaussian within its members' own largest semi-axis, does not block
  /// either (FloaterRule::isolated). Without it a pair of overlapping floaters 12 mm above the
  /// fidelity plane held a 5 mm tool like a solid blob (direction p95 94 degrees). 1: single
  /// Gaussians only; at most FloaterRule::kLargestCluster.
  std::size_t floater_cluster = FloaterRule::kMaxCluster;
  /// The shaded normal's turns under the loaded spring add no energy that the contact's earlier
  /// turns did not take out (SpringEnergyBound): without it a press into a Gaussian crease gave
  /// back up to 12 mJ more than it took (bench/RESULTS.md, twenty-sixth session). false: the
  /// plain coupling. The rotational spring of a compound tool is not bounded.
  bool energy_bound = true;
  /// Every tool. The solid the proxy rests on (kSeen: the surface the splats render, issue 71;
  /// kEllipsoids: the Gaussians' exact ellipsoids, the solid before).
  ProxySurface surface = ProxySurface::kSeen;
  /// kSeen, every tool. How far behind the tool's leading point the eye of the seen solid may
  /// be, in tool radii (> 0): the layers a push has come through since its approach began, up to
  /// this far back, count toward the surface it meets. Far enough that a viewer outside an
  /// object capture sees what the proxy is held by: at 32 R the floaters beyond it were left out
  /// and fruitdrops' 0.5 % tool went through where a viewer sees a surface (bench/RESULTS.md,
  /// fiftieth session).
  double seen_window = 256.0;
  /// One-part tool, kSeen. The tool's footprint (SeenProxy): rays around the leading point's
  /// hold the sphere as a rigid ball on the rim of a see-through hole narrower than it and on the
  /// walls of a groove or a corner. One more short ray a tick (probe-run render p99 1.3-2.4x the
  /// seen proxy's without it, within 2x the ellipsoid proxy's; bench/RESULTS.md, fifty-sixth
  /// session). Compound tools have footprint lines of their own (SeenCompoundProxy).
  bool seen_footprint = true;

  /// Compound tool. k_r, N m/rad: the rotational coupling; 1 N m/rad gives 0.5 N m, a desktop
  /// 6-DoF arm's torque, at about 30 deg.
  double rot_stiffness = 1.0;
  /// Compound tool. b_r, N m s/rad: twice the sampled-spring bound k_r T / 2 at 1 kHz, as for the force.
  double rot_damping = 0.001;
  /// Compound tool. The largest motion of any point per sub-rotation, in smallest semi-axes, (0, 1].
  double rotation_step = 0.25;
  /// Compound tool. Sub-rotations per tick (the rest of a turn waits for the next tick), >= 1.
  int max_rotation_steps = 64;
  /// Compound tool. The translation's and the contact probe's sweeps keep each part's near list
  /// (SweepQuery's reuse margin, one smallest semi-axis): a part resting on the Gaussians reads
  /// its candidates from it instead of the BVH. The same contacts (within the exact search's
  /// tolerance); false: the BVH every sweep.
  bool near_lists = true;
  /// Compound tool. On a clean flat face each part's shaded normal is averaged with the face's
  /// mean thin axis where they agree (EdgeNormal::face_blend). false: the shaded normal (and
  /// edges) only.
  bool face_average = true;
};

/// Throws InputError, its message starting with `who`, for a non-positive or non-finite
/// stiffness, negative damping, friction outside 0 <= mu_k <= mu_s, substeps outside [1, 16], a
/// negative lift, isolation gap, device shading or shading turn, a non-positive shading kernel,
/// tail, teleport, a negative tau_opacity or shading reuse, floater_cluster outside
/// [1, FloaterRule::kLargestCluster], negative rotational stiffness or damping, rotation_step
/// outside (0, 1], max_rotation_steps < 1, or a surface-specific field
/// (surface_specific_proxy_fields()) set away from its default for the other surface.
void validate_proxy_params(const ProxyParams& p, std::string_view who);

/// Which tool a field of ProxyParams serves.
enum class ProxyTool { kOnePart, kCompound };

/// A field of ProxyParams that serves one kind of tool only: its name, the command-line option
/// that sets it, the tool it serves, whether `p` holds it at its default, and why it does not
/// apply to the other tool.
struct ProxyToolField {
  std::string_view name, option;
  ProxyTool serves;
  bool (*at_default)(const ProxyParams& p);
  void (*reset)(ProxyParams& p);  ///< sets the field to its default
  std::string_view why_not;
};

/// Every tool-specific field (a fixed table).
[[nodiscard]] std::span<const ProxyToolField> tool_specific_proxy_fields() noexcept;

/// A field of ProxyParams that one surface only reads: the ellipsoid proxy's floater rule,
/// shaded normal, crest hold, sweeps and energy bound; the seen solid's window and footprint.
/// Its name, option, the surface it serves, whether `p` holds it at its default, and why the
/// other surface has no use for it.
struct ProxySurfaceField {
  std::string_view name, option;
  ProxySurface serves;
  bool (*at_default)(const ProxyParams& p);
  std::string_view why_not;
};

/// Every surface-specific field (a fixed table).
[[nodiscard]] std::span<const ProxySurfaceField> surface_specific_proxy_fields() noexcept;

/// `p` with every field that does not serve `tool` at its default: for a caller that renders
/// tools of both kinds from one set (the fidelity benchmark's point-tool and 6-DoF rows), so
/// that each renderer gets the fields that serve its tool.
[[nodiscard]] ProxyParams proxy_params_for(const ProxyParams& p, ProxyTool tool);

/// Throws InputError (starting with `who`) naming every field of `p` that is set away from its
/// default but does not serve `tool` (a compound tool: kCompound), with the option that sets it
/// and why it does not apply. Called by ProxyRenderer::set_tool; a command checks the options it
/// was given with the same table.
void check_proxy_params_apply(const ProxyParams& p, ProxyTool tool, std::string_view who);

}  // namespace gshaptics
