#include "gshaptics/force/proxy_renderer.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "gshaptics/broadphase/bvh.h"
#include "gshaptics/error.h"

namespace gshaptics {

ProxyRenderer::ProxyRenderer(const CollisionWorld& world, const ProxyParams& params, double f_max)
    : world_(&world), params_(params), f_max_(f_max), sweep_(world), free_query_(world, [] {
        QueryOptions q;
        q.max_contacts = 1;  // any_contact() keeps no contact set
        return q;
      }()) {
  const ProxyParams& p = params;
  if (!(p.stiffness > 0) || !std::isfinite(p.stiffness)) throw InputError("proxy: stiffness must be > 0 N/m");
  if (!(p.damping >= 0) || !std::isfinite(p.damping)) throw InputError("proxy: damping must be >= 0 N s/m");
  if (!(f_max > 0)) throw InputError("proxy: f_max must be > 0 N");
  if (!(p.mu_s >= 0 && p.mu_k >= 0 && p.mu_k <= p.mu_s) || !std::isfinite(p.mu_s))
    throw InputError("proxy: friction needs 0 <= mu_k <= mu_s");
  if (p.substeps < 1 || p.substeps > 16) throw InputError("proxy: substeps must be in [1, 16]");
  if (!(p.shading_kernel > 0) || !(p.teleport > 0) || !(p.tau_opacity >= 0))
    throw InputError("proxy: shading_kernel and teleport must be > 0, tau_opacity >= 0");
}

void ProxyRenderer::reset() noexcept {
  valid_ = in_contact_ = sticking_ = sliding_ = shade_valid_ = false;
  n_blockers_ = 0;
  opacity_ = 1.0;
  cache_state_.fill(0);
  normal_.setZero();
}

Eigen::Vector3d ProxyRenderer::shaded_normal(const Eigen::Vector3d& c, double radius) const noexcept {
  const double s = params_.shading_kernel * radius, s2 = s * s;
  const double half = radius + 3.0 * s;
  float lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = round_down_to_float(c[k] - half);
    hi[k] = round_up_to_float(c[k] + half);
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const CollisionGaussian* gs = world_->gaussians().data();
  world_->bvh().for_each_overlapping_leaf(lo, hi, [&](std::uint32_t first, std::uint32_t count) {
    for (std::uint32_t k = first; k < first + count; ++k) {
      const CollisionGaussian& g = gs[k];
      const Eigen::Vector3d d = c - Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
      // In the Gaussian's frame A = diag(a^2 + s^2): q = sum dl^2 / A, A^-1 d = R (dl / A).
      const Eigen::Matrix3d R = rotation_matrix(g);
      const Eigen::Vector3d dl = R.transpose() * d;
      Eigen::Vector3d ad;
      double q = 0;
      for (int j = 0; j < 3; ++j) {
        const double inv = 1.0 / (double(g.semi_axes[j]) * g.semi_axes[j] + s2);
        ad[j] = dl[j] * inv;
        q += dl[j] * ad[j];
      }
      if (q > 40) continue;
      const double an = ad.norm();
      if (!(an > 0)) continue;
      // A flat Gaussian (a disc, as 3DGS leaves surfaces) states its own normal: its shortest
      // axis, turned toward p. A round one only says where it is: the density gradient. The two
      // are blended by flatness f = 1 - a_min / a_mid.
      int jmin = 0;
      for (int j = 1; j < 3; ++j)
        if (g.semi_axes[j] < g.semi_axes[jmin]) jmin = j;
      const double a_min = g.semi_axes[jmin];
      const double a_mid = std::min(g.semi_axes[(jmin + 1) % 3], g.semi_axes[(jmin + 2) % 3]);
      const double flat = a_mid > 0 ? 1.0 - a_min / a_mid : 0.0;
      const Eigen::Vector3d axis = R.col(jmin) * (dl[jmin] >= 0 ? 1.0 : -1.0);
      const Eigen::Vector3d dir = flat * axis + (1.0 - flat) * (R * ad) / an;
      sum += (double(g.opacity) * std::exp(-0.5 * q)) * dir;
    }
  });
  const double n = sum.norm();
  return n > 0 && std::isfinite(n) ? Eigen::Vector3d(sum / n) : Eigen::Vector3d::Zero();
}

Eigen::Vector3d ProxyRenderer::constrained_goal(const Eigen::Vector3d& goal, const Plane* planes, int n) const noexcept {
  // The point of {x : n_i . (x - p_i) >= 0} closest to the goal: the best feasible projection
  // onto the intersection of a subset of the planes (the god-object's small quadratic program).
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
      const Eigen::MatrixXd Nm = N.topRows(m);
      const Eigen::MatrixXd G = Nm * Nm.transpose();
      const double det = G.determinant();
      if (!(std::fabs(det) > 1e-10)) continue;  // (nearly) parallel planes
      x = goal - Nm.transpose() * (G.inverse() * (Nm * goal - b.head(m)));
    }
    if (!feasible(x)) continue;
    const double d = (x - goal).squaredNorm();
    if (d < best_d) best_d = d, best = x;
  }
  return best;
}

bool ProxyRenderer::isolated(std::uint32_t slot) noexcept {
  for (std::size_t i = 0; i < kIsolationCache; ++i)
    if (cache_state_[i] != 0 && cache_slot_[i] == slot) return cache_state_[i] == 2;
  const CollisionGaussian& g = world_->gaussians()[slot];
  ToolEllipsoid self;
  self.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
  self.rotation = Eigen::Quaterniond(rotation_matrix(g)).normalized();
  self.semi_axes = Eigen::Vector3d(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
  const bool alone = !free_query_.any_contact(self, slot);
  cache_slot_[cache_next_] = slot;
  cache_state_[cache_next_] = alone ? 2 : 1;
  cache_next_ = (cache_next_ + 1) % kIsolationCache;
  return alone;
}

void ProxyRenderer::place(const ToolEllipsoid& tool) noexcept {
  ++placements_;
  valid_ = true;
  in_contact_ = sticking_ = sliding_ = false;
  n_blockers_ = 0;
  proxy_ = tool.center;
  if (!free_query_.any_contact(tool)) return;
  // Nearest free pose: outward along the shaded normal first, then the 6 axis and 8 diagonal
  // directions, in steps of a quarter tool radius up to 10 radii; the closest free point wins.
  const double r = tool.bounding_radius();
  Eigen::Vector3d dirs[15];
  int nd = 0;
  const Eigen::Vector3d ns = shaded_normal(tool.center, r);
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

RenderOutput ProxyRenderer::render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept {
  RenderOutput out;
  out.proxy = tool.center;
  if (!tool.valid() || !velocity.allFinite() || !(dt > 0)) {
    out.status = QueryStatus::kInvalidTool;
    return out;
  }
  const Eigen::Vector3d xd = tool.center;
  const double r = tool.bounding_radius();
  ToolEllipsoid at = tool;
  if (!valid_ || (xd - last_device_).norm() > params_.teleport * r) {
    place(tool);
  } else if (!tool.rotation.isApprox(last_rotation_, 1e-12)) {
    at.center = proxy_;
    if (free_query_.any_contact(at)) place(tool);  // the tool turned into geometry
  }
  const Eigen::Vector3d device_step = xd - last_device_;
  last_device_ = xd;
  last_rotation_ = tool.rotation;

  // Friction cone (Coulomb): a sticking proxy stays while the device's tangential offset is
  // within mu_s times its depth; then it slides, kept mu_k times the depth behind the device,
  // for as long as the device keeps moving on (kinetic friction needs relative motion).
  Eigen::Vector3d goal = xd;
  Eigen::Vector3d slip_dir = Eigen::Vector3d::Zero();
  const bool was_sliding = sliding_;
  sticking_ = sliding_ = false;
  if (in_contact_ && params_.mu_s > 0 && normal_.squaredNorm() > 0) {
    const Eigen::Vector3d e = xd - proxy_;
    const double depth = -e.dot(normal_);
    const Eigen::Vector3d et = e + depth * normal_;
    const double offset = et.norm();
    if (depth > 0 && offset > 0) {
      const Eigen::Vector3d dir = et / offset;
      const bool moving_on = was_sliding && device_step.dot(dir) > 0;
      const double limit = (was_sliding ? params_.mu_k : params_.mu_s) * depth;
      if (offset <= limit && !moving_on) {
        sticking_ = true;
        goal = proxy_;  // stuck: the proxy stays (the device is inside the cone)
      } else {
        // Kinetic friction opposes the sliding motion: the device's own tangential step when
        // it has one (the offset's direction wanders with the shell's bumps), else the offset.
        sliding_ = true;
        const Eigen::Vector3d step_t = device_step - device_step.dot(normal_) * normal_;
        slip_dir = step_t.norm() > 1e-9 * r ? Eigen::Vector3d(step_t.normalized()) : dir;
        goal = xd - slip_dir * (params_.mu_k * depth);
      }
    } else if (depth > 0) {
      sticking_ = true;
      goal = proxy_;
    }
  }

  // God-object: sweep toward the goal, stop at the first contact, slide on the planes. A
  // sticking proxy keeps its place and its blockers. The last tick's blockers are tested first.
  Plane planes[3];
  int np = sticking_ ? std::max(1, last_constraints_) : 0;
  std::uint32_t hints[3];
  std::size_t n_hints = 0;
  for (; n_hints < n_blockers_; ++n_hints) hints[n_hints] = blockers_[n_hints].slot;
  if (!sticking_) n_blockers_ = 0;
  Eigen::Vector3d p = proxy_;
  const double eps = 1e-4 * r;  // the proxy stops this far short of a contact
  std::uint32_t candidates = 0;
  std::uint32_t ignore[8];
  std::size_t n_ignore = 0;
  int lifts = 0;
  for (int s = 0; s < params_.substeps && !sticking_; ++s) {
    const Eigen::Vector3d target = constrained_goal(goal, planes, np);
    const Eigen::Vector3d u = target - p;
    const double len = u.norm();
    if (len <= 1e-9 * r) break;
    at.center = p;
    SweepHit hit = sweep_.first_contact(at, u, {ignore, n_ignore}, {hints, n_hints});
    candidates += sweep_.counts().candidates;
    // Floaters do not block: sweep again without them (at most 8 per tick).
    while (hit.hit && params_.pass_isolated && n_ignore < 8 && isolated(hit.slot)) {
      ignore[n_ignore++] = hit.slot;
      hit = sweep_.first_contact(at, u, {ignore, n_ignore});
      candidates += sweep_.counts().candidates;
    }
    if (!hit.hit) {
      p = target;
      if (np == 0) break;
      continue;
    }
    p += u * std::max(0.0, hit.t - eps / len);
    // Wedged between Gaussian-scale bumps (two planes already, and blocked at once): step up
    // along the planes' mean normal by a small lift and start the planes afresh, so the proxy
    // glides over the shell's noise instead of stopping in a pocket of it.
    if (np >= 2 && hit.t * len < 1e-3 * r && lifts < 2) {
      Eigen::Vector3d up = Eigen::Vector3d::Zero();
      for (int i = 0; i < np; ++i) up += planes[i].normal;
      up += hit.normal;
      if (up.norm() > 0) {
        const Eigen::Vector3d lift = up.normalized() * (params_.lift * r);
        at.center = p;
        const SweepHit lh = sweep_.first_contact(at, lift, {ignore, n_ignore});
        if (!lh.hit) {
          p += lift;
          np = 0;
          ++lifts;
          continue;
        }
      }
    }
    const CollisionGaussian& g = world_->gaussians()[hit.slot];
    if (n_blockers_ < blockers_.size()) {
      Contact& c = blockers_[n_blockers_++];
      c.index = g.source_index;
      c.slot = hit.slot;
      c.opacity = g.opacity;
      c.k_min = 0;
      c.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
    }
    if (np == 3) break;
    planes[np++] = {hit.normal, p};
  }
  proxy_ = p;
  last_constraints_ = np;
  out.proxy = p;
  out.constraints = std::uint8_t(np);
  out.counts.candidates = candidates;
  out.counts.contacts = std::uint32_t(n_blockers_);

  const Eigen::Vector3d e = p - xd;
  if (np == 0 && e.norm() <= 1e-6 * r) {  // free: the proxy is on the device
    in_contact_ = sticking_ = sliding_ = false;
    opacity_ = 1.0;
    return out;
  }
  // The contact normal: shaded (recomputed once the proxy has moved 5 % of the tool radius),
  // unless it disagrees with where the proxy holds the device.
  if (!(shade_valid_ && (p - shade_at_).norm() <= params_.shading_reuse * r)) {
    // The kernel follows the tool, or the Gaussians when they are larger (sparse scenes): a
    // kernel smaller than the spacing would see single Gaussians, not the surface.
    double scale = r;
    for (std::size_t i = 0; i < n_blockers_; ++i) {
      const float* a = world_->gaussians()[blockers_[i].slot].semi_axes;
      scale = std::max(scale, double(std::max({std::min(a[0], a[1]), std::min(a[1], a[2]), std::min(a[0], a[2])})));
    }
    shade_ = shaded_normal(p, scale);
    shade_at_ = p;
    shade_valid_ = true;
  }
  Eigen::Vector3d n = shade_;
  if (!(n.dot(e) > 0)) {
    // (planes[] is filled only when the proxy moved this tick; a sticking proxy keeps normal_.)
    const Eigen::Vector3d fallback = !sticking_ && np > 0 ? planes[0].normal : normal_;
    n = e.norm() > 0 ? Eigen::Vector3d(e.normalized()) : fallback;
  }
  normal_ = n;
  in_contact_ = true;
  double k = params_.stiffness;
  if (params_.opacity_stiffness && n_blockers_ > 0) {
    double a = 0;
    for (std::size_t i = 0; i < n_blockers_; ++i) a += blockers_[i].opacity;
    a /= double(n_blockers_);
    const double beta = params_.tau_opacity > 0 ? 1.0 - std::exp(-dt / params_.tau_opacity) : 1.0;
    opacity_ += beta * (a - opacity_);
    k *= opacity_;
  }
  const double fn = std::max(0.0, k * e.dot(n) - params_.damping * velocity.dot(n));
  Eigen::Vector3d f = fn * n;
  if (sticking_) f += k * (e - e.dot(n) * n);  // static friction: the spring's tangential part
  if (sliding_) f -= params_.mu_k * fn * slip_dir;  // kinetic friction: mu_k times the normal force
  const double fm = f.norm();
  if (fm > f_max_) f *= f_max_ / fm;
  out.force = f;
  return out;
}

}  // namespace gshaptics
