#include "gshaptics/force/compound_proxy.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/error.h"
#include "gshaptics/force/shaded_normal.h"
#include "gshaptics/force/virtual_coupling.h"

namespace gshaptics {

static_assert(std::size_t(kMaxToolParts) <= SweepQuery::kMaxParts, "a compound tool's parts must fit one compound sweep");

namespace {

// The smallest semi-axis of any part (0 for an empty tool: validated later).
double smallest_semi_axis(const CompoundTool& tool) noexcept {
  double m = INFINITY;
  for (const ToolPart& p : tool.view()) m = std::min(m, p.semi_axes.minCoeff());
  return std::isfinite(m) && m > 0 ? m : 0.0;
}

}  // namespace

CompoundProxy::CompoundProxy(const CollisionWorld& world, const CompoundTool& tool, const ProxyParams& params,
                             double f_max)
    : world_(&world),
      tool_(tool),
      params_((validate_proxy_params(params, "compound proxy"), params)),
      floaters_(world, params.floater_cluster),
      sweep_(world, 4096, params.near_lists ? smallest_semi_axis(tool) : 0.0),
      turn_sweep_(world),
      free_query_(world, [] {
        QueryOptions q;
        q.max_contacts = 1;
        return q;
      }()),
      coupling_(params_, f_max),
      f_max_(f_max),
      edge_(world) {
  if (!(f_max > 0)) throw InputError("compound proxy: f_max must be > 0 N");
  friction_ = FrictionCone(params_.mu_s, params_.mu_k);
  tool_.validate("compound proxy: tool");
  reach_ = tool_.reach();
  largest_ = tool_.largest_semi_axis();
  min_axis_ = largest_;
  for (const ToolPart& p : tool_.view()) min_axis_ = std::min(min_axis_, p.semi_axes.minCoeff());
  for (ShadedNormalCache& sh : shades_) sh.set_turn_tolerance(params_.shading_turn * M_PI / 180);
}

void CompoundProxy::reset() noexcept {
  placed_ = false;
  undone_.active = false;
  release();
  for (ShadedNormalCache& sh : shades_) sh.reset();
  for (EdgeNormalCache& c : edges_) c.reset();
  n_blockers_ = 0;
  floaters_.reset();
}

int CompoundProxy::pose_parts(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept {
  const int n = tool_.count;
  if (!(q.coeffs() == posed_q_.coeffs())) {
    posed_q_ = q;
    for (int j = 0; j < n; ++j) {
      const ToolPart& part = tool_.parts[std::size_t(j)];
      turned_offset_[std::size_t(j)] = q * part.offset;
      turned_rotation_[std::size_t(j)] = q * part.rotation;
    }
  }
  for (int j = 0; j < n; ++j) {  // (as CompoundTool::posed computes them)
    ToolEllipsoid& e = parts_[std::size_t(j)];
    e.center = x + turned_offset_[std::size_t(j)];
    e.rotation = turned_rotation_[std::size_t(j)];
    e.semi_axes = tool_.parts[std::size_t(j)].semi_axes;
  }
  return n;
}

bool CompoundProxy::blocked(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation) noexcept {
  const int n = pose_parts(position, orientation);
  for (int j = 0; j < n; ++j)
    if (free_query_.any_contact(parts_[std::size_t(j)])) return true;
  return false;
}


void CompoundProxy::set_materials(std::shared_ptr<const MaterialField> field) {
  follower_ = field ? std::make_unique<MaterialFollower>(std::move(field), params_) : nullptr;
}

void CompoundProxy::release() noexcept {
  if (follower_) follower_->release();
  in_contact_ = false;
  coupling_.release();
  normal_.setZero();
  friction_.reset();
  last_constraints_ = 0;
  n_probe_slots_ = 0;
}

void CompoundProxy::place(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation) noexcept {
  ++placements_;
  release();
  placed_ = true;
  undone_.active = false;
  n_blockers_ = 0;
  x_ = position;
  q_ = orientation;
  if (!blocked(position, orientation)) return;
  Eigen::Vector3d dirs[14];
  int nd = 0;
  for (int a = 0; a < 3; ++a)
    for (double sg : {1.0, -1.0}) dirs[nd++] = Eigen::Vector3d::Unit(a) * sg;
  for (int k = 0; k < 8; ++k) dirs[nd++] = Eigen::Vector3d(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1).normalized();
  double best = INFINITY;
  for (int i = 0; i < nd; ++i)
    for (int step = 1; step <= 40; ++step) {
      const double dist = 0.25 * largest_ * step;
      if (dist >= best) break;
      if (!blocked(position + dirs[i] * dist, orientation)) {
        best = dist;
        x_ = position + dirs[i] * dist;
        break;
      }
    }
  if (!std::isfinite(best)) ++lost_;
}

bool CompoundProxy::turn_toward(const Eigen::Quaterniond& target) noexcept {  // true: contact stopped it
  const Eigen::AngleAxisd delta(target * q_.conjugate());
  double angle = delta.angle();
  Eigen::Vector3d axis = delta.axis();
  if (angle > M_PI) {  // the short way round
    angle = 2 * M_PI - angle;
    axis = -axis;
  }
  if (!(angle > 1e-12) || !axis.allFinite()) {
    q_ = target;
    return false;
  }
  // Each part's centre is swept along its chord; relative to that, no point of the part moves
  // more than rotation_step x the smallest semi-axis per sub-rotation: a delta + o delta^2 / 8
  // <= eta (the part's turn about its own centre, a its largest semi-axis, plus the arc's
  // departure from the chord, o its distance from the TCP).
  const double eta = params_.rotation_step * min_axis_;
  double step = INFINITY;
  for (const ToolPart& part : tool_.view()) {
    const double a = part.semi_axes.maxCoeff(), c = part.offset.norm() / 8;
    step = std::min(step, c > 0 ? (-a + std::sqrt(a * a + 4 * c * eta)) / (2 * c) : eta / a);
  }
  const int needed = int(std::ceil(angle / step));
  const int steps = std::min(needed, params_.max_rotation_steps);
  const Eigen::Quaterniond start = q_;
  FloaterRule::Filter floaters = floater_rule();
  const BlockFilter filter = floaters.block_filter();
  for (int k = 1; k <= steps; ++k) {
    const Eigen::Quaterniond next =
        (Eigen::Quaterniond(Eigen::AngleAxisd(angle * double(k) / double(needed), axis)) * start).normalized();
    const int n = pose_parts(x_, q_);
    for (int j = 0; j < n; ++j) {
      const ToolPart& part = tool_.parts[std::size_t(j)];
      const Eigen::Vector3d chord = (x_ + next * part.offset) - parts_[std::size_t(j)].center;
      if (chord.squaredNorm() == 0) continue;
      if (turn_sweep_.first_contact(parts_[std::size_t(j)], chord, {}, {}, filter).hit) return true;
    }
    if (blocked(x_, next)) return true;
    q_ = next;
  }
  return false;  // turned all the way, or out of sub-rotations this tick (the rest comes next tick)
}

int CompoundProxy::translate_toward(const Eigen::Vector3d& goal) noexcept {
  ConstraintPlane planes[3];
  int np = 0;
  std::uint32_t hints[3];
  std::size_t n_hints = 0;
  for (; n_hints < n_blockers_; ++n_hints) hints[n_hints] = blockers_[n_hints].slot;
  n_blockers_ = 0;
  Eigen::Vector3d p = x_;
  const double eps = ProxySolver::kStandOff * min_axis_;  // (the one-ellipsoid proxy's stand-off, on the thinnest part)
  int lifts = 0;
  WedgedState wedged;  // where it was wedged before its first step-up (proxy_solver.h)
  FloaterRule::Filter floaters = floater_rule();
  const BlockFilter filter = floaters.block_filter();
  const auto first_of_parts = [&](const Eigen::Vector3d& at, const Eigen::Vector3d& u, std::span<const std::uint32_t> h,
                                  int& part) {
    // All parts in one traversal, one sorted list and one bar (SweepQuery's compound sweep).
    // Near-ties within half the stand-off are not searched to the end (SweepQuery's tolerance).
    const int n = pose_parts(at, q_);
    const SweepHit best = sweep_.first_contact(std::span<const ToolEllipsoid>(parts_.data(), std::size_t(n)), u, {}, h,
                                               filter, 1.0, 0.5 * eps / u.norm());
    count_sweep();
    if (best.hit) part = best.part;
    return best;
  };
  for (int s = 0; s < params_.substeps; ++s) {
    const Eigen::Vector3d target = closest_feasible_point(goal, {planes, std::size_t(np)});
    const Eigen::Vector3d u = target - p;
    const double len = u.norm();
    // After a contact, a slide shorter than the sweeps' tolerance (half the stand-off) is not
    // swept: the proxy stays, within that of its goal (a resting tool's residual slide along a
    // tilted blocker would otherwise re-search every Gaussian it rests on for a few nanometres).
    if (len <= (np > 0 ? 0.5 * eps : 1e-9 * largest_)) break;
    int part = 0;
    const SweepHit hit = first_of_parts(p, u, {hints, n_hints}, part);
    if (!hit.hit) {
      p = target;
      if (np == 0) break;
      continue;
    }
    p += u * std::max(0.0, hit.t - eps / len);
    // Wedged: step up and slide on (not where the last step-up was undone, at the same pose,
    // while the goal is within a lift of its goal then: ProxySolver's rule).
    if (params_.lift > 0 && np >= 2 && hit.t * len < 1e-3 * largest_ && lifts < 2 &&
        !undone_.repeats(p, goal, eps, params_.lift * largest_, q_, reach_)) {
      Eigen::Vector3d up = hit.normal;
      for (int i = 0; i < np; ++i) up += planes[i].normal;
      if (up.norm() > 0) {
        const Eigen::Vector3d lift = up.normalized() * (params_.lift * largest_);
        int lp = 0;
        if (!first_of_parts(p, lift, {}, lp).hit) {
          if (lifts == 0) wedged.save(p, planes, np, n_blockers_, hit.normal, hit.slot, std::uint8_t(part));
          p += lift;
          np = 0;
          ++lifts;
          continue;
        }
      }
    }
    if (n_blockers_ < blockers_.size()) blockers_[n_blockers_++] = blocker_contact(*world_, hit.slot, std::uint8_t(part));
    if (np == 3) break;
    planes[np++] = {hit.normal, p};
  }
  if (lifts > 0 && (p - goal).squaredNorm() > (wedged.p - goal).squaredNorm()) {
    // The step-up did not bring the proxy nearer its goal: it stays wedged (WedgedState).
    p = wedged.p;
    np = wedged.restore(planes, n_blockers_);
    if (n_blockers_ < blockers_.size())
      blockers_[n_blockers_++] = blocker_contact(*world_, wedged.hit_slot, wedged.hit_part);
    undone_.remember(p, goal, q_);
  }
  x_ = p;
  return np;
}

Eigen::Vector3d CompoundProxy::part_normal(int j, const SweepHit& h, double spacing, const BlockFilter& filter) noexcept {
  const ToolEllipsoid& part = parts_[std::size_t(j)];
  Eigen::Vector3d nj = h.normal;
  const double rho = part.semi_axes.minCoeff();
  // The field's scale at this part (the kernel is shading_kernel times it): its smallest
  // semi-axis, or the Gaussians' spacing where they are sparser. The readings are kept over
  // shading_reuse times it, as the field is smooth at that scale: on the 8 mm cube the 5 mm
  // stylus's parts re-read every 0.4 mm, not 0.25 (their shaded and edge readings fall due on
  // the same tick, as the parts move together: those ticks were its slowest 1 %).
  const double scale = std::max(rho, spacing);
  const double reuse = params_.shading_reuse * scale;
  // Shaded (shaded_normal.h) at the centre of the sphere of the part's smallest semi-axis that
  // touches where the part touches: the field the one-ellipsoid proxy reads, at the part's own
  // contact (the Gaussian's own contact normal where the field disagrees with it). (The part
  // rests free: the floaters beside it that reach into it at the reading point were passed;
  // `up` is the part's contact normal. FreeBall.)
  const Eigen::Vector3d at = part.surface_point(-h.normal) + h.normal * rho;
  const Eigen::Vector3d& sn =
      shades_[std::size_t(j)].read(*world_, at, scale, params_.shading_kernel, reuse, shading_scratch_,
                                   {part.inner_clearance(at), h.normal}, 0, params_.shading_tail,
                                   params_.shading_visits);
  if (sn.dot(h.normal) > 0) nj = sn;
  // At a clean convex edge the shaded field blends the faces' normals; the tool resting on
  // the edge is pushed along the patch's support normal instead (edge_normal.h).
  // On a clean flat face, averaged with the face's mean thin axis where the two agree
  // (EdgeNormal::face_blend: both average the discs' tilts, the field over the few its kernel
  // weighs near the reading point, the axis over the whole patch; their mean is the quieter).
  const EdgeNormalAnswer patch =
      edge_.read(part, nj, kPatchBand * min_axis_, reuse, filter, edges_[std::size_t(j)],
                 params_.face_average ? ConvexFeatures::kEdgesAndFaces : ConvexFeatures::kEdges);
  return EdgeNormal::face_blend(EdgeNormal::blend(nj, patch, h.normal), patch, h.normal);
}

double CompoundProxy::touching_parts(const Eigen::Vector3d& spring, Eigen::Vector3d& normal,
                                     Eigen::Vector3d& moment) noexcept {
  // The parts that touch: each part within the contact band (half the smallest semi-axis) of a
  // Gaussian along the spring, weighted 1 - (gap / band)^2 (the Epanechnikov kernel: flat at
  // touch, so gaps of the Gaussians' jitter, small against the band, barely move a weight; the
  // linear 1 - gap / band moved the resultant of a stylus lying on the 8 mm plane by up to 15 %
  // of its lever). A rigid tool resting on a surface along a line (a stylus's side on a wall)
  // thus gets the resultant at the middle of the line, whatever the Gaussians' jitter. Each
  // touching part's contact point is its surface point facing its contact normal (part_normal).
  FloaterRule::Filter floaters = floater_rule();
  const BlockFilter filter = floaters.block_filter();
  const int count = pose_parts(x_, q_);
  const double band = kContactBand * min_axis_;
  const Eigen::Vector3d probe = -spring * band;
  moment.setZero();
  normal.setZero();
  double weight = 0;
  const std::span<const Contact> held_by = blockers();
  // The blockers are the likely first contacts of the probes too: tested first, they prune
  // the rest (the answer is the same exact search).
  // So are each part's first contacts along the last tick's probe (a resting part's again).
  std::uint32_t held_slots[3 + kMaxToolParts];
  std::size_t n_held = 0;
  for (const Contact& c : held_by) held_slots[n_held++] = c.slot;
  for (std::size_t i = 0; i < n_probe_slots_; ++i) {
    bool seen = false;
    for (std::size_t k = 0; k < n_held; ++k) seen = seen || held_slots[k] == probe_slots_[i];
    if (!seen) held_slots[n_held++] = probe_slots_[i];
  }
  const std::span<const std::uint32_t> hints{held_slots, n_held};
  // The Gaussian spacing under the tool (shading_spacing), read once for every part's scale.
  const double spacing = shading_spacing(*world_, held_by);
  // Each part's own first contact along the probe, all parts in one traversal, to within two
  // stand-offs (kProbeTolerance): a part's weight moves by at most that over the band. A part
  // resting on a Gaussian a stand-off away (the translation left it there) is then settled by
  // that hint, and its other candidates are not read (SweepQuery's settled parts).
  std::array<SweepHit, kMaxToolParts> probes;
  sweep_.first_contacts(std::span<const ToolEllipsoid>(parts_.data(), std::size_t(count)), probe, probes, hints,
                        filter, kProbeTolerance * ProxySolver::kStandOff * min_axis_ / band);
  count_sweep();
  n_probe_slots_ = 0;
  for (int j = 0; j < count; ++j)
    if (probes[std::size_t(j)].hit) probe_slots_[n_probe_slots_++] = probes[std::size_t(j)].slot;
  for (int j = 0; j < count; ++j) {
    const ToolEllipsoid& part = parts_[std::size_t(j)];
    const SweepHit& h = probes[std::size_t(j)];
    if (!h.hit) continue;
    // A part whose first contact lies inside another part is not touching with the tool's
    // surface: there the union's surface is the other part's, which meets the Gaussian sooner
    // (a stylus's part hanging beside the lip of an edge that its neighbour rests on: its own
    // contact point, its support point along the shaded normal, lay at its middle, 31 mm from
    // the lip). Its weight fades to nothing as that point sinks kHiddenRamp into the other part.
    double hidden = 0;
    const Eigen::Vector3d touch = part.surface_point(-h.normal);
    for (int k = 0; k < count; ++k)
      if (k != j) hidden = std::max(hidden, parts_[std::size_t(k)].inner_clearance(touch));
    const double w = std::max(1e-6, 1.0 - h.t * h.t) * std::clamp(1.0 - hidden / (kHiddenRamp * min_axis_), 0.0, 1.0);
    if (!(w > 0)) continue;
    const Eigen::Vector3d nj = part_normal(j, h, spacing, filter);
    moment += w * (part.surface_point(-nj) - x_);
    normal += w * nj;
    weight += w;
  }
  return weight;
}

Eigen::Vector3d CompoundProxy::turn_torque(const Eigen::Quaterniond& qd, const Eigen::Vector3d& angular_velocity,
                                           bool turn_stopped) const noexcept {
  const Eigen::AngleAxisd held(q_ * qd.conjugate());
  double angle = held.angle();
  Eigen::Vector3d axis = held.axis();
  if (angle > M_PI) {
    angle = 2 * M_PI - angle;
    axis = -axis;
  }
  // Only a turn that contact stopped is rendered (a turn that ran out of sub-rotations this
  // tick catches up on the next: free space stays free).
  if (turn_stopped && angle > 1e-9 && axis.allFinite())
    return params_.rot_stiffness * angle * axis - params_.rot_damping * angular_velocity;
  return Eigen::Vector3d::Zero();
}

RenderOutput CompoundProxy::render(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                                   const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                   double dt) noexcept {
  RenderOutput out;
  out.proxy = position;
  const bool finite = position.allFinite() && orientation.coeffs().allFinite() && orientation.norm() > 1e-9 &&
                      velocity.allFinite() && angular_velocity.allFinite() && dt > 0;
  if (!finite) {
    out.status = QueryStatus::kInvalidTool;
    return out;
  }
  const Eigen::Quaterniond qd = orientation.normalized();
  if (!placed_ || (position - last_device_).norm() > params_.teleport * reach_) place(position, qd);
  const Eigen::Vector3d device_step = position - last_device_;
  last_device_ = position;

  // 1. Turn toward the device's orientation, stopping at a contact.
  const bool turn_stopped = turn_toward(qd);
  // 2. Friction decides where the proxy heads (Salisbury et al. 1995): inside the cone it holds
  // still with its blockers; else it moves toward the goal, sliding on the blockers' planes.
  const FrictionStep fr = friction_.update(in_contact_, normal_, position, x_, device_step, reach_);
  const int np = fr.sticking && n_blockers_ > 0 ? last_constraints_ : translate_toward(fr.goal);
  last_constraints_ = np;
  out.proxy = x_;
  out.constraints = std::uint8_t(np);
  out.counts.contacts = std::uint32_t(n_blockers_);

  // 3. The wrench: the coupling in translation, applied at the touching parts' contacts, and in
  // rotation.
  const Eigen::Vector3d e = x_ - position;
  const double el = e.norm();
  if (el > 1e-6 * largest_ && n_blockers_ > 0) {
    const Eigen::Vector3d spring = e / el;
    Eigen::Vector3d normal, moment;
    const double weight = touching_parts(spring, normal, moment);
    Eigen::Vector3d n = normal.norm() > 0 ? Eigen::Vector3d(normal.normalized()) : spring;
    if (caught_in_pocket(n, e, [&] { return !blocked(position, qd); })) {
      place(position, qd);
      out.proxy = x_;
      out.constraints = 0;
      out.counts.contacts = 0;
      return out;
    }
    if (!(n.dot(e) > 0)) n = spring;
    // (With materials: those of the Gaussians holding the proxy, and the texture under the
    // touching parts' contact point.)
    const Eigen::Vector3d contact = weight > 0 ? Eigen::Vector3d(x_ + moment / weight) : Eigen::Vector3d(x_ - min_axis_ * n);
    if (follower_) {
      apply_blend(follower_->update(x_, n, min_axis_, contact, blockers()), coupling_, friction_);
    }
    out.force = coupling_.force_at_depth(coupling_.bounded_depth(e, n), e, n, velocity, dt, blockers(), fr,
                                         follower_ ? follower_->blend().mu_k : params_.mu_k);  // with friction
    if (follower_) {
      out.force = follower_->add_forces(*world_, out.force, texture_tip(contact, position, n), n, velocity, min_axis_,
                                        f_max_, dt);
      out.texture_rms = float(follower_->texture_rms());
      out.vibration = float(follower_->blend().vibration);
    }
    if (weight > 0) out.torque = (moment / weight).cross(out.force);
    in_contact_ = true;
    normal_ = n;
  } else {
    release();
  }
  out.torque += turn_torque(qd, angular_velocity, turn_stopped);
  return out;
}

}  // namespace gshaptics
