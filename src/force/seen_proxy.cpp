#include "gshaptics/force/seen_proxy.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace gshaptics {

SeenProxy::SeenProxy(const CollisionWorld& world, const ProxyParams& params, double f_max)
    : solid_(world), params_(params), coupling_(params, f_max), friction_(params.mu_s, params.mu_k) {}

void SeenProxy::reset() noexcept {
  started_ = false;
  contact_count_ = 0;
  in_contact_ = false;
  wall_.setZero();
  normal_.setZero();
  normal_trend_.setZero();
  fresh_normal_ = false;
  slide_mem_.setZero();
  edge_load_ = 0;
  kept_load_ = 0;
  lip_kept_ = std::numeric_limits<double>::infinity();
  edge_settle_ = 0;
  turn_left_ = 0;
  on_lip_ = false;
  coupling_.release();
  friction_.reset();
  friction_step_ = {};
  ring_read_.fill(SeenLineMemo{});
  free_eye_ = 0;
  forget_ledger();
  if (follower_) follower_->release();
}

void SeenProxy::forget_ledger() noexcept {
  ledger_.forget();
  deficit_ = 0;
}

Eigen::Vector3d SeenProxy::ring_offset(int k, const Eigen::Vector3d& u, double radius) const noexcept {
  // The sphere's shadow along u: the disc of its radius (ToolShadow's basis, L = radius I).
  ToolShadow shadow;
  shadow.e1 = u.unitOrthogonal();
  shadow.e2 = u.cross(shadow.e1);
  shadow.l = radius * Eigen::Matrix2d::Identity();
  return seen_footprint::ray_offset(shadow, k);
}

double SeenProxy::holding(const std::array<double, kRingRays>& support) noexcept {
  std::array<int, kRingRays> order{};
  for (int k = 0; k < kRingRays; ++k) order[std::size_t(k)] = k;
  std::sort(order.begin(), order.end(), [&](int a, int b) { return support[std::size_t(a)] < support[std::size_t(b)]; });
  unsigned mask = 0;
  for (int k : order) {
    if (!std::isfinite(support[std::size_t(k)])) break;
    mask |= 1u << k;
    // Around the circle (30 degrees a ray) no two neighbouring rays in the set lie 180 degrees
    // or more apart.
    int first = -1, prev = -1, widest = 0;
    for (int j = 0; j < kRingRays; ++j) {
      if (!(mask >> j & 1u)) continue;
      if (prev >= 0) widest = std::max(widest, j - prev);
      if (first < 0) first = j;
      prev = j;
    }
    widest = std::max(widest, first + kRingRays - prev);
    if (widest < kRingRays / 2) return support[std::size_t(k)];
  }
  return std::numeric_limits<double>::infinity();
}

double SeenProxy::ring_at(int k, const Eigen::Vector3d& centre, double radius) const noexcept {
  const Eigen::Vector3d moved = centre - ring_from_[std::size_t(k)];
  if ((moved - moved.dot(ring_axis_) * ring_axis_).norm() > kRingDrift * radius)
    return std::numeric_limits<double>::infinity();
  return ring_at_[std::size_t(k)];
}

double SeenProxy::ring_lead(int k, double radius) noexcept {
  const double rho = kRingRadius[k % 3] * radius;
  return std::sqrt(radius * radius - rho * rho);
}

double SeenProxy::free_ring(const Eigen::Vector3d& u, double radius, double len, bool leaving) noexcept {
  if (u.dot(ring_axis_) < kRingAxisCos) forget_ring(u);
  const int k = ring_next_;
  ring_next_ = (ring_next_ + 1) % kRingRays;
  // Seen from the sphere's surface there, or from as far behind it as it may have gone past a
  // rim since the ray was last read (the rays before it may have met the rim already), unless
  // the tool is leaving the surface it last rested on.
  const Eigen::Vector3d o = proxy_ + ring_offset(k, u, radius) + ring_lead(k, radius) * u;
  const double back = leaving ? 0.0 : -(kRingLook * radius + kRingRays * len);
  const SeenHit hit = solid_.first_inside(o, u, back, 0, len + kRingLook * radius, scratch_);
  ring_at_[std::size_t(k)] = hit.hit ? (o + hit.t * u).dot(ring_axis_) : std::numeric_limits<double>::infinity();
  ring_from_[std::size_t(k)] = proxy_;
  // How far each ray's point of the sphere is from its surface along the push.
  std::array<double, kRingRays> travel{};
  for (int j = 0; j < kRingRays; ++j)
    travel[std::size_t(j)] = ring_at(j, proxy_, radius) - proxy_.dot(ring_axis_) - ring_lead(j, radius);
  return holding(travel);
}

void SeenProxy::forget_ring(const Eigen::Vector3d& axis) noexcept {
  ring_at_.fill(std::numeric_limits<double>::infinity());
  ring_read_.fill(SeenLineMemo{});
  ring_axis_ = axis;
}

bool SeenProxy::begin_contact(const Eigen::Vector3d& device, double radius) noexcept {
  const Eigen::Vector3d d = device - proxy_;
  const double len = d.norm();
  if (!(len > 1e-9 * radius)) return false;
  return begin_contact_along(d / len, len, radius);
}

bool SeenProxy::begin_contact_along(const Eigen::Vector3d& u, double len, double radius) noexcept {
  // The eye: as far behind the proxy as it is still seen from (at most seen_window R), so a
  // surface behind it (the floor it lifted off) does not hold it, and a faint layer it is in does.
  double& eye = free_eye_;  // (in: the last free push's eye, push()'s guess; out: this one's)
  const bool leaving = u.dot(normal_) > 0;  // away from the surface it last rested on
  const SeenHit hit = solid_.push(proxy_, u, radius, params_.seen_window * radius, len, leaving, eye, scratch_);
  // With the footprint, one of its rays is read a tick, and rays around the sphere may hold it
  // before the leading point's ray does: the rim of a hole narrower than it, a groove's walls
  // (the 10 mm ball in the 60-degree groove: its leading point 10 mm short of the groove line).
  const bool footprint = params_.seen_footprint && !hit.hit;
  // A footprint found only after the sphere went past it by more than its rays' refresh allows
  // (a slanted wall met ray by ray) does not hold it: snapping the proxy back would start the
  // contact with a force step, and a step on the way in is energy given back on the way out.
  const double ring = footprint ? free_ring(u, radius, len, leaving) : std::numeric_limits<double>::infinity();
  const bool by_ring = ring <= len && ring >= -(kRingRays * len + seen_footprint::begin_lateness(len, radius, radius, kRingLate));
  if (!hit.hit && !by_ring) return false;
  // (The eye stands kEyeMargin R clear of the surface behind it: layers peaking at the eye
  // itself would count or not by rounding, and the surface behind would hold the tool.)
  const double back = radius + std::max(0.0, eye - kEyeMargin * radius);
  axis_ = u;
  eye_ = proxy_ + (radius - back) * u;
  // The contact's footprint starts from the readings that began it, or from none.
  if (!by_ring || u.dot(ring_axis_) < kRingAxisCos) forget_ring(u);
  ring_read_.fill(SeenLineMemo{});  // (searched afresh along this contact's axis and eye plane)
  // (Read afresh by hold(); until then the last contact's stays in normal_, which says whether
  // the tool is leaving a surface, should this contact fail at once.)
  fresh_normal_ = true;
  normal_reading_.forget();
  last_hit_ = std::numeric_limits<double>::quiet_NaN();
  sunk_ = 0;
  continued_ = false;
  entry_motion_ = len;
  axis_from_ = proxy_;
  forget_ledger();  // (a new contact's ledger starts empty)
  return true;
}

void SeenProxy::read_ring(const Eigen::Vector3d& device, const Eigen::Vector3d& foot, double radius,
                          double limit) noexcept {
  const int k = ring_next_;
  ring_next_ = (ring_next_ + 1) % kRingRays;
  const double reach = limit - (radius - ring_lead(k, radius));  // a surface deeper does not hold the sphere
  double& at = ring_at_[std::size_t(k)];
  ring_from_[std::size_t(k)] = device;
  if (!(reach > 0)) {
    at = std::numeric_limits<double>::infinity();
    return;
  }
  // Only a surface at or below the sphere's own point on this ray, where the proxy rests, matters
  // (one higher the sphere has gone past), seen from kRingLook R above that: a short ray,
  // whatever the eye plane's distance. (Searched from the proxy's point, not from R above the
  // device's: pressed more than R past a groove's walls, the device is deeper than any wall the
  // rays could meet there, and the ball sank with it.)
  const Eigen::Vector3d o = foot + ring_offset(k, axis_, radius);
  const double resting = (proxy_ + radius * axis_ - eye_).dot(axis_) - (radius - ring_lead(k, radius));
  const double from = std::max(0.0, std::min(reach, resting) - kRingLate * radius);
  const double eye = std::max(0.0, from - kRingLook * radius);
  SeenLineMemo& last = ring_read_[std::size_t(k)];
  double t = std::numeric_limits<double>::infinity();
  if (!last.reuse(o, axis_, eye, from, reach, kSameRay * radius, t)) {
    const SeenHit hit = solid_.first_inside(o, axis_, eye, from, reach, scratch_);
    t = hit.hit ? hit.t : std::numeric_limits<double>::infinity();
    last.keep(o, axis_, eye, from, reach, t);
  }
  at = std::isfinite(t) ? o.dot(axis_) + t : std::numeric_limits<double>::infinity();
}

double SeenProxy::ring_support(const Eigen::Vector3d& device, double radius) const noexcept {
  std::array<double, kRingRays> rest{};  // where each ray's surface holds the leading point, from the eye plane
  for (int k = 0; k < kRingRays; ++k)
    rest[std::size_t(k)] = ring_at(k, device, radius) - eye_.dot(axis_) + radius - ring_lead(k, radius);
  return holding(rest);
}

bool SeenProxy::hold(const Eigen::Vector3d& device, const Eigen::Vector3d& goal, double radius, double dt) noexcept {
  const Eigen::Vector3d& a = axis_;
  const double depth = (device + radius * a - eye_).dot(a);  // the device's leading point, from the eye plane
  const bool continued = std::exchange(continued_, false);
  deficit_ = 0;
  if (!(depth > 0)) return false;
  // The ray of the goal's leading point (the device's without friction, stopped by a wall across
  // the axis), from the eye plane.
  const Eigen::Vector3d across = slide_across(goal, radius);
  const Eigen::Vector3d foot = across + (radius - (across + radius * a - eye_).dot(a)) * a;
  // (The surface moves little from tick to tick: the layers up to just past the last hit are
  // read first, those deeper only when the surface is not among them.)
  const double guess = std::isfinite(last_hit_) ? last_hit_ + kGuessMargin * radius : depth;
  const SeenHit hit = solid_.first_inside(foot, a, 0, 0, depth, scratch_, guess);
  read_hit_layers(hit);
  // With the footprint, one of its rays is read a tick, and rays around the sphere hold it where
  // they do before the leading point's ray (a hole narrower than it, a groove's walls).
  if (params_.seen_footprint) read_ring(device, foot, radius, depth);
  const double footprint = params_.seen_footprint ? ring_support(device, radius) : std::numeric_limits<double>::infinity();
  const double rest = std::min(hit.hit ? hit.t : std::numeric_limits<double>::infinity(), footprint);
  // (A new contact's surface more than the tick's motion behind the leading point: the device was
  // already in it, seen along this axis, or a footprint ray met it late; the contact holds the
  // proxy that much deeper; sunk_.)
  if (fresh_normal_ && std::isfinite(rest) && !continued)
    sunk_ = std::max(0.0, depth - rest - (entry_motion_ + kSunkSlack * radius));
  if (continued) rest_ = (proxy_ + radius * a - eye_).dot(a);  // (its level along the new axis: climb() rises from it)
  // (A climb that the ledger asks to come toward the device stops short of it: the force then
  // ends, and the contact with it, only when the device itself leaves the surface.)
  const double climbed = std::min(climb(rest, across - proxy_ - (across - proxy_).dot(a) * a, radius, continued),
                                  std::max(rest, depth - sunk_ - 1e-6 * radius));
  const double held = climbed + sunk_;
  if (!(held < depth)) return false;  // the device is out of the surface
  // A rise of more than kMaxClimb R in one tick is no surface the sphere slides onto but the top
  // of a wall or an overhang that the ray over the goal met (a wall seen edge-on that the line
  // across did not see): the proxy stays where it stood, held by it across the axis.
  if (!fresh_normal_ && rest < rest_ - kMaxClimb * radius) {
    Eigen::Vector3d refused = across - proxy_;
    refused -= refused.dot(a) * a;
    const double len = refused.norm();
    if (len > 0) wall_ = -refused / len;
    return (proxy_ + radius * a - eye_).dot(a) < depth;
  }
  if (hit.hit) last_hit_ = hit.t;
  rest_ = climbed;
  deficit_ = std::isfinite(rest) ? std::max(0.0, climbed - rest) : 0.0;  // (a wall's top refused above owes nothing)
  under_ = hit.hit ? hit.t - climbed : std::numeric_limits<double>::infinity();
  const double t = std::max(0.0, held - 1e-6 * radius);
  const Eigen::Vector3d moved = foot + (t - radius) * a - proxy_;
  proxy_ += moved;
  read_normal(foot + rest * a, radius, rest);
  // Cradled by its footprint well above where its leading point's ray meets the surface (a
  // groove's walls, a hole's rim), the sphere is held by what lies under its side, beyond the
  // reach of the reading's rays around the floating leading point (pressed 28 mm past a groove's
  // walls, the force leaned 28 deg off its bisector). The rays that hold it surround its centre
  // line (holding()), so the cone of the sphere's own normals over them holds the push along the
  // contact's axis: a rigid cradle pushes back along it. Blended in from kCradleFrom to
  // kCradleFull R of float: a 60-degree groove floats the leading point 1 R, a 90-degree corner
  // 0.41 R, a hole's rim more; on a slope the rays that surround the centre line meet it no
  // earlier than the leading point's own ray (no float), and its seen normal stays.
  const double lift = (hit.hit ? hit.t : std::numeric_limits<double>::infinity()) - rest;
  const double w = std::clamp((lift - kCradleFrom * radius) / ((kCradleFull - kCradleFrom) * radius), 0.0, 1.0);
  if (w > 0) {
    const Eigen::Vector3d mixed = (1 - w) * target_normal_ - w * a;
    target_normal_ = mixed.norm() > 1e-9 ? Eigen::Vector3d(mixed.normalized()) : Eigen::Vector3d(-a);
  }
  if (fresh_normal_ || normal_.squaredNorm() == 0) {
    normal_ = target_normal_;
    normal_trend_.setZero();
    fresh_normal_ = false;
  }
  // The normal follows its readings over kNormalTau and over kNormalPath R of the proxy's slide,
  // whichever is slower: relief finer than the tool (a grating under a sphere) does not turn it.
  // A lag alone trails a steady turn (a dome) by the turn rate times its path; the smoothing
  // follows the turn's trend per slide too, learnt over kTrendPath R (Holt's linear trend, 1957).
  const double slide = (moved - moved.dot(a) * a).norm();
  // (A resting proxy's reading refined by the ring's turns, SeenNormalReading::settling, is the
  // same spot's: it is taken over kNormalTau alone.)
  const double by_time = -std::expm1(-dt / kNormalTau);
  const double rate =
      normal_reading_.settling() && slide < kSlideMin * radius ? by_time : std::min(by_time, -std::expm1(-slide / (kNormalPath * radius)));
  const Eigen::Vector3d predicted = normal_ + slide * normal_trend_;
  const Eigen::Vector3d blended = predicted + rate * (target_normal_ - predicted);
  const Eigen::Vector3d was = normal_;
  normal_ = blended.norm() > 1e-9 ? Eigen::Vector3d(blended.normalized()) : target_normal_;
  if (slide > 0) {
    const double follow = -std::expm1(-slide / (kTrendPath * radius));
    normal_trend_ += follow * ((normal_ - was) / slide - normal_trend_);
  }
  return true;
}

void SeenProxy::read_hit_layers(const SeenHit& hit) noexcept {
  // (A search that overflowed its scratch has no layers: no contacts, no material shares.)
  contact_count_ = solid_.hit_contacts(hit, scratch_, 0, contacts_);
  target_held_ = follower_ && hit.hit &&
                 follower_->field().weighted_shares([&](auto&& add) { solid_.visit_hit_layers(hit, scratch_, add); }, target_);
}

double SeenProxy::climb(double rest, const Eigen::Vector3d& slide, double radius, bool continued) const noexcept {
  // A rigid sphere rises onto a bump before its centre line reaches it, over the part of its
  // shadow the bump is in; the height field of its leading point (and its footprint's surround,
  // read one ray a tick) rises at once. The rise a tick is bounded by seen_footprint::
  // rise_allowance: the slope a sliding sphere climbs and the footprint's lateness spread over one
  // turn of its rays, so a rise the sphere's own slide does not explain comes as a ramp, not a
  // force step. A new contact starts where its surface is; the proxy never
  // sinks below the surface it rested on. Under load it rises only as far as the rise is paid for
  // (ClimbLedger::rise_room); what is left is deficit_, which the ledger's reaction charges.
  if ((fresh_normal_ && !continued) || !std::isfinite(rest) || !std::isfinite(rest_)) return rest;
  const double most = std::min(seen_footprint::rise_allowance(slide.norm(), radius), ledger_.rise_room(slide, normal_, axis_));
  return std::max(rest, rest_ - most);
}

bool SeenProxy::restart_along(const Eigen::Vector3d& u, double len, const Eigen::Vector3d& device,
                              const Eigen::Vector3d& device_step, double radius, double dt, bool continued) noexcept {
  const ClimbLedger kept = ledger_;
  if (!(len > 1e-9 * radius) || !begin_contact_along(u, len, radius)) return false;
  if (continued) ledger_ = kept;  // (the same surface: what its climb has paid and owes carries on)
  continued_ = continued;
  friction_.reset();
  friction_step_ = friction_.update(false, Eigen::Vector3d::Zero(), device, proxy_, device_step, radius);
  in_contact_ = hold(device, friction_step_.goal, radius, dt);
  return true;
}

void SeenProxy::follow_surface(const Eigen::Vector3d& device, const Eigen::Vector3d& before,
                               const Eigen::Vector3d& device_step, double radius, double dt) noexcept {
  // The contact is a height field along its axis, and the sphere rests where its leading point's
  // ray meets the surface. On a surface sloped theta to the axis, a rigid sphere touches at its
  // tangent point (R sin theta across from its centre line) and rests R (1 / cos theta - 1) higher:
  // sliding over a dome the proxy sank into the far side and the force faded to nothing
  // (bench/RESULTS.md, eightieth session). Once the smoothed normal has turned kFollowAngle from
  // the axis while the proxy slides across it, the contact begins again along the normal from
  // where the proxy stands (begin_contact_along: its eye, footprint and ledger afresh), so the
  // sink stays under R (1 / cos kFollowAngle - 1). A proxy that does not slide keeps its axis: a
  // press at a crease, whose normal lies in its cone rather than along the push, is no slope, and
  // one that has slid less than kFollowPath R since its axis was set keeps it too (a rough
  // capture's normal wanders a few degrees under a resting sphere).
  const Eigen::Vector3d step = proxy_ - before, path = proxy_ - axis_from_;
  const double slid = (step - step.dot(axis_) * axis_).norm(), far = (path - path.dot(axis_) * axis_).norm();
  if (fresh_normal_ || !(normal_.squaredNorm() > 0) || !(-normal_.dot(axis_) < std::cos(kFollowAngle)) ||
      !(slid > kFollowSlide * radius) || !(far > kFollowPath * radius))
    return;
  const Eigen::Vector3d into = -normal_, axis = axis_, normal = normal_, trend = normal_trend_;
  const double len = (device - proxy_).dot(into);
  if (!(len > 1e-9 * radius)) return;
  if (!restart_along(into, len, device, device_step, radius, dt, /*continued=*/true)) {
    if (ring_axis_.dot(axis) < kRingAxisCos) forget_ring(axis);  // (the tried push read its ring along `into`)
    return;
  }
  normal_ = normal;  // (the force keeps its smoothed direction; the new readings turn it from there)
  normal_trend_ = trend;
}

Eigen::Vector3d SeenProxy::slide_direction(double radius) const noexcept {
  const Eigen::Vector3d s = slide_mem_ - slide_mem_.dot(axis_) * axis_;
  return s.norm() > kEdgeSlideMin * radius ? Eigen::Vector3d(s.normalized()) : Eigen::Vector3d::Zero();
}

bool SeenProxy::sank_through_lip(double radius) const noexcept {
  return kept_lip(radius) && (proxy_ - kept_point_).norm() < (1 - kEdgeLoad) * radius;
}

bool SeenProxy::kept_lip(double radius) const noexcept {
  return lip_kept_ > 0 && lip_kept_ < kLipKeep * radius && kept_load_ > kEdgeLoad * radius;
}

bool SeenProxy::begin_lip(const Eigen::Vector3d& device, const Eigen::Vector3d& point, double radius, double rested) noexcept {
  // Where the face it slid on ends under load (the contact's last point, edge_point_), with the
  // device gone on past it along the slide, or short of it by less than kLipBehind R, the ball
  // rolls over that point.
  const Eigen::Vector3d s = slide_direction(radius);
  if (s.squaredNorm() == 0) return false;
  const Eigen::Vector3d d = device - point;
  if (!(d.norm() < radius) || !(d.dot(s) > -kLipBehind * radius)) return false;
  // (No deeper on the lip than it rested last tick, give or take kLipSlack R: a lip that would
  // push harder than the contact did is no roll but a kick, a step from 0.2 to 1.9 N on one of
  // firepit's probe-run releases.)
  if (!(radius - d.norm() < rested + kLipSlack * radius)) return false;
  lip_ = point;
  lip_out_ = s;
  on_lip_ = true;
  in_contact_ = false;
  forget_ledger();
  wall_.setZero();
  read_lip_layers(radius);
  return true;
}

void SeenProxy::read_lip_layers(double radius) noexcept {
  // The layers that make the face at the lip, seen along the contact's axis just back from it
  // on the face: the touched Gaussians while the ball rolls over it, and the material there (the
  // coupling, the friction's coefficients and the follower carry on from the face).
  const Eigen::Vector3d foot = lip_ - kLipLook * radius * lip_out_ - radius * axis_;
  read_hit_layers(solid_.first_inside(foot, axis_, 0, 0, 2 * radius, scratch_));
  lip_contacts_ = contact_count_;
  under_ = 0;  // (a point under the ball: no relief below it for the texture tip)
}

bool SeenProxy::roll_over_lip(const Eigen::Vector3d& device, const Eigen::Vector3d& device_step, double radius,
                              double dt) noexcept {
  // A ball on a point: it rests R from it, along the line from it to the device, while the
  // device is within R of it and on past it along the slide (back over the face it came from,
  // the face holds it again: a new contact). A face beyond that the ball is less deep past takes
  // the contact (turn_over_edge).
  const Eigen::Vector3d d = device - lip_;
  const double dist = d.norm();
  on_lip_ = dist < radius && dist > 0 && d.dot(lip_out_) > -kLipBehind * radius;
  if (!on_lip_) {
    slide_mem_.setZero();
    edge_load_ = 0;
    if (dist > 0) proxy_ = lip_ + std::max(dist, radius) * (d / dist);  // (free: the next push starts here)
    return false;
  }
  if (!turn_over_edge(device, device_step, radius, dt, radius - dist) && !land_from_lip(device, device_step, radius, dt))
    return false;
  on_lip_ = false;
  return true;
}

bool SeenProxy::land_from_lip(const Eigen::Vector3d& device, const Eigen::Vector3d& device_step, double radius,
                              double dt) noexcept {
  const SeenHit hit = solid_.first_inside(proxy_, axis_, 0, 0, radius, scratch_);
  if (!hit.hit || scratch_.overflow) return false;
  // A face across the axis (its seen normal within 30 degrees of it), not the discs of a face
  // along it met edge-on (a crisp cube's side below the lip).
  if (!face_agrees(proxy_ + hit.t * axis_, axis_, hit.t, -axis_, radius)) return false;
  const Eigen::Vector3d axis = axis_, normal = normal_;
  if (!restart_along(axis, (device - proxy_).dot(axis), device, device_step, radius, dt) || !in_contact_) {
    if (ring_axis_.dot(axis) < kRingAxisCos) forget_ring(axis);
    in_contact_ = false;
    return false;
  }
  normal_ = normal;  // (the force keeps the lip's direction; the floor's readings turn it from there)
  normal_trend_.setZero();
  lip_kept_ = std::numeric_limits<double>::infinity();
  return true;
}

bool SeenProxy::face_agrees(const Eigen::Vector3d& at, const Eigen::Vector3d& u, double t, const Eigen::Vector3d& m,
                            double radius) noexcept {
  const double h = solid_.normal_ring(radius);
  return solid_.normal(at, u, h, h, t, scratch_).dot(m) > kEdgeAgree;
}

RenderOutput SeenProxy::lip_output(const Eigen::Vector3d& device, const Eigen::Vector3d& device_step,
                                   const Eigen::Vector3d& velocity, double radius, double dt) noexcept {
  // A sphere on a point: the proxy on the sphere of radius R round the lip, where the friction
  // cone about its normal there puts it (the device's side without friction; trailing it as on
  // the face while sliding, so the face's friction carries on over the lip), with the coupling
  // along that normal and the face's material.
  friction_step_ = friction_.update(true, normal_, device, proxy_, device_step, radius);
  const Eigen::Vector3d to = friction_step_.goal - lip_;
  if (to.norm() > 1e-9 * radius) proxy_ = lip_ + radius * to.normalized();
  normal_ = (proxy_ - lip_) / radius;
  contact_count_ = lip_contacts_;
  const double mu_k = apply_material(lip_, radius);
  const Eigen::Vector3d f = coupling_.clamp(coupling_.force(proxy_ - device, normal_, velocity, dt, {}, friction_step_, mu_k));
  return contact_output(f, lip_, velocity, radius, dt);
}

void SeenProxy::track_slide(const Eigen::Vector3d& before, double radius, double load) noexcept {
  Eigen::Vector3d step = proxy_ - before;
  step -= step.dot(axis_) * axis_;
  slide_mem_ = std::exp(-step.norm() / (kEdgeSlidePath * radius)) * slide_mem_ + step;
  edge_settle_ = std::max(0.0, edge_settle_ - step.norm());
  // The point it rested on under load is kept through kLipKeep R of slide under less (the
  // height field sinking off a rounded edge, or onto the discs of the face beyond seen edge-on),
  // so a contact that ends there still rolls over the face's end.
  edge_load_ = load;
  edge_point_ = proxy_ - radius * normal_;
  lip_kept_ += step.norm();
  if (load > kEdgeLoad * radius || !(lip_kept_ < kLipKeep * radius)) {
    kept_load_ = load;
    kept_point_ = edge_point_;
    lip_kept_ = 0;
  }
}

bool SeenProxy::edge_ahead(double radius) const noexcept {
  // The footprint's rays ahead along the slide (one read a tick) that met no surface where the
  // sphere could rest on it, or met it kEdgeDrop R deeper than where the proxy rests: the face
  // ends or falls away within R ahead. Without the footprint, always. Not within kEdgeSettle R
  // of slide after a turn.
  const Eigen::Vector3d s = slide_direction(radius);
  if (s.squaredNorm() == 0 || edge_settle_ > 0) return false;
  if (!params_.seen_footprint) return true;
  for (int k = 0; k < kRingRays; ++k) {
    if (!ring_read_[std::size_t(k)].valid || !(ring_offset(k, axis_, radius).dot(s) > 0)) continue;
    const double at = ring_at_[std::size_t(k)];
    if (!std::isfinite(at) || at - eye_.dot(axis_) + radius - ring_lead(k, radius) > rest_ + kEdgeDrop * radius)
      return true;
  }
  return false;
}

bool SeenProxy::turn_over_edge(const Eigen::Vector3d& device, const Eigen::Vector3d& device_step, double radius,
                               double dt, double load) noexcept {
  // A contact is a height field along its axis; past a convex edge the face beyond is seen
  // edge-on along it, so the proxy either holds the device on the first face's lip or, where
  // that face's discs end, loses the surface (bench/RESULTS.md, eighty-sixth session). A rigid
  // ball rolls over the edge onto the face nearer its centre: for a convex solid the depth a
  // ball is in is the least of its depths past each face's plane. Looking back along the slide
  // from the device's centre, a face that faces the slide and that the ball is less
  // deep past than past the face under it (by kEdgeMargin R), or one the ball is past at all
  // when the contact has just ended under load, takes the contact: it begins along that face's
  // inward normal from just outside it.
  const Eigen::Vector3d s = slide_direction(radius);
  if (s.squaredNorm() == 0) return false;
  // Seen from the device's centre along -s: a face that makes the ball less deep than `load`
  // lies between the centre and the leading point, past R - load + kEdgeMargin R (its depth is
  // R - t (s . m)); one already there at that point is no face beyond but one the centre is in.
  const Eigen::Vector3d& eye = device;
  const Eigen::Vector3d u = -s;
  const double from = std::clamp(radius - load + kEdgeMargin * radius, 0.0, radius);
  const SeenHit hit = solid_.first_inside(eye, u, 0, from, radius, scratch_);
  if (!hit.hit || scratch_.overflow || !(hit.t > from)) return false;
  Eigen::Vector3d m = solid_.shade(u, hit, scratch_);
  if (!(m.norm() > 0)) return false;
  m.normalize();
  if (!(m.dot(s) > kEdgeFacing)) return false;
  const Eigen::Vector3d at = eye + hit.t * u;
  const double depth = radius - (device - at).dot(m);
  if (!(depth > 0) || !(depth < load - kEdgeMargin * radius)) return false;
  // A face: its seen normal over the reading's ring faces the slide as its shade does (not one
  // disc met edge-on at the device's height).
  if (!face_agrees(at, u, hit.t, m, radius)) return false;
  // The ball gets there without going through the seen solid: the line from where the proxy
  // stands to where the new contact begins is clear (not a wall's far side, met after the device
  // went through it).
  const double gap = kEdgeGap * radius;
  const Eigen::Vector3d start = device + (depth + gap) * m, path = start - proxy_;
  const double far = path.norm();
  if (far > 0 && (solid_.first_inside(proxy_, path / far, 0, 0, far, scratch_).hit || scratch_.overflow)) return false;
  const Eigen::Vector3d was = proxy_;
  proxy_ = start;
  if (!restart_along(-m, depth + gap, device, device_step, radius, dt)) {
    proxy_ = was;
    return false;
  }
  begin_turn_blend(was, device, radius);
  slide_mem_.setZero();
  edge_load_ = in_contact_ ? depth : 0;
  lip_kept_ = std::numeric_limits<double>::infinity();  // (the next tick's point is the new face's)
  edge_settle_ = kEdgeSettle * radius;
  return true;
}

void SeenProxy::begin_turn_blend(const Eigen::Vector3d& was, const Eigen::Vector3d& device, double radius) noexcept {
  // The ball before the turn: centred at `was`, pushing the device along was - device. Within R
  // of the device it rests on the point R from `was` through the device (the pivot: a ball on a
  // point pushes exactly so), and rolls over it as the device moves on; deeper, it stays
  // where it was.
  const Eigen::Vector3d e = was - device;
  const double depth = e.norm();
  turn_from_ = was;
  turn_on_pivot_ = depth > 1e-9 * radius && depth < radius;
  if (turn_on_pivot_) turn_pivot_ = was - radius * (e / depth);
  turn_left_ = kTurnBlend * radius;
}

Eigen::Vector3d SeenProxy::blend_turn(const Eigen::Vector3d& f, const Eigen::Vector3d& device,
                                      const Eigen::Vector3d& velocity, double step, double radius, double dt) noexcept {
  const double w = 1 - turn_left_ / (kTurnBlend * radius);
  turn_left_ = std::max(0.0, turn_left_ - step);
  Eigen::Vector3d before = turn_from_ - device;
  if (turn_on_pivot_) {
    const Eigen::Vector3d d = device - turn_pivot_;
    const double dist = d.norm();
    before = dist > 1e-9 * radius ? Eigen::Vector3d(std::max(0.0, radius - dist) / dist * d) : Eigen::Vector3d::Zero();
  }
  const double depth = before.norm();
  const Eigen::Vector3d f_before =
      depth > 0 ? coupling_.force(before, before / depth, velocity, dt, {}, FrictionStep{}, 0.0) : Eigen::Vector3d::Zero();
  return coupling_.clamp((1 - w) * f_before + w * f);
}

Eigen::Vector3d SeenProxy::slide_across(const Eigen::Vector3d& goal, double radius) noexcept {
  const Eigen::Vector3d& a = axis_;
  Eigen::Vector3d step = goal - proxy_;
  step -= step.dot(a) * a;
  // Each line is seen from the proxy's centre and searched from kWallDepth R inside the sphere's
  // leading point: the wall the proxy was held against last tick may lie a little inside it now
  // (the height field moved the proxy along the axis, and a tilted disc's crossing moves with
  // the height). A surface that the line already crosses deeper inside the sphere (a slope the
  // height field climbs, the footprint's groove walls) does not stop it.
  const double lead = (1 - kWallDepth) * radius, stop = (kWallDepth + kWallGap) * radius;
  const WallSlide slide = slide_along_walls(
      step, kSlideMin * radius, seen_footprint::kMaxSlide * radius, [&](const Eigen::Vector3d& u, const Eigen::Vector3d& moved, double len, Eigen::Vector3d& wall) {
        const SeenHit hit = solid_.first_inside(proxy_ + moved, u, 0, lead, lead + len + stop, scratch_);
        // (Kept kWallGap R short of the wall, so the next tick's line meets it ahead of the
        // leading point, not at it, where rounding would put it behind; < 0: backs out of the wall.)
        if (!hit.hit || !(hit.t > lead) || scratch_.overflow) return std::numeric_limits<double>::infinity();
        wall = solid_.wall_normal(u, a, hit, scratch_);
        return hit.t - lead - stop;
      });
  wall_ = slide.wall;
  const Eigen::Vector3d off = proxy_ + slide.moved - goal;
  return goal + off - off.dot(a) * a;
}

void SeenProxy::read_normal(const Eigen::Vector3d& point, double radius, double depth) noexcept {
  // Read afresh once the point moved kNormalReuse R from the last reading (SeenNormalReading), and
  // smoothed by hold() over kNormalTau (each reading carries the seen surface's noise). The ring's
  // rays search as deep as the ring is wide (SeenSolid::kNormalSpan >= 1: slopes to 45 deg).
  const double h = solid_.normal_ring(radius), back = std::min(depth, kNormalEye * radius);
  target_normal_ = normal_reading_.update(solid_, point, axis_, h, back, kNormalReuse * radius, scratch_);
}

double SeenProxy::apply_material(const Eigen::Vector3d& contact, double radius) noexcept {
  if (!follower_) return params_.mu_k;
  apply_blend(follower_->follow(proxy_, normal_, radius, contact, target_held_ ? &target_ : nullptr), coupling_, friction_);
  return follower_->blend().mu_k;
}

RenderOutput SeenProxy::contact_output(const Eigen::Vector3d& f, const Eigen::Vector3d& contact,
                                       const Eigen::Vector3d& velocity, double radius, double dt) noexcept {
  RenderOutput out;
  out.proxy = proxy_;
  out.constraints = 1;
  out.force = f;
  out.counts.contacts = std::max<std::uint32_t>(1, std::uint32_t(contact_count_));
  if (!follower_) return out;
  // The texture tip hangs from where the proxy rests down to the seen surface under the leading
  // point (a point tip under the sphere): the relief the proxy does not render itself. Where the
  // leading point's ray holds the proxy, the proxy rides that relief and the tip adds none; held
  // by its footprint over a valley or a hole (a sphere bridging a grating's crests), the tip reads
  // how deep it is, as the ellipsoid proxy's tip reads under a sphere riding at its own scale;
  // kept below a crest it has not paid to climb (SeenProxy::climb), the tip reads how high it is.
  // (As first built the tip was the proxy's own height, so the relief was rendered twice: the
  // gratings' peak was 2 k A where the ellipsoids give k A; bench/RESULTS.md, sixty-first session.)
  const double tip = -std::clamp(under_, -radius, radius);
  out.force = follower_->add_forces_at_tip(tip, f, contact, normal_, velocity, radius, coupling_.f_max(), dt);
  out.texture_rms = float(follower_->texture_rms());
  out.vibration = float(follower_->blend().vibration);
  return out;
}

bool SeenProxy::at_edge(const Eigen::Vector3d& device, const Eigen::Vector3d& before, const Eigen::Vector3d& device_step,
                        double r, double dt, bool was_in_contact) noexcept {
  if (in_contact_) {
    const double load = (proxy_ - device).dot(normal_);
    const bool look = edge_ahead(r);
    if (look && turn_over_edge(device, device_step, r, dt, load)) return false;
    if (look) edge_settle_ = kEdgeLookStride * r;  // (the next look after this much more slide)
    const double rested = edge_load_;  // (the load it rested under last tick)
    track_slide(before, r, load);
    return sank_through_lip(r) && begin_lip(device, kept_point_, r, rested);
  }
  if (!was_in_contact) return false;
  if (edge_load_ > kEdgeLoad * r)  // (ended under load)
    return !turn_over_edge(device, device_step, r, dt, std::numeric_limits<double>::infinity()) &&
           begin_lip(device, edge_point_, r, std::numeric_limits<double>::infinity());
  return kept_lip(r) && begin_lip(device, kept_point_, r, edge_load_);  // (it sank off the face, and the load faded)
}

RenderOutput SeenProxy::render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept {
  RenderOutput out;
  out.proxy = tool.center;
  contact_count_ = 0;
  if (!tool.valid() || !velocity.allFinite() || !(dt > 0)) {
    out.status = QueryStatus::kInvalidTool;
    return out;
  }
  const double r = tool.bounding_radius();
  if (!started_) {
    proxy_ = last_device_ = tool.center;
    started_ = true;
  }
  const Eigen::Vector3d device_step = tool.center - last_device_;
  const Eigen::Vector3d before = proxy_;
  if (in_contact_) ledger_.pay(device_step);  // (before the climb asks what is paid for)
  last_device_ = tool.center;
  // A contact lasts while the device's leading point is past the seen surface along the axis it
  // came in on: the proxy rests on that surface (a height field along the axis) above the device,
  // or above where the friction cone holds it.
  const bool was_in_contact = in_contact_;
  // Rolling over the lip where a face it slid on ended (roll_over_lip): a face beyond may take
  // the contact (handed: it is held already this tick).
  const bool handed = on_lip_ && roll_over_lip(tool.center, device_step, r, dt);
  if (on_lip_) return lip_output(tool.center, device_step, velocity, r, dt);
  if (!in_contact_) {
    turn_left_ = 0;  // (a blend after a turn ends with its contact, on a lip too)
    in_contact_ = begin_contact(tool.center, r);
  }
  if (in_contact_ && !handed) {
    const Eigen::Vector3d held = fresh_normal_ ? Eigen::Vector3d::Zero() : normal_;  // (none yet in a new contact)
    friction_step_ = friction_.update(was_in_contact, held, tool.center, proxy_, device_step, r);
    in_contact_ = hold(tool.center, friction_step_.goal, r, dt);
    // Out of the surface along this contact's axis while a wall across it held the proxy (the
    // device came up along the wall): a contact along the wall's inward normal begins from where
    // the proxy stands, not from the device inside the wall (a push toward the device, up and
    // barely into the wall, would miss it with the sphere's leading point).
    if (!in_contact_ && wall_.squaredNorm() > 0) {
      const Eigen::Vector3d into = -wall_;
      wall_.setZero();
      (void)restart_along(into, (tool.center - proxy_).dot(into), tool.center, device_step, r, dt);  // (sets in_contact_)
    }
  }
  if (in_contact_) follow_surface(tool.center, before, device_step, r, dt);
  if (at_edge(tool.center, before, device_step, r, dt, was_in_contact))
    return lip_output(tool.center, device_step, velocity, r, dt);
  if (!in_contact_) {
    slide_mem_.setZero();
    turn_left_ = 0;
    edge_load_ = 0;
    edge_settle_ = 0;
    contact_count_ = 0;  // (a search that ended the contact may have read its layers)
    forget_ledger();
    proxy_ = tool.center;
    wall_.setZero();
    coupling_.release();
    friction_.reset();
    if (follower_) follower_->release();
    return out;
  }
  const Eigen::Vector3d e = proxy_ - tool.center;
  const Eigen::Vector3d contact = proxy_ - r * normal_;  // where the tool meets the surface
  const double mu_k = apply_material(contact, r);
  Eigen::Vector3d f = coupling_.force(e, normal_, velocity, dt, {}, friction_step_, mu_k);
  // The proxy's own step against the coupling, and the hand's payment for a rise still owed.
  ledger_.book(proxy_ - before, f, normal_, r);
  f = coupling_.clamp(f + ledger_.reaction(deficit_, velocity, normal_, r, dt));
  if (wall_.squaredNorm() > 0) f = coupling_.add_wall(f, wall_, normal_, e, velocity, dt);
  if (turn_left_ > 0) f = blend_turn(f, tool.center, velocity, device_step.norm(), r, dt);
  return contact_output(f, contact, velocity, r, dt);
}

}  // namespace gshaptics
