#pragma once
/// @file
/// The god-object proxy for a compound tool (issue 36, item 2, first version): a rigid copy of
/// the tool, every part of it, kept where no part overlaps a Gaussian, coupled to the device in
/// translation and in rotation.
///
/// Each tick:
/// 1. Rotation: the proxy turns from its orientation toward the device's about its tool centre
///    point (TCP), in sub-rotations; each part's centre is swept along its chord (SweepQuery,
///    continuous), the sub-rotation small enough that no point moves more than `rotation_step`
///    smallest semi-axes off its part's swept chord (shells thicker than that are certified),
///    and the turned pose is tested (the early-exit query), so a turn
///    that would swing the tool through a thin plate stops at the contact (the conservative
///    advancement of Mirtich 1996 / Ortega, Redon & Coquillart 2007, in fixed steps).
/// 2. Translation: the god-object of Zilles & Salisbury (1995) with all parts: the proxy moves
///    toward the device, stops at the first contact of any part (all parts in one sweep: one
///    BVH traversal, one sorted list of candidates; SweepQuery), then slides on the constraint
///    planes of the Gaussians that block it (at most three). Floaters (ProxyParams::pass_isolated) do not block.
/// 3. Wrench: a virtual coupling in both (Colgate, Stanley & Brown 1995): F = max(0, k_c e . n - b_c v . n) n
///    with e = x_proxy - x_device and n the contact normal: the touching parts' shaded normals
///    (Morgenbesser & Srinivasan 1996; shaded_normal.h, each read at the centre of the sphere of
///    the part's smallest semi-axis touching where the part touches); where the part's patch of
///    Gaussians is a clean edge (two faces, told by the spread of the Gaussians' thin axes), the
///    patch's support normal blends in (support_normal.h: the direction that best separates the
///    part from the patch's hull, kept across the edge), the tool's own normal where it rests on
///    the edge; where it is one clean flat face, the shaded normal is averaged with the face's
///    mean thin axis while they agree (EdgeNormal::face_blend); weighted as below (e^
///    when they disagree with e; when they say the device is on the free side and its pose is
///    free, the proxy rejoins the device), applied at the contacts: its moment about the
///    TCP is (c - x_tcp) x F, c the mean of the touching parts' surface points facing their
///    contacts, each weighted 1 - (gap / band)^2 (gap: how far the part is from a Gaussian along
///    -F, band: half the smallest semi-axis; a stylus lying on a wall gets the middle of its line of
///    contact, as a penalty model with its depth-weighted contacts would (McNeely et al. 1999);
///    a part whose first contact lies inside another part, where the tool's surface is the
///    other part's, carries none: kHiddenRamp); plus, when
///    contact stopped a turn, the rotational coupling tau = k_r theta - b_r omega, theta the
///    rotation taking the device's orientation to the proxy's (axis times angle, world). The
///    translational spring's depth is bounded so that the contact normal's turns add no energy
///    (SpringEnergyBound; the rotational spring is not bounded). A turn
///    that ran out of sub-rotations this tick catches up on the next, with no torque.
/// Without contact the proxy is the device and the wrench is zero.
///
/// 4. Friction (mu_s > 0): the friction cone of the one-ellipsoid proxy (friction_cone.h,
///    Salisbury et al. 1995) on the translation, about the last tick's contact normal: inside
///    the cone the proxy holds still with its blockers and the spring's tangential part is
///    rendered too; outside it the proxy slides, held mu_k times the depth behind the device, and
///    the force gets mu_k times the normal force against the sliding direction. Friction acts at
///    the contacts, so its moment is in the torque.
///
/// What it does not do yet: the proxy does not turn under the contact torque (a full 6-DoF
/// god-object solves for the pose that balances it; here the torque is rendered and the proxy
/// keeps the device's orientation while that is free), no torsional (spin) friction, and
/// corners (three faces) keep the shaded normal, as do grooves (edge_normal.h tests convexity).
///
/// Threading: one thread; render() allocates, locks, logs and throws nothing.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <limits>
#include <memory>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/collision/sweep_query.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/force/floater_rule.h"
#include "gshaptics/force/friction_cone.h"
#include "gshaptics/force/material.h"
#include "gshaptics/force/shaded_normal.h"
#include "gshaptics/force/proxy_params.h"
#include "gshaptics/force/proxy_solver.h"
#include "gshaptics/force/edge_normal.h"
#include "gshaptics/force/virtual_coupling.h"

namespace gshaptics {

class CompoundProxy {
 public:
  /// Reads the proxy's parameters (proxy_params.h: every field but the one-part tool's own; its
  /// "tool radii" are the tool's largest semi-axis, its reach for `teleport`); `f_max` clamps the
  /// coupling force, N (+inf: none; the safety layer limits it). Throws InputError for an invalid
  /// tool or parameters.
  CompoundProxy(const CollisionWorld& world, const CompoundTool& tool, const ProxyParams& params = {},
                double f_max = std::numeric_limits<double>::infinity());

  /// One tick: the device's TCP position (m) and orientation (tool frame -> world), its velocity
  /// (m/s) and angular velocity (rad/s), dt (s, > 0). Force and torque (about the device's TCP)
  /// on the device, world frame.
  RenderOutput render(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                      const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity, double dt) noexcept;
  void reset() noexcept;
  /// Materials by region (force/material.h), read as the one-part proxy reads them
  /// (MaterialFollower): its contacts' materials along its path over the smallest semi-axis, and
  /// the texture under the touching parts' contact point, carried across the normal by the
  /// device's lag behind or ahead of the proxy (texture_tip). nullptr: none.
  void set_materials(std::shared_ptr<const MaterialField> field);
  /// The blend at the last tick in contact; nullptr without a field.
  [[nodiscard]] const MaterialBlend* material() const noexcept { return follower_ ? &follower_->blend() : nullptr; }
  /// The Gaussians holding the proxy (at most three), Contact::part naming the part.
  [[nodiscard]] std::span<const Contact> blockers() const noexcept { return {blockers_.data(), n_blockers_}; }
  [[nodiscard]] const Eigen::Vector3d& position() const noexcept { return x_; }
  [[nodiscard]] const Eigen::Quaterniond& orientation() const noexcept { return q_; }
  /// The tool, in its tool frame (as given).
  [[nodiscard]] const CompoundTool& tool() const noexcept { return tool_; }
  [[nodiscard]] std::uint64_t placements() const noexcept { return placements_; }
  [[nodiscard]] std::uint64_t lost() const noexcept { return lost_; }
  /// What the translation's and the probe's sweeps have done since construction: sweeps run,
  /// parts whose candidates came from their near lists (near_lists), near lists built,
  /// candidates read and exact first-contact searches run (SweepCounts).
  struct SweepWork {
    std::uint64_t sweeps = 0, reused = 0, rebuilt = 0, candidates = 0, exact = 0;
  };
  [[nodiscard]] const SweepWork& sweep_work() const noexcept { return work_; }
  /// The parts' shaded-normal readings since construction (cache misses, ShadedNormalCache::reads).
  [[nodiscard]] std::uint64_t shading_reads() const noexcept {
    std::uint64_t n = 0;
    for (const ShadedNormalCache& c : shades_) n += c.reads();
    return n;
  }
  /// Whether any part of the tool at this pose overlaps a kept Gaussian.
  [[nodiscard]] bool blocked(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation) noexcept;

 private:
  const CollisionWorld* world_;
  CompoundTool tool_;
  ProxyParams params_;
  FloaterRule floaters_;  // the floater rule of the one-ellipsoid proxy, with its own cache
  // The translation's and the contact probe's sweeps, with near lists (SweepQuery's reuse margin:
  // the smallest semi-axis, twice the contact band), and the turns' sub-step sweeps, without.
  SweepQuery sweep_, turn_sweep_;
  ContactQuery free_query_;
  std::array<ToolEllipsoid, kMaxToolParts> parts_{};
  // The parts' offsets and rotations turned by posed_q_ (pose_parts: the sweeps of one tick share
  // the orientation, so each poses its parts by a translation only; the same values as
  // CompoundTool::posed).
  Eigen::Quaterniond posed_q_{0, 0, 0, 0};
  std::array<Eigen::Vector3d, kMaxToolParts> turned_offset_{};
  std::array<Eigen::Quaterniond, kMaxToolParts> turned_rotation_{};
  Eigen::Vector3d x_ = Eigen::Vector3d::Zero(), last_device_ = Eigen::Vector3d::Zero();
  FrictionCone friction_{0.0, 0.0};
  VirtualCoupling coupling_;  // the translational coupling, with its energy bound (energy_bound)
  bool in_contact_ = false;                             // the proxy held the device at the last tick
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero();    // along this contact normal
  int last_constraints_ = 0;                            // planes holding it at the last move
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
  bool placed_ = false;
  UndoneStepUp undone_;  // the last step-up translate_toward undid (ProxySolver's rule)
  std::array<Contact, 3> blockers_{};
  std::size_t n_blockers_ = 0;
  // Each part's first contact along the last tick's contact probe (the Gaussian's slot), tried
  // first by the next tick's probe as a hint: a part at rest usually touches it again.
  std::array<std::uint32_t, kMaxToolParts> probe_slots_{};
  std::size_t n_probe_slots_ = 0;
  std::uint64_t placements_ = 0, lost_ = 0;
  SweepWork work_;
  void count_sweep() noexcept {  // (after each of sweep_'s sweeps)
    ++work_.sweeps;
    work_.reused += sweep_.counts().reused;
    work_.rebuilt += sweep_.counts().rebuilt;
    work_.candidates += sweep_.counts().candidates;
    work_.exact += sweep_.counts().exact;
  }
  double min_axis_ = 0, reach_ = 0, largest_ = 0;
  double f_max_ = std::numeric_limits<double>::infinity();
  std::unique_ptr<MaterialFollower> follower_;  // set_materials (nullptr: none)
  std::array<ShadedNormalCache, kMaxToolParts> shades_{};  // each part's last shaded normal
  ShadingScratch shading_scratch_;  // the parts' readings' working memory
  EdgeNormal edge_;  // each part's normal at a clean convex edge, with its cache
  std::array<EdgeNormalCache, kMaxToolParts> edges_{};
  // A part touches within this x the smallest semi-axis of a Gaussian along the force (its weight
  // falls as 1 - (gap / band)^2 to 0 there): wide enough that a stylus lying on a surface loads every part
  // whatever the Gaussians' 0.5 mm jitter, short enough to keep the probe sweeps cheap.
  static constexpr double kContactBand = 0.5;
  // The probe's tolerance, in stand-offs (ProxySolver::kStandOff x the smallest semi-axis): a
  // part's gap along the probe is known to within this, its weight to within 0.4 % of the band.
  // Over one stand-off, so that a part the translation left a stand-off from a Gaussian is
  // settled by that Gaussian as hint (a resting stylus's parts: on the 8 mm cube the probe's
  // candidates in the slow ticks fell from 17 to 12 a tick).
  static constexpr double kProbeTolerance = 2.0;
  // A part's first contact this far inside another part (ToolEllipsoid::inner_clearance, in the
  // tool's smallest semi-axis) is hidden: the part carries no load there (its weight falls
  // linearly to 0 from the other part's surface to this depth).
  static constexpr double kHiddenRamp = 0.05;
  // The edge normal's patch: the Gaussians within this x the smallest semi-axis of a part (a
  // wider patch than the contact band, so that an edge's hull spans several rims).
  static constexpr double kPatchBand = 1.0;

  int pose_parts(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept;
  void place(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation) noexcept;
  bool turn_toward(const Eigen::Quaterniond& target) noexcept;  // true: a contact stopped the turn
  int translate_toward(const Eigen::Vector3d& goal) noexcept;  // the constraint planes holding it
  void release() noexcept;  // out of contact: friction and the contact normal forgotten
  // The floater rule's state for one tick's sweeps (FloaterRule::Filter, off with pass_isolated).
  [[nodiscard]] FloaterRule::Filter floater_rule() noexcept {
    return FloaterRule::Filter(floaters_, params_.isolation_gap * largest_, params_.pass_isolated);
  }
  // The sum of the touching parts' shaded contact normals and of their contact points' moments
  // about the proxy's TCP, each weighted (the contact band, the hidden ramp), for the spring
  // along `spring` (unit). Returns the summed weight (0: no part touches).
  double touching_parts(const Eigen::Vector3d& spring, Eigen::Vector3d& normal, Eigen::Vector3d& moment) noexcept;
  // Where the texture's tip reads the relief: the touching parts' contact point moved across the
  // normal n by the device's offset from the proxy's TCP there, at most the smallest semi-axis.
  // A proxy caught between a relief's Gaussians lags the hand by up to a wavelength and then
  // hops (the stick-hop of a god-object in a row of pockets); a tip on the proxy read the relief
  // at the pocket, and its force's fundamental stayed at 0.04 N whatever the relief's amplitude
  // (lambda 2 mm, 20 mm/s). The tip follows the hand's path instead, as a stylus's tip does.
  [[nodiscard]] Eigen::Vector3d texture_tip(const Eigen::Vector3d& contact, const Eigen::Vector3d& device,
                                            const Eigen::Vector3d& n) const noexcept {
    Eigen::Vector3d lag = device - x_;
    lag -= lag.dot(n) * n;
    const double len = lag.norm();
    return contact + (len > min_axis_ ? Eigen::Vector3d(lag * (min_axis_ / len)) : lag);
  }
  // One touching part's contact normal (shaded, edge, face) for its probe hit `h`.
  Eigen::Vector3d part_normal(int j, const SweepHit& h, double spacing, const BlockFilter& filter) noexcept;
  // The rotational coupling's torque when contact stopped the turn toward `qd`.
  [[nodiscard]] Eigen::Vector3d turn_torque(const Eigen::Quaterniond& qd, const Eigen::Vector3d& angular_velocity,
                                            bool turn_stopped) const noexcept;
};

}  // namespace gshaptics
