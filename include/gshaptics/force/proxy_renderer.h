#pragma once
/// @file
/// The proxy (god-object) renderer on the Gaussians themselves: a copy of the tool, the proxy,
/// is kept where it overlaps no Gaussian that passed the filter, and the device is coupled to
/// it by a virtual spring-damper. Each tick the proxy moves from its last free pose toward the
/// device, stops at the first contact along the way (continuous: SweepQuery, so no shell is
/// thin enough to tunnel through), then slides along the constraint planes of the Gaussians
/// that block it (at most three, as in the god-object) within a fixed number of sub-steps.
///
/// Sources: the god-object of Zilles & Salisbury (1995), the virtual proxy of Ruspini, Kolarov &
/// Khatib (1997), point-cloud proxies (Leeper et al. 2012; Ryden & Chizeck 2012), virtual
/// coupling and its passivity bound b > k T / 2 (Colgate, Stanley & Brown 1995; Colgate &
/// Schenkel 1997), Coulomb friction by a friction cone on the proxy (Salisbury et al. 1995),
/// and force shading (Morgenbesser & Srinivasan 1996): the force acts along a smoothed normal.
///
/// Force shading on Gaussians: the contact normal is the negative gradient of the opacity-weighted
/// Gaussian density, each Gaussian widened by a kernel of `shading_kernel` tool radii,
///   n(p) ∝ sum_i alpha_i exp(-q_i / 2) A_i^-1 (p - c_i),  A_i = Sigma_i + s^2 I,
///   q_i = (p - c_i)^T A_i^-1 (p - c_i),
/// which varies smoothly across neighbouring Gaussians (docs/design.md Sec. 7). The proxy's
/// position comes from the exact geometry; the force F = k_c (x_proxy - x_device) is taken along
/// n (normal part, minus b_c v_device . n, never pulling), plus the friction part when
/// friction is on. Without friction the tangential offset of the proxy, which comes only from
/// Gaussian-scale bumps of the shell, is not rendered.
///
/// The renderer is the composition of four parts, each with its own header and tests:
/// ProxySolver (next free position: sweep, slide, lift, placement, floaters), shaded_normal()
/// (the contact normal), FrictionCone (stick or slide) and VirtualCoupling (the force).
///
/// Threading and hot path as ForceRenderer: one thread; render() allocates, locks, logs and
/// throws nothing. Placing the proxy after a start inside geometry or a teleport runs a bounded
/// search (at most 15 directions x 40 steps of the early-exit query).

#include <Eigen/Core>
#include <limits>

#include <memory>

#include "gshaptics/force/compound_proxy.h"
#include "gshaptics/force/edge_normal.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/force/friction_cone.h"
#include "gshaptics/force/proxy_solver.h"
#include "gshaptics/force/virtual_coupling.h"

namespace gshaptics {

/// Parameters of the proxy renderer. SI units.
struct ProxyParams {
  double stiffness = 1000.0;  ///< k_c, N/m: coupling spring (a desktop device renders 1-3 N/mm)
  /// b_c, N s/m, along the contact normal while in contact. A sampled spring of stiffness k with
  /// one tick T of delay is passive for b > k T / 2 (0.5 N s/m at 1000 N/m and 1 kHz).
  double damping = 1.0;
  double mu_s = 0.0;          ///< static friction coefficient (0: off)
  double mu_k = 0.0;          ///< kinetic friction coefficient (<= mu_s)
  bool opacity_stiffness = false;  ///< k_c scaled by the smoothed opacity of the blocking Gaussians
  double tau_opacity = 0.02;  ///< s, time constant of that smoothing
  int substeps = 4;           ///< sweeps per tick (first contact, then slides on up to 3 planes)
  /// When the proxy is wedged between Gaussian-scale bumps it steps up this many tool radii
  /// (at most twice a tick) and slides on: it glides over the shell's noise (0: never).
  double lift = 0.05;
  double shading_kernel = 0.5;  ///< kernel width of the shaded normal, in tool radii (or in the
                                ///< blocking Gaussians' middle semi-axis when that is larger)
  /// How far the shaded normal's support reaches past the Gaussians that touch the tool, in q
  /// (kShadingTail, shaded_normal()): a term left out weighs under exp(-tail / 2) of theirs.
  double shading_tail = kShadingTail;
  double shading_reuse = 0.05;  ///< the shaded normal is recomputed once the proxy moved this many tool radii
  /// ... or sooner where the field turns fast: a reading is kept only while the normal would
  /// turn by at most this many degrees at the rate it turned between the last two readings
  /// (down to 1/25 of shading_reuse; ShadedNormalCache::set_turn_tolerance). Round a convex
  /// edge the field turns tens of degrees per mm, and a normal held over 5 % of the tool made
  /// the force depend on the path (presses that gave back more energy than they took). 0: off.
  double shading_turn = 1.0;
  /// Steps (Gaussians visited or fitted) a tick may spend preparing the next shaded normal while
  /// the proxy slides steadily, so the tick it is due does not pay for a whole reading (about
  /// 1700 steps, 70 us, for a 10 mm tool on 2 mm spacing); ShadedNormalCache::read_ahead. A
  /// reading within this budget, or on a slow or wandering motion, is made whole when due. 0:
  /// every reading whole, when due.
  std::size_t shading_budget = 384;
  /// Where the field turns slowly (shading_turn does not bind), the shaded normal is also read
  /// where the device would rest, the device lifted along the normal to the proxy's level, at
  /// most this many tool radii from the proxy, and blended with the proxy's reading while the
  /// two agree (ProxyRenderer::kDeviceShadingFrom / To degrees). The frictionless proxy slides
  /// off the Gaussians' rims into the hollows between them, and on a curved face the field read
  /// there belongs to another place than the one the hand presses: on the 8 mm-spacing fidelity
  /// cylinder with a 10 mm tool, direction p95 3.8 -> 2.3-2.6 degrees over seeds 1-18
  /// (bench/RESULTS.md, thirty-second session). 0: off (the proxy's reading alone).
  double device_shading = 0.2;
  /// Where the patch under the tool is a clean convex corner (three faces: EdgeNormal's corner
  /// test), the force turns to the patch's support normal (edge_normal.h, blended over 3-6
  /// degrees of disagreement): the direction that best separates the tool from the corner's
  /// Gaussians, which stays in the corner's normal cone where the shaded field of the face the
  /// proxy rests on tilts out of it (fidelity seeds 1-18: every cube corner cell within 4.0
  /// degrees p95, were up to 8.9, but seed 12's fin; bench/RESULTS.md, thirty-fourth session).
  /// false: the shaded field everywhere.
  bool corner_normal = true;
  /// Where a disc of the other face overhangs a convex edge and blocks the tool beside it (a
  /// fin), the shaded normal leaves out that face's discs behind the plane of the face under the
  /// tool (front_face, FreeBall::face; fidelity seeds 1-30, 8 mm cube, 5 mm tool: edges p95 23.5
  /// -> 3.8 degrees, corners 29.7 -> 2.5; bench/RESULTS.md, thirty-seventh session). false:
  /// every disc near counts.
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
  /// either (FloaterTest::isolated). Without it a pair of overlapping floaters 12 mm above the
  /// fidelity plane held a 5 mm tool like a solid blob (direction p95 94 degrees). 1: single
  /// Gaussians only; at most FloaterTest::kLargestCluster.
  std::size_t floater_cluster = FloaterTest::kMaxCluster;
  /// The shaded normal's turns under the loaded spring add no energy that the contact's earlier
  /// turns did not take out (SpringEnergyBound): without it a press into a Gaussian crease gave
  /// back up to 12 mJ more than it took (bench/RESULTS.md, twenty-sixth session). false: the
  /// plain coupling.
  bool energy_bound = true;
  /// A compound tool's sweeps keep each part's near list (CompoundProxyParams::near_lists).
  bool near_lists = true;
  /// On a clean flat face a compound tool's part averages its shaded normal with the face's mean
  /// thin axis (CompoundProxyParams::face_average).
  bool face_average = true;
};

class ProxyRenderer final : public ForceRenderer {
 public:
  /// `f_max`: a clamp on the output, N (+inf: none; the runtime's safety layer limits the force).
  /// Throws InputError for non-positive stiffness or f_max, negative damping, friction or
  /// device_shading, mu_k > mu_s, substeps outside [1, 16] or a non-positive kernel.
  explicit ProxyRenderer(const CollisionWorld& world, const ProxyParams& params = {},
                         double f_max = std::numeric_limits<double>::infinity());
  [[nodiscard]] std::string_view name() const noexcept override { return "proxy"; }
  /// ProxyParams::corner_normal: where the last corner reading found a messy patch (a real
  /// scene's), the next comes once the proxy has moved this many tool radii (elsewhere,
  /// shading_reuse's).
  static constexpr double kCornerSearch = 0.5;
  /// ProxyParams::corner_normal: the corner patch's reach beyond the tool, in its smallest
  /// semi-axis (EdgeNormal's band, as the compound proxy's edge patch: it takes in the other
  /// faces' discs while the tool rests on one face within a radius of the corner; half of it
  /// left seed 5's 8 mm corner at 6.7 degrees, bench/RESULTS.md).
  static constexpr double kCornerBand = 1.0;
  /// ProxyParams::device_shading's blend: the reading where the device would rest counts fully
  /// while it is within kDeviceShadingFrom degrees of the proxy's, not at all past
  /// kDeviceShadingTo (linear between).
  static constexpr double kDeviceShadingFrom = 6.0, kDeviceShadingTo = 12.0;
  /// The cosine of the turn of the face under an overhang (front_face) past which the cached
  /// shaded readings are made again (10 degrees).
  static constexpr double kFaceTurn = 0.985;
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept override;
  /// The Gaussians holding the proxy at the last tick (at most three).
  [[nodiscard]] std::span<const Contact> contacts() const noexcept override {
    return compound_active_ ? compound_->blockers() : solver_.blockers();
  }
  void reset() noexcept override;
  /// A tool of several parts (or one off the TCP) gets the compound proxy (force/compound_proxy.h:
  /// translation and rotation, the wrench at the contacts), with this renderer's stiffness,
  /// damping, substeps, shading kernel and reuse, floater rule, teleport distance and friction
  /// (mu_s, mu_k). A single part at the TCP stays with the one-ellipsoid proxy.
  void set_tool(const CompoundTool& tool) override;
  [[nodiscard]] bool renders_compound() const noexcept override { return compound_ != nullptr; }
  RenderOutput render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                               const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                               double dt) noexcept override;
  /// The compound proxy, when set_tool() gave one (nullptr otherwise).
  [[nodiscard]] const CompoundProxy* compound() const noexcept { return compound_.get(); }

  [[nodiscard]] const Eigen::Vector3d& proxy_position() const noexcept { return solver_.position(); }
  /// The one-ellipsoid proxy's last move: its sweeps, candidates and exact searches (profiling;
  /// gshaptics_proxy_bench --breakdown).
  [[nodiscard]] const ProxyMove& last_move() const noexcept { return last_move_; }
  /// Readings of the shaded normal so far (the cache's misses; profiling).
  [[nodiscard]] std::uint64_t shading_reads() const noexcept { return shade_.reads(); }
  /// The shaded normal's cache (its readings, whole and ahead; profiling).
  [[nodiscard]] const ShadedNormalCache& shading_cache() const noexcept { return shade_; }
  [[nodiscard]] const Eigen::Vector3d& contact_normal() const noexcept { return normal_; }
  [[nodiscard]] bool sticking() const noexcept { return sticking_; }
  /// The depth the energy bound withholds now, m (SpringEnergyBound::withheld; 0 without contact).
  [[nodiscard]] double withheld_depth() const noexcept { return bound_.withheld(); }
  /// Proxy placements by the search (start inside geometry, teleports) and failed searches,
  /// of the one-ellipsoid proxy and the compound proxy together.
  [[nodiscard]] std::uint64_t placements() const noexcept {
    return solver_.placements() + (compound_ ? compound_->placements() : 0);
  }
  [[nodiscard]] std::uint64_t lost() const noexcept { return solver_.lost() + (compound_ ? compound_->lost() : 0); }
  [[nodiscard]] const ProxyParams& params() const noexcept { return params_; }

  /// The shaded normal at `center` for a tool of bounding radius `radius` with this renderer's
  /// kernel (unit; zero when no Gaussian is near). See gshaptics::shaded_normal().
  [[nodiscard]] Eigen::Vector3d shaded_normal(const Eigen::Vector3d& center, double radius) const noexcept;

 private:
  // Out of contact: friction, the coupling's onset, the energy bound and the contact flags reset.
  void leave_contact() noexcept;
  // leave_contact(), and the normal readings' caches dropped too (shaded, device, corner): nothing
  // of the last contact kept.
  void forget_contact() noexcept;
  // The proxy placed anew at `tool` (free there, or the nearest free pose) after forget_contact():
  // a device jump, or the proxy caught in a pocket.
  void restart_at(const ToolEllipsoid& tool) noexcept;
  const CollisionWorld* world_;
  ProxyParams params_;
  ProxySolver solver_;
  FrictionCone friction_;
  VirtualCoupling coupling_;
  SpringEnergyBound bound_;  // the shaded normal's turns add no energy (ProxyParams::energy_bound)
  Eigen::Vector3d last_device_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond last_rotation_ = Eigen::Quaterniond::Identity();
  bool in_contact_ = false, sticking_ = false;
  ShadedNormalCache shade_;
  ShadedNormalCache shade_device_;  // the field where the device would rest (device_shading)
  Eigen::Vector3d face_ = Eigen::Vector3d::Zero();  // the FreeBall::face the cached readings were made for
  ProxyMove last_move_;
  ShadingScratch shading_scratch_;  // the shaded normal's working memory
  // Its own working memory: a reading in shading_scratch_ would give up shade_'s reading ahead.
  ShadingScratch device_scratch_;
  EdgeNormal corners_;  // the patch's support normal at a clean convex corner (corner_normal)
  EdgeNormalCache corner_cache_;
  std::unique_ptr<CompoundProxy> compound_;
  CompoundTool tool_;
  bool compound_active_ = false;
};

}  // namespace gshaptics
