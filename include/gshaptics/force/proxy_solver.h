#pragma once
/// @file
/// The god-object solver on the Gaussians (one of the proxy renderer's four parts): where the
/// proxy, a copy of the tool that overlaps no Gaussian, goes next. Each tick it moves from its last
/// free pose toward a goal (the device, or where friction puts it), stops at the first contact
/// along the way (continuous: SweepQuery, so no shell is thin enough to tunnel through), then
/// slides on the constraint planes of the Gaussians that block it (at most three, as in the
/// god-object), within a fixed number of sweeps.
///
/// Sources: the god-object of Zilles & Salisbury (1995) and the virtual proxy of Ruspini,
/// Kolarov & Khatib (1997): the constrained goal is the point of the planes' feasible side
/// closest to the goal; point-cloud proxies (Leeper et al. 2012; Ryden & Chizeck 2012) for
/// proxies on unstructured primitives.
///
/// Threading: one thread; move_toward() allocates, locks, logs and throws nothing. place() runs
/// a bounded search (at most 15 directions x 40 steps of the early-exit query).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <span>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/collision/sweep_query.h"
#include "gshaptics/force/floater_rule.h"
#include "gshaptics/force/proxy_params.h"

namespace gshaptics {

/// A constraint of the god-object: the proxy must stay on the side of `normal` (unit) through
/// `point`: normal . (x - point) >= 0. World frame, m.
struct ConstraintPlane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ(), point = Eigen::Vector3d::Zero();
};

/// The point of {x : n_i . (x - p_i) >= 0 for all i} closest to `goal`: the god-object's small
/// quadratic program (Zilles & Salisbury 1995), solved by trying the projection onto the
/// intersection of every subset of the planes (at most three) and keeping the nearest feasible
/// one. Nearly parallel subsets are skipped. Returns `goal` when it is feasible, and the first
/// plane's point when no projection is (an empty intersection).
[[nodiscard]] Eigen::Vector3d closest_feasible_point(const Eigen::Vector3d& goal,
                                                     std::span<const ConstraintPlane> planes) noexcept;

/// The Contact a proxy reports for the Gaussian in `slot` that holds it (k_min 0: it touches),
/// made by the tool's part `part`.
[[nodiscard]] Contact blocker_contact(const CollisionWorld& world, std::uint32_t slot, std::uint8_t part = 0) noexcept;

/// Where a god-object was wedged when it first stepped up out of a pocket, kept through the
/// rest of its tick's sweeps. The step-up moves the proxy away from its goal; if the sweeps after
/// it do not end nearer the goal than this, the proxy goes back here: under a loaded coupling a
/// move away from the device is energy the proxy made (the 60-degree groove's crease gave back
/// 1-5 mJ a press that way). Sweeps toward the constrained goal never move away from it, so this
/// is the only move the rule can undo. Used by ProxySolver and CompoundProxy.
struct WedgedState {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();  ///< the proxy's centre, world, m
  ConstraintPlane planes[3];
  int np = 0;
  std::size_t n_blockers = 0;
  ConstraintPlane hit_plane;  ///< the contact that wedged it (not yet a plane)
  std::uint32_t hit_slot = 0;
  std::uint8_t hit_part = 0;  ///< the compound tool's part that made it (0: one ellipsoid)
  void save(const Eigen::Vector3d& at, const ConstraintPlane* pl, int n, std::size_t blockers,
            const Eigen::Vector3d& hit_normal, std::uint32_t slot, std::uint8_t part = 0) noexcept {
    p = at;
    np = n;
    for (int i = 0; i < n; ++i) planes[i] = pl[i];
    n_blockers = blockers;
    hit_plane = {hit_normal, at};
    hit_slot = slot;
    hit_part = part;
  }
  /// Restores the planes as the sweeps had them without the step-up (the wedging contact's plane
  /// added, as they would have) and the blocker count; returns the plane count.
  int restore(ConstraintPlane* pl, std::size_t& blockers) const noexcept {
    int n = np;
    for (int i = 0; i < n; ++i) pl[i] = planes[i];
    if (n < 3) pl[n++] = hit_plane;
    blockers = n_blockers;
    return n;
  }
};

/// The last step-up WedgedState undid: where the proxy was wedged, at which orientation, and its
/// goal then. A step-up is not tried again from there until the goal has moved a lift away: a
/// proxy held wedged would otherwise pay the step-up and the sweeps after it on every tick only
/// to undo them (halo's probe run: proxy p99 17.6 -> 8.4 us; the fidelity side-on stylus at seed
/// 12: 81 -> 43 us). Used by ProxySolver (orientation unused) and CompoundProxy.
struct UndoneStepUp {
  bool active = false;
  Eigen::Vector3d at = Eigen::Vector3d::Zero(), goal = Eigen::Vector3d::Zero();  ///< world, m
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  void remember(const Eigen::Vector3d& p, const Eigen::Vector3d& g,
                const Eigen::Quaterniond& q = Eigen::Quaterniond::Identity()) noexcept {
    active = true, at = p, goal = g, rotation = q;
  }
  /// Whether a step-up from `p` toward `g` (orientation `q`) repeats the undone one: the proxy
  /// within `eps` m of where it was, turned by no more than moves a point `reach` m from its
  /// centre by `eps`, and the goal less than `lift` m from the goal then.
  [[nodiscard]] bool repeats(const Eigen::Vector3d& p, const Eigen::Vector3d& g, double eps, double lift,
                             const Eigen::Quaterniond& q = Eigen::Quaterniond::Identity(),
                             double reach = 0) const noexcept {
    return active && (p - at).norm() <= eps && (g - goal).norm() < lift &&
           (reach == 0 || q.angularDistance(rotation) * reach <= eps);
  }
};

/// The pocket rule of both proxies (ProxyRenderer, CompoundProxy): the contact normal `n` says
/// the device is on the surface's free side (n . offset < 0, offset = proxy - device), and the
/// device's own pose is free (`device_free()`, asked only then): the proxy is caught in a
/// Gaussian-scale pocket (a sharp tool rim under a neighbouring disc's rim) and would pull the
/// hand into the surface. It rejoins the device instead (the caller re-places it there).
template <class DeviceFree>
[[nodiscard]] bool caught_in_pocket(const Eigen::Vector3d& n, const Eigen::Vector3d& offset,
                                    DeviceFree&& device_free) noexcept {
  return n.dot(offset) < 0 && device_free();
}

/// One tick's move of the proxy.
struct ProxyMove {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< the proxy's new centre, world, m
  int constraints = 0;        ///< planes holding it (0: free; 1 face, 2 edge, 3 corner)
  /// The first plane's normal when the proxy moved onto a plane this tick (zero when it held
  /// still or is free).
  Eigen::Vector3d first_normal = Eigen::Vector3d::Zero();
  std::uint32_t candidates = 0;  ///< Gaussians the sweeps looked at
  std::uint32_t sweeps = 0;      ///< continuous first-contact sweeps run (SweepQuery::first_contact)
  std::uint32_t exact = 0;       ///< exact first-contact searches those ran (the expensive step)
};

class ProxySolver {
 public:
  /// Reads substeps, lift, pass_isolated, isolation_gap, floater_cluster and shading_kernel of
  /// `params` (a copy); the caller validates them (ProxyRenderer does).
  ProxySolver(const CollisionWorld& world, const ProxyParams& params);

  /// Forget the proxy: the next tick places it again.
  void reset() noexcept;
  [[nodiscard]] bool placed() const noexcept { return valid_; }

  /// Put the proxy at the free pose nearest to `tool` (the tool itself when it is free):
  /// outward along the shaded normal first, then the 6 axis and 8 diagonal directions, in steps
  /// of a quarter tool radius up to 10 radii. Counts a placement, and a loss when no free pose
  /// was found (the proxy then stays on the tool).
  void place(const ToolEllipsoid& tool) noexcept;

  /// Whether `tool` overlaps a kept Gaussian (the early-exit query).
  [[nodiscard]] bool blocked(const ToolEllipsoid& tool) noexcept { return free_query_.any_contact(tool); }

  /// How far short of a contact the proxy stops, in tool radii (a compound tool: in its parts'
  /// smallest semi-axis, CompoundProxy): 5 um on a 5 mm tool, 5 mN at 1 kN/m. The sweeps' tolerance is half of it
  /// (SweepQuery: a near-tie within it is not searched to the end), so it sets how many exact
  /// searches a resting tool's ticks run: 1e-4 cost firepit a third more of them at p95-p99
  /// (bench/RESULTS.md, twenty-third session) and moved no fidelity cell beyond its noise.
  static constexpr double kStandOff = 1e-3;

  /// Move the proxy (of `tool`'s shape and rotation) toward `goal`, or hold it where it is with
  /// its blockers when `hold` (static friction). Floaters (pass_isolated) are swept through in
  /// the same pass (SweepQuery's BlockFilter); the last tick's blockers are tested first.
  ProxyMove move_toward(const ToolEllipsoid& tool, const Eigen::Vector3d& goal, bool hold) noexcept;

  [[nodiscard]] const Eigen::Vector3d& position() const noexcept { return proxy_; }
  /// The Gaussians holding the proxy after the last move (at most three; k_min is 0: they touch).
  [[nodiscard]] std::span<const Contact> blockers() const noexcept { return {blockers_.data(), n_blockers_}; }
  /// Unit mean of the constraint planes' normals (the exact contact normals, Gaussian -> tool,
  /// world frame) at the last move that met one; kept while held; zero before any or after a
  /// placement. Which way is "away from the surface" the proxy rests on (FreeBall::up).
  [[nodiscard]] const Eigen::Vector3d& support_normal() const noexcept { return support_; }
  [[nodiscard]] std::uint64_t placements() const noexcept { return placements_; }
  [[nodiscard]] std::uint64_t lost() const noexcept { return lost_; }
  /// Whether the Gaussian in `slot` is a floater (FloaterRule::isolated).
  bool isolated(std::uint32_t slot, double gap) noexcept { return floaters_.isolated(slot, gap); }
  /// The floater rule with its cache, for a filter of the renderer's own readings.
  [[nodiscard]] FloaterRule& floater_rule() noexcept { return floaters_; }

 private:
  const CollisionWorld* world_;
  ProxyParams params_;
  SweepQuery sweep_;
  ContactQuery free_query_;
  Eigen::Vector3d proxy_ = Eigen::Vector3d::Zero();
  bool valid_ = false;
  std::array<Contact, 3> blockers_{};
  std::size_t n_blockers_ = 0;
  Eigen::Vector3d support_ = Eigen::Vector3d::Zero();
  int last_constraints_ = 0;
  std::uint64_t placements_ = 0, lost_ = 0;
  FloaterRule floaters_;
  UndoneStepUp undone_;  // the last step-up WedgedState undid
};

}  // namespace gshaptics
