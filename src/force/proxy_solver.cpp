#include "gshaptics/force/proxy_solver.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "gshaptics/force/shaded_normal.h"

namespace gshaptics {

Eigen::Vector3d closest_feasible_point(const Eigen::Vector3d& goal, std::span<const ConstraintPlane> planes) noexcept {
  const int n = int(std::min<std::size_t>(planes.size(), 3));
  const auto feasible = [&](const Eigen::Vector3d& x) {
    for (int i = 0; i < n; ++i)
      if (planes[i].normal.dot(x - planes[i].point) < -1e-12) return false;
    return true;
  };
  if (feasible(goal)) return goal;
  Eigen::Vector3d best = n > 0 ? planes[0].point : goal;
  double best_d = INFINITY;
  for (int mask = 1; mask < (1 << n); ++mask) {
    Eigen::Matrix3d N = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    int m = 0;
    for (int i = 0; i < n; ++i)
      if (mask & (1 << i)) {
        N.row(m) = planes[i].normal.transpose();
        b[m] = planes[i].normal.dot(planes[i].point);
        ++m;
      }
    Eigen::Vector3d x;
    if (m == 1) {
      x = goal - (N.row(0).dot(goal) - b[0]) * N.row(0).transpose();
    } else {
      // Fixed-size blocks (the unused rows of N are zero): no allocation on the servo tick.
      const Eigen::Vector3d res = N * goal - b;
      Eigen::Vector3d lambda = Eigen::Vector3d::Zero();
      if (m == 2) {
        const Eigen::Matrix2d G = N.topRows<2>() * N.topRows<2>().transpose();
        if (!(std::fabs(G.determinant()) > 1e-10)) continue;  // (nearly) parallel planes
        lambda.head<2>() = G.inverse() * res.head<2>();
      } else {
        const Eigen::Matrix3d G = N * N.transpose();
        if (!(std::fabs(G.determinant()) > 1e-10)) continue;
        lambda = G.inverse() * res;
      }
      x = goal - N.transpose() * lambda;
    }
    if (!feasible(x)) continue;
    const double d = (x - goal).squaredNorm();
    if (d < best_d) best_d = d, best = x;
  }
  return best;
}

Contact blocker_contact(const CollisionWorld& world, std::uint32_t slot, std::uint8_t part) noexcept {
  const CollisionGaussian& g = world.gaussians()[slot];
  Contact c;
  c.index = g.source_index;
  c.slot = slot;
  c.opacity = g.opacity;
  c.k_min = 0;
  c.part = part;
  c.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
  return c;
}

ProxySolver::ProxySolver(const CollisionWorld& world, const ProxyParams& params)
    : world_(&world), params_(params), sweep_(world), free_query_(world, [] {
        QueryOptions q;
        q.max_contacts = 1;  // any_contact() keeps no contact set
        return q;
      }()),
      floaters_(world, params.floater_cluster) {}

void ProxySolver::reset() noexcept {
  valid_ = false;
  undone_.active = false;
  n_blockers_ = 0;
  support_.setZero();
  floaters_.reset();
}

void ProxySolver::place(const ToolEllipsoid& tool) noexcept {
  ++placements_;
  valid_ = true;
  undone_.active = false;
  n_blockers_ = 0;
  support_.setZero();
  proxy_ = tool.center;
  if (!free_query_.any_contact(tool)) return;
  const double r = tool.bounding_radius();
  Eigen::Vector3d dirs[15];
  int nd = 0;
  const Eigen::Vector3d ns = shaded_normal(*world_, tool.center, r, params_.shading_kernel);
  if (ns.squaredNorm() > 0) dirs[nd++] = ns;
  for (int a = 0; a < 3; ++a)
    for (double sg : {1.0, -1.0}) dirs[nd++] = Eigen::Vector3d::Unit(a) * sg;
  for (int k = 0; k < 8 && nd < 15; ++k)
    dirs[nd++] = Eigen::Vector3d(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1).normalized();
  double best = INFINITY;
  ToolEllipsoid at = tool;
  for (int i = 0; i < nd; ++i)
    for (int step = 1; step <= 40; ++step) {
      const double dist = 0.25 * r * step;
      if (dist >= best) break;
      at.center = tool.center + dirs[i] * dist;
      if (!free_query_.any_contact(at)) {
        best = dist;
        proxy_ = at.center;
        break;
      }
    }
  if (!std::isfinite(best)) ++lost_;
}

ProxyMove ProxySolver::move_toward(const ToolEllipsoid& tool, const Eigen::Vector3d& goal, bool hold) noexcept {
  const double r = tool.bounding_radius();
  ToolEllipsoid at = tool;
  ConstraintPlane planes[3];
  int np = hold ? std::max(1, last_constraints_) : 0;
  std::uint32_t hints[3];
  std::size_t n_hints = 0;
  for (; n_hints < n_blockers_; ++n_hints) hints[n_hints] = blockers_[n_hints].slot;
  if (!hold) n_blockers_ = 0;
  Eigen::Vector3d p = proxy_;
  const double eps = kStandOff * r;  // the proxy stops this far short of a contact
  std::uint32_t candidates = 0, sweeps = 0, exact = 0;
  int lifts = 0;
  // Where the proxy was wedged before its first step-up: a step-up may only bring it nearer its
  // goal by the end of the tick (WedgedState, below).
  WedgedState wedged;
  // Floaters do not block: the sweep asks, in its one pass, whether a Gaussian it reaches first
  // is one (FloaterRule, cached per slot). At most FloaterRule::kQueriesPerTick uncached answers
  // a tick; past that a Gaussian blocks (the safe side).
  FloaterRule::Filter floaters(floaters_, params_.isolation_gap * r, params_.pass_isolated);
  const BlockFilter filter = floaters.block_filter();
  for (int s = 0; s < params_.substeps && !hold; ++s) {
    const Eigen::Vector3d target = closest_feasible_point(goal, {planes, std::size_t(np)});
    const Eigen::Vector3d u = target - p;
    const double len = u.norm();
    // After a contact, a slide shorter than the sweeps' tolerance (half the stand-off) is not
    // swept: the proxy stays, within that of its goal.
    if (len <= (np > 0 ? 0.5 * eps : 1e-9 * r)) break;
    at.center = p;
    // The proxy stops eps short of the reported contact; a near-tie within half of that is
    // not searched to the end (SweepQuery's tolerance): it still stays eps / 2 away.
    const SweepHit hit = sweep_.first_contact(at, u, {}, {hints, n_hints}, filter, 1.0, 0.5 * eps / len);
    candidates += sweep_.counts().candidates;
    exact += sweep_.counts().exact;
    ++sweeps;
    if (!hit.hit) {
      p = target;
      if (np == 0) break;
      continue;
    }
    p += u * std::max(0.0, hit.t - eps / len);
    // Wedged between Gaussian-scale bumps (two planes already, and blocked at once): step up
    // along the planes' mean normal by a small lift and start the planes afresh, so the proxy
    // glides over the shell's noise instead of stopping in a pocket of it.
    // (Not where the last step-up was undone while the goal is within a lift of its goal then.)
    if (params_.lift > 0 && np >= 2 && hit.t * len < 1e-3 * r && lifts < 2 &&
        !undone_.repeats(p, goal, eps, params_.lift * r)) {
      Eigen::Vector3d up = Eigen::Vector3d::Zero();
      for (int i = 0; i < np; ++i) up += planes[i].normal;
      up += hit.normal;
      if (up.norm() > 0) {
        const Eigen::Vector3d lift = up.normalized() * (params_.lift * r);
        at.center = p;
        const SweepHit lh = sweep_.first_contact(at, lift, {}, {}, filter);
        candidates += sweep_.counts().candidates;
        exact += sweep_.counts().exact;
        ++sweeps;
        if (!lh.hit) {
          if (lifts == 0) wedged.save(p, planes, np, n_blockers_, hit.normal, hit.slot);
          p += lift;
          np = 0;
          ++lifts;
          continue;
        }
      }
    }
    if (n_blockers_ < blockers_.size()) blockers_[n_blockers_++] = blocker_contact(*world_, hit.slot);
    if (np == 3) break;
    planes[np++] = {hit.normal, p};
  }
  if (lifts > 0 && (p - goal).squaredNorm() > (wedged.p - goal).squaredNorm()) {
    // The step-up left the proxy farther from its goal than where it was wedged: under a loaded
    // coupling that is energy the proxy made (it moved against the force). It stays wedged.
    p = wedged.p;
    np = wedged.restore(planes, n_blockers_);
    if (n_blockers_ < blockers_.size()) blockers_[n_blockers_++] = blocker_contact(*world_, wedged.hit_slot);
    undone_.remember(p, goal);
  }
  proxy_ = p;
  last_constraints_ = np;
  ProxyMove out;
  out.position = p;
  out.constraints = np;
  if (!hold && np > 0) {
    out.first_normal = planes[0].normal;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int i = 0; i < np; ++i) sum += planes[i].normal;
    if (sum.norm() > 1e-9) support_ = sum.normalized();
  }
  out.candidates = candidates;
  out.sweeps = sweeps;
  out.exact = exact;
  return out;
}

}  // namespace gshaptics
