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
/// The renderer is the composition of four parts, each with its own header and tests, all
/// reading one ProxyParams (proxy_params.h): ProxySolver (next free position: sweep, slide, lift,
/// placement, floaters), ProxyNormal (the contact normal: shaded, device-side, corner),
/// FrictionCone (stick or slide) and VirtualCoupling (the force, with its energy bound). A tool
/// with a shape gets the compound proxy (compound_proxy.h), which reads the same ProxyParams.
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
#include "gshaptics/force/material.h"
#include "gshaptics/force/proxy_normal.h"
#include "gshaptics/force/proxy_params.h"
#include "gshaptics/force/seen_compound_proxy.h"
#include "gshaptics/force/seen_proxy.h"
#include "gshaptics/force/proxy_solver.h"
#include "gshaptics/force/virtual_coupling.h"

namespace gshaptics {

class ProxyRenderer final : public ForceRenderer {
 public:
  /// `f_max`: a clamp on the output, N (+inf: none; the runtime's safety layer limits the force),
  /// for the compound proxy too. Throws InputError for a non-positive f_max or what
  /// validate_proxy_params() refuses.
  explicit ProxyRenderer(const CollisionWorld& world, const ProxyParams& params = {},
                         double f_max = std::numeric_limits<double>::infinity());
  [[nodiscard]] std::string_view name() const noexcept override { return "proxy"; }
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept override;
  /// The Gaussians holding the proxy at the last tick (at most three).
  /// The ellipsoid proxy's blockers; on the seen solid, the layers that make the seen surface
  /// under the contact (SeenProxy::contacts(), SeenCompoundProxy::contacts(): Contact::k_min
  /// holds a layer's weight there).
  [[nodiscard]] std::span<const Contact> contacts() const noexcept override {
    if (seen_compound_) return seen_compound_->contacts();
    if (seen_) return seen_->contacts();
    return compound_active_ ? compound_->blockers() : solver_.blockers();
  }
  void reset() noexcept override;
  /// A tool of several parts (or one off the TCP) gets the compound proxy (force/compound_proxy.h:
  /// translation and rotation, the wrench at the contacts), reading this renderer's ProxyParams
  /// and f_max. A single part at the TCP stays with the one-ellipsoid proxy. On the seen solid
  /// (ProxySurface::kSeen) the seen compound proxy (seen_compound_proxy.h) takes every tool but
  /// a sphere at the TCP, one ellipsoid included (the one-part seen proxy is a sphere of the
  /// tool's bounding radius). Throws InputError for an invalid tool, where a field of
  /// ProxyParams set away from its default does not serve this tool
  /// (check_proxy_params_apply), and on the seen solid for a tool other than a sphere with
  /// materials (not served yet).
  void set_tool(const CompoundTool& tool) override;
  [[nodiscard]] bool renders_compound() const noexcept override {
    return compound_ != nullptr || seen_compound_ != nullptr;
  }
  RenderOutput render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                               const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                               double dt) noexcept override;
  /// The compound proxy, when set_tool() gave one (nullptr otherwise).
  [[nodiscard]] const CompoundProxy* compound() const noexcept { return compound_.get(); }
  /// The compound proxy on the seen solid, when set_tool() gave one (nullptr otherwise).
  [[nodiscard]] const SeenCompoundProxy* seen_compound() const noexcept { return seen_compound_.get(); }

  /// The one-part proxy's centre, world, m; on the seen solid the seen proxy's (a tool with a
  /// shape there: the seen compound proxy's TCP).
  [[nodiscard]] const Eigen::Vector3d& proxy_position() const noexcept {
    if (seen_compound_) return seen_compound_->position();
    if (seen_) return seen_->position();
    return solver_.position();
  }
  /// The one-ellipsoid proxy's last move: its sweeps, candidates and exact searches (profiling;
  /// gshaptics_proxy_bench --breakdown).
  [[nodiscard]] const ProxyMove& last_move() const noexcept { return last_move_; }
  /// Readings of the shaded normal so far (the cache's misses; profiling).
  [[nodiscard]] std::uint64_t shading_reads() const noexcept { return normals_.reads(); }
  /// The shaded normal's cache (its readings, whole and ahead; profiling).
  [[nodiscard]] const ShadedNormalCache& shading_cache() const noexcept { return normals_.cache(); }
  /// The contact's normal (unit, world; zero before a first contact), as proxy_position() picks
  /// its proxy.
  [[nodiscard]] const Eigen::Vector3d& contact_normal() const noexcept {
    if (seen_compound_) return seen_compound_->contact_normal();
    if (seen_) return seen_->contact_normal();
    return normal_;
  }
  [[nodiscard]] bool sticking() const noexcept { return sticking_; }
  /// The depth the energy bound withholds now, m (SpringEnergyBound::withheld; 0 without contact).
  [[nodiscard]] double withheld_depth() const noexcept { return coupling_.withheld(); }
  /// Proxy placements by the search (start inside geometry, teleports) and failed searches,
  /// of the one-ellipsoid proxy and the compound proxy together.
  [[nodiscard]] std::uint64_t placements() const noexcept {
    return solver_.placements() + (compound_ ? compound_->placements() : 0);
  }
  [[nodiscard]] std::uint64_t lost() const noexcept { return solver_.lost() + (compound_ ? compound_->lost() : 0); }
  [[nodiscard]] const ProxyParams& params() const noexcept { return params_; }

  /// ProxyParams::crest_hold: how deep inside the crest's normal cone the spring must lie, rad
  /// (EdgeNormal::crest_depth): 10 degrees, past the discs' tilts (3 degrees on the fidelity
  /// scenes), so a tool resting on a face beside an edge, its spring along the face's normal, is
  /// not held.
  static constexpr double kCrestMargin = 10.0 * 3.14159265358979323846 / 180;
  /// ... and the device moves along the spring: |v . e| >= kCrestAlong |v| |e| (within 45
  /// degrees), or slower than kCrestStill m/s (a hand resting; a device's velocity noise).
  static constexpr double kCrestAlong = 0.7;
  static constexpr double kCrestStill = 2e-3;
  /// ... and the device lies within kCrestCorridor tool radii of the line from the proxy through
  /// the crest's apex (EdgeNormalAnswer::apex; across an edge's line).
  static constexpr double kCrestCorridor = 0.25;

  /// The shaded normal at `center` for a tool of bounding radius `radius` with this renderer's
  /// kernel (unit; zero when no Gaussian is near). See gshaptics::shaded_normal().
  [[nodiscard]] Eigen::Vector3d shaded_normal(const Eigen::Vector3d& center, double radius) const noexcept;

  /// Materials by region (force/material.h), resolved on this renderer's world: each tick the
  /// coupling's stiffness and damping, the friction cone's coefficients and the viscous drag are
  /// the blend under the proxy (MaterialField::at); nullptr: the ProxyParams' own everywhere.
  /// On the seen surface (SeenProxy) the materials are read from the layers that make the seen
  /// surface under the contact, weighted T_k alpha_k. A compound tool (set_tool) reads the same
  /// field on the ellipsoids; on the seen solid it refuses one (InputError).
  void set_materials(std::shared_ptr<const MaterialField> field);
  /// The blend under the proxy at the last tick in contact (the ProxyParams' own without a field):
  /// the materials of the Gaussians holding it (MaterialField::contact_shares), followed along
  /// its path over one tool radius (MaterialFollower).
  [[nodiscard]] const MaterialBlend& material() const noexcept;
  [[nodiscard]] const MaterialField* materials() const noexcept { return follower_ ? &follower_->field() : nullptr; }

 private:
  // The materials of the Gaussians holding the proxy at `p` (`blockers`), followed along its path
  // (MaterialFollower), applied to the coupling and the friction cone; the procedural reliefs
  // read at `contact`.
  void apply_material(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double radius, const Eigen::Vector3d& contact,
                      std::span<const Contact> blockers) noexcept;
  // The device's new pose: the proxy is placed anew where the device jumped (teleport) or turned
  // into geometry. Returns the device's step since the last tick, m.
  Eigen::Vector3d follow_device(const ToolEllipsoid& tool) noexcept;
  // ProxyParams::crest_hold: whether the proxy, in contact on a clean convex edge or corner,
  // holds this tick for the device at `device` (m) moving at `velocity` (m/s).
  [[nodiscard]] bool held_on_crest(const Eigen::Vector3d& device, const Eigen::Vector3d& velocity,
                                   double radius) const noexcept;
  // The contact normal for the proxy at rest at `move`'s position (ProxyNormal's two stages, the
  // pocket rule between them). False: the proxy was caught in a pocket and rejoined the device.
  bool contact_normal(const ToolEllipsoid& tool, const ProxyMove& move, Eigen::Vector3d& n) noexcept;
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
  double f_max_;
  ProxySolver solver_;
  ProxyNormal normals_;
  FrictionCone friction_;
  VirtualCoupling coupling_;
  Eigen::Vector3d last_device_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond last_rotation_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero();
  bool in_contact_ = false, sticking_ = false;
  ProxyMove last_move_;
  std::unique_ptr<CompoundProxy> compound_;  // a tool with a shape (set_tool)
  std::unique_ptr<SeenProxy> seen_;          // ProxySurface::kSeen: the proxy on the seen solid
  std::unique_ptr<SeenCompoundProxy> seen_compound_;  // kSeen with a tool with a shape (on seen_'s solid)
  bool compound_active_ = false;             // the last tick was the compound proxy's
  bool seen_compound_active_ = false;        // the last tick was the seen compound proxy's
  std::unique_ptr<MaterialFollower> follower_;  // set_materials (nullptr: none)
  MaterialBlend own_material_;                  // the ProxyParams' own, as a blend
};

}  // namespace gshaptics
