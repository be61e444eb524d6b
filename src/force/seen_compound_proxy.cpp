#include "gshaptics/force/seen_compound_proxy.h"

#include "gshaptics/collision/ellipsoid_line.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace gshaptics {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The middle of a part's three semi-axes (a stylus segment's radius, a disc's radius).
double middle_semi_axis(const Eigen::Vector3d& semi_axes) noexcept {
  Eigen::Vector3d s = semi_axes;
  std::sort(s.data(), s.data() + 3);
  return s[1];
}

// The n-th point of the R2 sequence (Roberts 2018: an additive recurrence by the plastic number's
// powers) mapped onto the unit disc by area: low-discrepancy, so the first points of any run
// spread over the whole disc.
Eigen::Vector2d r2_disc(std::uint32_t n) noexcept {
  constexpr double kA1 = 0.7548776662466927, kA2 = 0.5698402909980532;  // 1/p, 1/p^2
  const double u1 = std::fmod(0.5 + kA1 * n, 1.0), u2 = std::fmod(0.5 + kA2 * n, 1.0);
  const double rho = std::sqrt(u1), angle = 2 * std::numbers::pi * u2;
  return {rho * std::cos(angle), rho * std::sin(angle)};
}

// The part's outward surface normal at its surface point x (unit).
Eigen::Vector3d outward_normal(const ToolEllipsoid& part, const Eigen::Vector3d& x) noexcept {
  const Eigen::Matrix3d r = part.rotation.toRotationMatrix();
  const Eigen::Vector3d local = (r.transpose() * (x - part.center)).cwiseQuotient(part.semi_axes.cwiseAbs2());
  return (r * local).normalized();
}

}  // namespace

SeenCompoundProxy::SeenCompoundProxy(const SeenSolid& solid, const CompoundTool& tool, const ProxyParams& params,
                                     double f_max)
    : solid_(&solid),
      tool_(tool),
      params_(params),
      coupling_(params, f_max),
      friction_(params.mu_s, params.mu_k) {
  tool_.validate("seen proxy: tool");
  radius_ = tool_.largest_semi_axis();
  min_axis_ = kInf;
  for (int j = 0; j < tool_.count; ++j) {
    min_axis_ = std::min(min_axis_, tool_.parts[std::size_t(j)].semi_axes.minCoeff());
    middle_[std::size_t(j)] = middle_semi_axis(tool_.parts[std::size_t(j)].semi_axes);
    reach_ = std::max(reach_, tool_.parts[std::size_t(j)].offset.norm() + tool_.parts[std::size_t(j)].semi_axes.maxCoeff());
  }
  reset();
}

void SeenCompoundProxy::reset() noexcept {
  started_ = false;
  release();
  normal_.setZero();
  fresh_normal_ = false;
  free_eye_.fill(0);
  for (int j = 0; j < tool_.count; ++j) forget_ring(j, Eigen::Vector3d::Zero());
}

void SeenCompoundProxy::release() noexcept {
  in_contact_ = false;
  wall_.setZero();
  touching_ = 0;
  coupling_.release();
  friction_.reset();
  friction_step_ = {};
  held_.fill(Hold{});
  weight_.fill(0);
  for (SeenLineMemo& m : leading_) m.forget();
  part_layer_count_.fill(0);
  contact_count_ = 0;
  part_held_.fill(false);
  ledger_.forget();
  deficit_ = 0;
  if (follower_) follower_->release();
}

void SeenCompoundProxy::set_materials(std::shared_ptr<const MaterialField> field) {
  follower_ = field ? std::make_unique<MaterialFollower>(std::move(field), params_) : nullptr;
  part_held_.fill(false);
}

void SeenCompoundProxy::read_part_shares(int j, const SeenHit& hit) noexcept {
  const std::size_t k = std::size_t(j);
  part_held_[k] = hit.hit && follower_->field().weighted_shares(
                                 [&](auto&& add) { solid_->visit_hit_layers(hit, scratch_, add); }, part_shares_[k]);
}

void SeenCompoundProxy::apply_material(const Eigen::Vector3d& contact_point) noexcept {
  // The touching parts' shares by their contact weights (SeenProxy reads its one leading point's).
  const std::size_t count = follower_->field().material_count();
  double sum = 0;
  for (int j = 0; j < tool_.count; ++j) {
    const std::size_t k = std::size_t(j);
    if (!(weight_[k] > 0) || !part_held_[k]) continue;
    if (!(sum > 0)) std::fill(target_shares_.begin(), target_shares_.begin() + std::ptrdiff_t(count), 0.0);
    for (std::size_t id = 0; id < count; ++id) target_shares_[id] += weight_[k] * part_shares_[k][id];
    sum += weight_[k];
  }
  if (sum > 0)
    for (std::size_t id = 0; id < count; ++id) target_shares_[id] /= sum;
  apply_blend(follower_->follow(x_, normal_, min_axis_, contact_point, sum > 0 ? &target_shares_ : nullptr), coupling_, friction_);
}

void SeenCompoundProxy::pose(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept {
  tool_.posed(x, q, std::span<ToolEllipsoid>(parts_.data(), std::size_t(tool_.count)));
}

void SeenCompoundProxy::forget_ring(int j, const Eigen::Vector3d& axis) noexcept {
  Ring& g = rings_[std::size_t(j)];
  g.axis = axis;
  g.at.fill(kInf);
  g.eye.fill(0);
  g.stamp.fill(0);
  for (SeenLineMemo& m : g.memo) m.forget();
  for (EdgeSearch& e : edges_[std::size_t(j)]) e = EdgeSearch{};
}

double SeenCompoundProxy::ring_gap(const ExitAlong& exit, int j, int k, const Eigen::Vector3d& axis,
                                   Eigen::Vector3d& front) const noexcept {
  const Ring& g = rings_[std::size_t(j)];
  if (!(g.axis.dot(axis) >= kRingAxisCos) || !std::isfinite(g.at[std::size_t(k)])) return kInf;
  const Eigen::Vector3d& p = g.foot[std::size_t(k)];
  const double t = exit(p);
  if (std::isnan(t)) return kInf;  // the line is no longer under the part
  front = p + t * g.axis;
  return g.at[std::size_t(k)] - front.dot(g.axis);
}

double SeenCompoundProxy::line_surface(int j, int slot, const Eigen::Vector3d& front, const Eigen::Vector3d& u,
                                       double back, double ahead) noexcept {
  Ring& g = rings_[std::size_t(j)];
  const double last = g.at[std::size_t(slot)];
  SeenLineMemo& memo = g.memo[std::size_t(slot)];
  const Eigen::Vector3d c = front - back * u;
  const double start = front.dot(u) - back, len = back + ahead;
  // (The line's eye is its own, found from c: a line that has not moved has the same eye.)
  double t = kInf;
  if (memo.reuse(c, u, 0, 0, len, kSameLine * min_axis_, t)) return std::isfinite(t) ? start + t : kInf;
  // (A part held while the device presses on reads its lines to the device's depth, tens of
  // middle semi-axes past the surface they meet: the layers up to the last answer come first.)
  const double guess = std::isfinite(last) ? last - start + kRingLook * middle_[std::size_t(j)] : kInf;
  // (Its eye guessed from the line's last: what lies behind a line hardly changes tick to tick.)
  const SeenHit hit = solid_->push(c, u, 0, params_.seen_window * middle_[std::size_t(j)], len, false,
                                   g.eye[std::size_t(slot)], scratch_,
                                   std::isfinite(guess) ? guess : std::numeric_limits<double>::quiet_NaN());
  if (scratch_.overflow)
    memo.forget();
  else
    memo.keep(c, u, 0, 0, len, hit.hit ? hit.t : kInf);
  return hit.hit ? start + hit.t : kInf;
}

std::array<double, 2> SeenCompoundProxy::free_ring(int j, const ToolEllipsoid& from, const Eigen::Vector3d& u,
                                                   double len, bool leaving) noexcept {
  Ring& g = rings_[std::size_t(j)];
  if (!(g.axis.dot(u) >= kRingAxisCos)) forget_ring(j, u);
  const double look = kRingLook * middle_[std::size_t(j)];
  for (const LineRead& line : next_lines(j, from, u)) {
    // The line through the part's shadow, from as far behind the part's front as the part may
    // have gone past a rim since the line was last read. A ring line sees from there (it places
    // faces and edges, met from near), an inner line from its own eye (line_surface: what lies
    // under the part's middle may be a surface of faint layers seen only from afar); both from
    // the front itself when the part is leaving (the surface it lifts off from does not count).
    const Eigen::Vector3d p = from.center + line.offset;
    const Eigen::Vector3d front = p + exit_along(from, p, u) * u;
    const double back = look + refresh(line.slot) * len;
    g.foot[std::size_t(line.slot)] = front;
    if (leaving || line.slot < kRingRays) {
      const double eye = leaving ? 0.0 : -back;  // (the surface kept where it lies, as line_surface's)
      const SeenHit hit = solid_->first_inside(front, u, eye, eye, len + look, scratch_);
      g.at[std::size_t(line.slot)] = hit.hit ? front.dot(u) + hit.t : kInf;
    } else {
      // (A roaming line reads kRoamLook ahead: a feature under a tenth of a part's shadow is met
      // by one reading in a hundred, so it needs a window of a few hundred readings before the
      // part is past it; the centre line, read every kInnerTurns ticks, keeps kRingLook.)
      const double ahead = (line.slot >= kRoamLine ? kRoamLook : kRingLook) * middle_[std::size_t(j)];
      g.at[std::size_t(line.slot)] = line_surface(j, line.slot, front, u, back, len + ahead);
    }
  }
  // A line met later than its refresh allows (a slanted wall met line by line) does not hold:
  // snapping the proxy back would start the contact with a force step.
  std::array<double, 2> travel{kInf, kInf};  // the ring's, the inner lines'
  const ExitAlong exit(from, g.axis);
  const double sink = begin_sink(j, len);
  for (int kk = 0; kk < kReadLines; ++kk) {
    Eigen::Vector3d at;
    const double gap = ring_gap(exit, j, kk, u, at);
    double& t = travel[kk < kRingRays ? 0 : 1];
    if (gap <= len && gap >= -(refresh(kk) * len + sink)) t = std::min(t, gap);
  }
  return travel;
}

double SeenCompoundProxy::begin_sink(int j, double len) const noexcept {
  // At rest, a footprint's lateness (SeenProxy's rule, seen_footprint::begin_lateness): begun
  // from a surface the resting part was already past, the contact's axis pointed out of the
  // surface, and the proxy, pushed back toward the eye at the rise allowance, walked through the
  // face under the tool (the Truck's probe run, seed 2: 40 cm in half a second, then 30 N pulling
  // the hand down for 30 s).
  return seen_footprint::begin_lateness(len, min_axis_, middle_[std::size_t(j)], kRingSink);
}

std::array<SeenCompoundProxy::LineRead, 2> SeenCompoundProxy::next_lines(int j, const ToolEllipsoid& part,
                                                                         const Eigen::Vector3d& u) noexcept {
  Ring& g = rings_[std::size_t(j)];
  std::array<LineRead, 2> lines;
  lines[0] = {g.next, seen_footprint::ray_offset(shadow_along(part, u), g.next)};
  g.next = (g.next + 1) % kRingRays;
  if (g.next_inner == 0) {
    lines[1] = {kCentreLine, Eigen::Vector3d::Zero()};
  } else {
    // The roaming slot that holds least: no surface, one the part is past, or the farthest below
    // it; of equals, the oldest.
    int slot = 0;
    double worst = -kInf;
    const ExitAlong exit(part, g.axis);
    for (int s = 0; s < kRoamLines; ++s) {
      Eigen::Vector3d front;
      double gap = ring_gap(exit, j, kRoamLine + s, u, front);
      if (!(gap >= -kRingSink * middle_[std::size_t(j)])) gap = kInf;
      const bool older = g.stamp[std::size_t(s)] < g.stamp[std::size_t(slot)];
      if (gap > worst || (gap == worst && older)) worst = gap, slot = s;
    }
    g.stamp[std::size_t(slot)] = g.roam;
    lines[1] = {kRoamLine + slot, shadow_along(part, u).at(kRoamFraction * r2_disc(g.roam++))};
  }
  g.next_inner = (g.next_inner + 1) % kInnerTurns;
  return lines;
}

bool SeenCompoundProxy::begin_contact(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept {
  // Each part's leading point along its own chord, searched over the whole chord, and its
  // footprint; the first to meet the seen solid (the least fraction of its chord) begins the contact.
  pose(x_, q_);
  const std::array<ToolEllipsoid, kMaxToolParts> before = parts_;
  pose(x, q);
  double first = kInf;
  Eigen::Vector3d first_u = Eigen::Vector3d::Zero(), first_eye = Eigen::Vector3d::Zero();
  entry_motion_.fill(0);
  for (int j = 0; j < tool_.count; ++j) {
    const ToolEllipsoid& part = before[std::size_t(j)];
    const Eigen::Vector3d d = parts_[std::size_t(j)].center - part.center;
    const double len = d.norm();
    entry_motion_[std::size_t(j)] = len;
    if (!(len > 1e-9 * radius_)) continue;
    const Eigen::Vector3d u = d / len;
    // The part's leading point along u, as the centre of a sphere of its support distance
    // (SeenSolid::push takes a centre and a lead along u).
    const Eigen::Vector3d tip = part.surface_point(u);
    const double lead = (tip - part.center).dot(u);
    const Eigen::Vector3d centre = tip - lead * u;
    double& eye = free_eye_[std::size_t(j)];  // (in: the part's last eye, push()'s guess; out: this one's)
    const bool leaving = u.dot(normal_) > 0;
    const SeenHit hit = solid_->push(centre, u, lead, params_.seen_window * radius_, len, leaving, eye, scratch_);
    if (hit.hit && hit.t / len < first) {
      first = hit.t / len;
      first_u = u;
      first_eye = tip - std::max(0.0, eye - kEyeMargin * min_axis_) * u;
    }
    const std::array<double, 2> travel = free_ring(j, part, u, len, leaving);
    double ring = travel[0];
    // Within a middle semi-axis of a surface by its footprint, the edge under it is searched out
    // (update_edges), and the part meets it at its own tangent point, not at whichever footprint
    // line it sinks onto first: a contact found late would start with a force step.
    const double look = kRingLook * middle_[std::size_t(j)];
    axis_ = u;  // (the searches read along the part's chord)
    const LineChoice c = nearest_line(j, part);
    if (c.source >= 0 && c.nearest < look) {
      update_edges(j, c, part);
      Eigen::Vector3d contact;
      const double edge = edge_gap(part, j, u, contact);
      if (edge <= len && edge >= -begin_sink(j, len)) ring = std::min(ring, edge);
    }
    // An inner line begins a contact only where it would hold the part (nearest_line's rule: the
    // ring and its edge meet nothing as near, by the contact band).
    if (c.line >= kRingRays && c.line < kReadLines) ring = std::min(ring, travel[1]);
    // So does an edge search's own line (the last of its lines to meet the surface) where it
    // would hold the part: nearer than every ring line. Left out, a disc whose edge search line
    // stood 0.4 R under the raised patch an inner line had met (too little to hold by the band)
    // went 1.5 R past both before a ring line met the surface (halo, vertical at 2 %).
    if (c.line >= kEdgeSlot && c.line < kLines) {
      Eigen::Vector3d front;
      const double gap = ring_gap(ExitAlong(part, rings_[std::size_t(j)].axis), j, c.line, u, front);
      if (gap <= len && gap >= -(refresh(c.line) * len + begin_sink(j, len))) ring = std::min(ring, gap);
    }
    if (std::isfinite(ring) && std::max(0.0, ring) / len < first) {
      first = std::max(0.0, ring) / len;
      first_u = u;
      // (The footprint's eye: from where the part's front was, as far back as it is still seen from.)
      const double back = solid_->eye_distance(tip, u, params_.seen_window * radius_, scratch_);
      first_eye = tip - std::max(0.0, back - kEyeMargin * min_axis_) * u;
    }
  }
  if (!std::isfinite(first)) return false;
  axis_ = first_u;
  eye_ = first_eye;
  fresh_normal_ = true;  // the contact's first reading sets the normal (render())
  normal_reading_.forget();
  return true;
}

void SeenCompoundProxy::read_ring(int j, double reach) noexcept {
  Ring& g = rings_[std::size_t(j)];
  if (!(g.axis.dot(axis_) >= kRingAxisCos)) forget_ring(j, axis_);
  const ToolEllipsoid& part = parts_[std::size_t(j)];
  const double look = kRingLook * middle_[std::size_t(j)];
  for (const LineRead& line : next_lines(j, part, axis_)) {
    // The line through the resting part's shadow (parts_ posed at the proxy), read from two
    // kRingLook above its front down to `reach` past it (the device's depth).
    const Eigen::Vector3d p = part.center + line.offset;
    const Eigen::Vector3d front = p + exit_along(part, p, axis_) * axis_;
    g.foot[std::size_t(line.slot)] = front;
    g.at[std::size_t(line.slot)] =
        line_surface(j, line.slot, front, axis_, 2 * look, reach);
  }
}

void SeenCompoundProxy::search_edge(int j, int which, int source, const ToolEllipsoid& part) noexcept {
  EdgeSearch& e = edges_[std::size_t(j)][std::size_t(which)];
  Ring& g = rings_[std::size_t(j)];
  const std::size_t slot = std::size_t(kEdgeSlot + which);
  e.source = source;
  e.centre = part.center;
  g.at[slot] = kInf;
  if (source < 0) return;
  // A line of the search meets the edge's surface where its surface lies no deeper along the axis
  // than the source line's by the contact band: past the edge, a line sees the far side (the
  // side face's discs seen edge-on, the floor).
  const double deepest = g.at[std::size_t(source)] + kContactBand * min_axis_;
  Eigen::Vector3d inner = g.foot[std::size_t(source)], outer = part.surface_point(axis_);
  const double look = kRingLook * middle_[std::size_t(j)];
  for (int step = 0; step < kEdgeSteps; ++step) {
    const Eigen::Vector3d mid = 0.5 * (inner + outer);
    const double t = exit_along(part, mid, axis_);
    if (std::isnan(t)) {
      outer = mid;
      continue;
    }
    const Eigen::Vector3d front = mid + t * axis_;
    const double reach = deepest - front.dot(axis_);
    const SeenHit hit = reach > -look ? solid_->first_inside(front, axis_, -2 * look, -look, reach, scratch_) : SeenHit{};
    if (!hit.hit || hit.t < -kRingSink * middle_[std::size_t(j)]) {
      outer = mid;
      continue;
    }
    inner = mid;
    g.foot[slot] = front;
    g.at[slot] = front.dot(axis_) + hit.t;
  }
  // No line between met the surface: the source line itself is the last that does (a part
  // resting with that line on the edge), not no edge.
  if (!std::isfinite(g.at[slot])) {
    g.foot[slot] = g.foot[std::size_t(source)];
    g.at[slot] = g.at[std::size_t(source)];
  }
}

void SeenCompoundProxy::update_edges(int j, const LineChoice& c, const ToolEllipsoid& resting) noexcept {
  // The first search keeps its source while that line still holds within the contact band of
  // the nearest, the second while its line sees the surface under the part at all; otherwise each
  // starts afresh, the first from the nearest line, the second from the nearest that sees the
  // surface 60 degrees or more from the first's (one within the band alone left a lone edge
  // point, and the part on a footprint line's own normal, 30 deg off, at 2 mm spacing).
  const double band = kContactBand * min_axis_;
  auto& e = edges_[std::size_t(j)];
  const auto holds = [&](int which, int r) {
    return r >= 0 && (which == 0 ? c.gaps[std::size_t(r)] <= c.nearest + band : std::isfinite(c.gaps[std::size_t(r)]));
  };
  // (A search always ends on an edge point: where no line between met the surface, its source's.)
  const auto stale = [&](int which) { return !holds(which, e[std::size_t(which)].source); };
  if (stale(0)) search_edge(j, 0, c.source, resting);
  if (stale(1) || !apart(e[1].source, e[0].source)) {
    int second = -1;
    for (int r = 0; r < kRingRays; ++r)
      if (holds(1, r) && apart(r, e[0].source) && (second < 0 || c.gaps[std::size_t(r)] < c.gaps[std::size_t(second)]))
        second = r;
    // (No line to start from: the edge point found last stays while it lies under the part and
    // the part has not moved from where it found it; the edge does not move under a resting part.)
    const Ring& g = rings_[std::size_t(j)];
    Eigen::Vector3d moved = resting.center - e[1].centre;
    moved -= moved.dot(g.axis) * g.axis;
    const bool keep = second < 0 && std::isfinite(g.at[kEdgeSlot + 1]) &&
                      moved.norm() < kEdgeSpan * middle_[std::size_t(j)] &&
                      !std::isnan(ExitAlong(resting, g.axis)(g.foot[kEdgeSlot + 1]));
    if (!keep) search_edge(j, 1, second, resting);
  }
}

double SeenCompoundProxy::edge_span(int j, const Eigen::Vector3d& axis, Eigen::Vector3d& along) const noexcept {
  const Ring& g = rings_[std::size_t(j)];
  if (!(g.axis.dot(axis) >= kRingAxisCos) || !std::isfinite(g.at[kEdgeSlot]) || !std::isfinite(g.at[kEdgeSlot + 1]))
    return 0;
  along = g.foot[kEdgeSlot + 1] - g.foot[kEdgeSlot];
  along -= along.dot(axis) * axis;
  const double span = along.norm();
  if (span > 0) along /= span;
  return span;
}

double SeenCompoundProxy::edge_gap(const ToolEllipsoid& part, int j, const Eigen::Vector3d& axis,
                                   Eigen::Vector3d& contact) const noexcept {
  Eigen::Vector3d e;
  const double span = edge_span(j, axis, e);
  if (!(span > kEdgeSpan * middle_[std::size_t(j)])) return kInf;
  const Ring& g = rings_[std::size_t(j)];
  const double at1 = g.at[kEdgeSlot], at2 = g.at[kEdgeSlot + 1];
  const Eigen::Vector3d& p1 = g.foot[kEdgeSlot];
  // The part's points whose normal is across the edge (n . e = 0) lie on the plane through its
  // centre with normal A e (A = Sigma^-1); the edge's plane along the axis has normal w. Their
  // line meets the part at its point resting on the edge.
  const Eigen::Matrix3d r = part.rotation.toRotationMatrix();
  const Eigen::Matrix3d inv = r * part.semi_axes.cwiseAbs2().cwiseInverse().asDiagonal() * r.transpose();
  const Eigen::Vector3d n1 = inv * e, w = axis.cross(e);
  const Eigen::Vector3d d = n1.cross(w);
  const double a11 = n1.dot(n1), a12 = n1.dot(w), a22 = w.dot(w), det = a11 * a22 - a12 * a12;
  if (!(std::abs(det) > 1e-18 * a11 * a22) || !(d.squaredNorm() > 0)) return kInf;
  const double rhs = w.dot(p1 - part.center);
  const Eigen::Vector3d x0 = (-a12 * rhs / det) * n1 + (a11 * rhs / det) * w;  // from the centre
  const double qa = d.dot(inv * d), qb = x0.dot(inv * d), qc = x0.dot(inv * x0) - 1;
  const double disc = qb * qb - qa * qc;
  if (!(disc >= 0)) return kInf;  // the edge passes beside the part
  const double t1 = (-qb + std::sqrt(disc)) / qa, t2 = (-qb - std::sqrt(disc)) / qa;
  const Eigen::Vector3d c1 = part.center + x0 + t1 * d, c2 = part.center + x0 + t2 * d;
  contact = c1.dot(axis) > c2.dot(axis) ? c1 : c2;
  // The edge's surface there, between its two readings.
  const double s = (contact - p1).dot(e) / span;
  return at1 + s * (at2 - at1) - contact.dot(axis);
}

bool SeenCompoundProxy::rests_on_edge(int j, double gap, Eigen::Vector3d& point) const noexcept {
  // A line a little higher than the edge's fit (a disc standing proud of its neighbours at the
  // edge, a fraction of a millimetre) is a bump on the edge, not a contact of its own: a stylus
  // held there on its own normal, a few millimetres beside its tangent point, leaned 30 degrees
  // along the edge (bench/RESULTS.md, ninety-seventh session). Two edge points closer than
  // kSnapSpan middle semi-axes give too loose a direction to move the contact onto.
  const std::size_t k = std::size_t(j);
  Eigen::Vector3d along;
  if (!(edge_span(j, axis_, along) >= kSnapSpan * middle_[k])) return false;
  // Within kEdgeSnap under the fit: a tangent point well below the edge's fit (a disc on a
  // droplet's curved top, the fit rising 0.9 smallest semi-axes over the line there) is a part
  // already past the edge, and moving the contact onto it let the disc slide through. Up to
  // kRimTop over it: the line on the rim's top, the fit through points down its shoulder.
  Eigen::Vector3d tangent;
  const double above = edge_gap(parts_[k], j, axis_, tangent) - gap;  // the line over the edge's fit
  if (!(above >= -kEdgeSnap * min_axis_ && above <= kRimTop * min_axis_)) return false;
  point = tangent;
  return true;
}

SeenCompoundProxy::LineChoice SeenCompoundProxy::nearest_line(int j, const ToolEllipsoid& resting) const noexcept {
  const std::size_t k = std::size_t(j);
  LineChoice c;
  const Eigen::Vector3d& along = rings_[k].axis;
  const ExitAlong rest(resting, along), now(parts_[k], along);
  const auto line_gap = [&](int r) {
    Eigen::Vector3d front;
    c.gaps[std::size_t(r)] = kInf;
    if (!(ring_gap(rest, j, r, axis_, front) >= -kRingSink * middle_[k])) return kInf;
    return c.gaps[std::size_t(r)] = ring_gap(now, j, r, axis_, front);
  };
  for (int r = 0; r < kLines; ++r) {
    if (r >= kRingRays && r < kReadLines) continue;  // the inner lines: below
    const double gap = line_gap(r);
    if (gap < c.gap) c.gap = gap, c.line = r;
    if (r < kRingRays && gap < c.nearest) c.nearest = gap, c.source = r;
  }
  Eigen::Vector3d contact;
  if (edge_gap(resting, j, axis_, contact) >= -kRingSink * middle_[k]) {
    const double gap = edge_gap(parts_[k], j, axis_, contact);
    if (gap < c.gap) c.gap = gap, c.line = kEdgeLine;
  }
  // An inner line holds the part only where it meets a surface the ring and the edge do not (a
  // thin feature or a raised patch under the middle): nearer than all of them by kInnerBand. On a
  // face or an edge they agree with the ring within the surface's roughness, and the ring's edge
  // search places the part.
  // The nearest inner line, whichever slot it is read in, or the one that holds the part while it
  // is as near within kInnerKeep: lines re-read on one raised patch trade places by less (held by
  // the first slot within the band of the nearest, the hold jumped between two lines 1.2 mm apart).
  int inner = -1;
  double inner_gap = kInf;
  for (int r = kRingRays; r < kReadLines; ++r) {
    const double gap = line_gap(r);
    if (gap < inner_gap) inner_gap = gap, inner = r;
  }
  const int held = held_[k].line;
  if (held >= kRingRays && held < kReadLines && c.gaps[std::size_t(held)] <= inner_gap + kInnerKeep * min_axis_)
    inner_gap = c.gaps[std::size_t(held)], inner = held;
  if (inner_gap < c.gap - kInnerBand * min_axis_) c.gap = inner_gap, c.line = inner;
  return c;
}

double SeenCompoundProxy::leading_ray(int j, double band, double& depth) noexcept {
  const std::size_t k = std::size_t(j);
  const Eigen::Vector3d tip = parts_[k].surface_point(axis_);
  depth = (tip - eye_).dot(axis_);
  if (!(depth > 0)) return kInf;  // behind the eye plane: nothing in front of it to meet
  // Past the part's depth by the contact band: a part just above its surface still touches.
  const double reach = depth + band;
  const Eigen::Vector3d origin = tip - depth * axis_;  // on the eye plane
  // The first crossing along a line from a fixed eye does not depend on how far the search
  // reaches past it: a part whose line has not moved (the proxy sticking while the device
  // presses on) meets the same hit, read again only when the line moves.
  SeenLineMemo& last = leading_[k];
  double t = kInf;
  if (last.reuse(origin, axis_, 0, 0, reach, kSameLine * min_axis_, t)) return t;
  const double guess = last.valid && std::isfinite(last.t) ? last.t + kGuessMargin * min_axis_ : reach;
  const SeenHit hit = solid_->first_inside(origin, axis_, 0, 0, reach, scratch_, guess);
  if (follower_) read_part_shares(j, hit);  // (a kept search keeps its shares and its layers)
  part_layer_count_[k] = solid_->hit_contacts(hit, scratch_, std::uint8_t(j), part_layers_[k]);
  if (scratch_.overflow) {
    last.forget();
    return hit.hit ? hit.t : kInf;
  }
  last.keep(origin, axis_, 0, 0, reach, hit.hit ? hit.t : kInf);
  return hit.hit ? hit.t : kInf;
}

Eigen::Vector3d SeenCompoundProxy::slide_across(const Eigen::Vector3d& goal,
                                                const std::array<ToolEllipsoid, kMaxToolParts>& resting) noexcept {
  // SeenProxy::slide_across part by part: each part's line along the move through its surface
  // point that way (where its outward normal is the move's direction: the point that leads, a
  // tilted part's side), seen and searched from kWallDepth inside that point (the wall it was
  // held against last tick may lie a little inside it now); a surface the line crosses deeper
  // (a slope the height field climbs) does not stop it. The nearest part's wall stops the move.
  const Eigen::Vector3d& a = axis_;
  Eigen::Vector3d step = goal - x_;
  step -= step.dot(a) * a;
  const WallSlide slide = slide_along_walls(
      step, kSlideMin * min_axis_, seen_footprint::kMaxSlide * min_axis_, [&](const Eigen::Vector3d& u, const Eigen::Vector3d& moved, double len, Eigen::Vector3d& wall) {
        double nearest = len;
        for (int j = 0; j < tool_.count; ++j) {
          const double m = middle_[std::size_t(j)];
          const double lead = kWallDepth * m, stop = (kWallDepth + kWallGap) * m;
          const Eigen::Vector3d o = resting[std::size_t(j)].surface_point(u) + moved - lead * u;
          // (A wall that holds the part lies just ahead: the layers up to kWallLook past the
          // part's point are read first, the rest of the line only when they do not make a surface.)
          const SeenHit hit = solid_->first_inside(o, u, 0, lead, lead + nearest + stop, scratch_, lead + stop + kWallLook * m);
          if (!hit.hit || !(hit.t > lead) || scratch_.overflow) continue;
          const double t = hit.t - lead - stop;
          if (t < nearest) {
            nearest = t;
            wall = solid_->wall_normal(u, a, hit, scratch_);
          }
        }
        return nearest;
      });
  wall_ = slide.wall;
  const Eigen::Vector3d off = x_ + slide.moved - goal;
  return goal + off - off.dot(a) * a;
}

double SeenCompoundProxy::sink(const std::array<double, kMaxToolParts>& past) noexcept {
  // SeenProxy's sunk_, part by part: at a contact's first tick, a part already past its surface
  // by more than its own motion this tick (and kSunkSlack) was in it before, seen along the new
  // axis (a stylus's far part behind a panel it passed seen edge-on): it holds that much deeper
  // for the contact, instead of throwing the proxy back by it (3.7 m on the Truck's probe run).
  // Within kRingSink middle semi-axes of it, but deeper than its footprint's lateness explains
  // (kRingRays ticks of its motion and kLate middle semi-axes, SeenProxy's rule for a footprint
  // that begins a contact), a part was met late by a footprint line on a rough capture: its
  // surface is the surface, not one it was in. It starts sunk too (held where the surface is at
  // once, it began the contact with a step: 13.5 N on the Truck's probe run), and its surface is
  // given back as a ramp of kClimbTick smallest semi-axes a tick (sunk for the contact, the
  // stylus pressed along seen-felt's rays rested up to 0.3 R deeper). The proxy rises onto it as
  // onto any rise, as far as the hand pays for it (climb(), ClimbLedger): a straight press keeps
  // its level, a slide pays its way up (let free, the ramp gave a loaded proxy energy the hand
  // never paid: bench/RESULTS.md, seventy-seventh session).
  double push = -kInf;
  for (int j = 0; j < tool_.count; ++j) {
    const std::size_t k = std::size_t(j);
    if (fresh_normal_) {
      const double beyond = std::isfinite(past[k]) ? past[k] - (entry_motion_[k] + kSunkSlack * min_axis_) : 0.0;
      const double late = kRingRays * entry_motion_[k] + seen_footprint::kLate * middle_[k];
      sunk_[k] = beyond > late ? beyond : 0.0;
      fading_[k] = !(beyond > kRingSink * middle_[k]);
    } else if (fading_[k] && sunk_[k] > 0) {
      sunk_[k] = std::max(0.0, sunk_[k] - seen_footprint::kClimbTick * min_axis_);
    }
    push = std::max(push, past[k] - sunk_[k]);
  }
  return push;
}

double SeenCompoundProxy::climb(double back, double ahead, double slide, const Eigen::Vector3d& lateral) const noexcept {
  // (A room below zero, a debt that the sphere's proxy pays by coming toward the device, is not
  // taken by the compound proxy: its parts' levels are not tried against it yet; an earlier
  // trial of a passive rise for it is bench/experiments/seen-compound-passive-rise.patch.)
  return std::min(back, ahead + std::min(seen_footprint::rise_allowance(slide, min_axis_),
                                         std::max(0.0, ledger_.rise_room(lateral, normal_, axis_))));
}

bool SeenCompoundProxy::hold(const Eigen::Vector3d& device, const Eigen::Vector3d& goal,
                             const Eigen::Quaterniond& q) noexcept {
  const Eigen::Vector3d& a = axis_;
  const double band = kContactBand * min_axis_;
  deficit_ = 0;
  // The footprints are read and judged at the resting proxy (turned to q): a line the proxy is
  // already past by more than kRingSink does not hold.
  pose(x_, q);
  const std::array<ToolEllipsoid, kMaxToolParts> resting = parts_;
  // The goal across the axis, stopped by a wall there, at the device's depth.
  const Eigen::Vector3d across = slide_across(goal, resting);
  const Eigen::Vector3d lateral_wall = wall_;
  const Eigen::Vector3d y = across + (device - across).dot(a) * a;
  const double ahead = std::max(0.0, (y - x_).dot(a)) + band;
  // (A part its leading point's ray held on the surface at the last tick reads no footprint line:
  // on a face its side does not touch first.)
  for (int j = 0; j < tool_.count; ++j)
    if (held_[std::size_t(j)].by_ring || !(held_[std::size_t(j)].gap < band)) read_ring(j, ahead);
  pose(y, q);
  std::array<double, kMaxToolParts> depth{}, at{}, past{};
  std::array<LineChoice, kMaxToolParts> lines{};
  for (int j = 0; j < tool_.count; ++j) {
    const std::size_t k = std::size_t(j);
    at[k] = leading_ray(j, band, depth[k]);
    lines[k] = nearest_line(j, resting[k]);
    // Where the footprint holds the part before its leading point does (an edge under its side),
    // the edge is searched out, at once when a search's line no longer holds.
    if (lines[k].source >= 0 && lines[k].gap < at[k] - depth[k]) {
      update_edges(j, lines[k], resting[k]);
      lines[k] = nearest_line(j, resting[k]);
    }
    // How far the part is past its surface (its leading point's ray or its footprint's line).
    past[k] = std::max(std::isfinite(at[k]) ? depth[k] - at[k] : -kInf, lines[k].line >= 0 ? -lines[k].gap : -kInf);
  }
  const double push = sink(past);
  if (!(push > 0)) return false;  // no part reaches its surface: the device is out
  const double back = push + 1e-6 * min_axis_;
  // A rise of more than kMaxClimb smallest semi-axes in one tick is no surface the tool slides
  // onto but the top of a wall that a part's ray met as the tool moved across the axis
  // (SeenProxy::kMaxClimb): the proxy stays where it stood, held by it across the axis.
  const Eigen::Vector3d next = y - back * a;
  wall_ = lateral_wall;
  if (!fresh_normal_ && (x_ - next).dot(a) > kMaxClimb * min_axis_) {
    Eigen::Vector3d refused = next - x_;
    refused -= refused.dot(a) * a;
    const double len = refused.norm();
    if (len > 0) wall_ = -refused / len;
    pose(x_, q);
    return true;
  }
  // The rise a tick, bounded as SeenProxy::climb bounds it: the slope of the move across the axis
  // and a small rise a tick (seen_footprint::rise_allowance; footprint lines read in turn find, one by one, surfaces
  // the parts are already past: on the Truck's probe run a 5 cm stylus stepped 10 mm at a time);
  // the slide counts the parts' motion by the turn as well (a turn that swings a part onto the
  // surface lifts the proxy at once).
  // (A turn moves the parts by up to its angle times the tool's reach from the TCP.)
  const double slide = (y - x_ - (y - x_).dot(a) * a).norm() + q_.angularDistance(q) * reach_;
  const double climbed = fresh_normal_ ? back : climb(back, (y - x_).dot(a), slide, y - x_ - (y - x_).dot(a) * a);
  deficit_ = std::max(0.0, back - climbed);
  x_ = y - climbed * a;
  pose(x_, q);
  record_holds(lines, at, depth, climbed);
  return true;
}

void SeenCompoundProxy::record_holds(const std::array<LineChoice, kMaxToolParts>& lines,
                                     const std::array<double, kMaxToolParts>& at,
                                     const std::array<double, kMaxToolParts>& depth, double back) noexcept {
  const Eigen::Vector3d& a = axis_;
  const double band = kContactBand * min_axis_;
  for (int j = 0; j < tool_.count; ++j) {
    const std::size_t k = std::size_t(j);
    Hold& h = held_[k];
    const LineChoice& c = lines[k];
    // (A sunk part's surfaces lie sunk_ deeper: sink().)
    const double centre_gap = std::isfinite(at[k]) ? at[k] + sunk_[k] - (depth[k] - back) : kInf;
    under_[k] = centre_gap;  // (< 0: a crest above the part, a rise not yet paid for: ClimbLedger)
    h.by_ring = !(centre_gap < band) && c.line >= 0 && c.gap + sunk_[k] + back < centre_gap;
    h.line = h.by_ring ? c.line : -1;
    if (h.by_ring) {
      h.gap = std::max(0.0, c.gap + sunk_[k] + back);
      if (c.line == kEdgeLine) {
        (void)edge_gap(parts_[k], j, a, h.point);
      } else {
        (void)ring_gap(ExitAlong(parts_[k], rings_[k].axis), j, c.line, a, h.point);
        if (rests_on_edge(j, h.gap, h.point)) h.line = kEdgeLine;
      }
    } else {
      h.gap = std::max(0.0, centre_gap);
      h.point = parts_[k].surface_point(a);
    }
  }
}

bool SeenCompoundProxy::contact(Eigen::Vector3d& target, Eigen::Vector3d& lever_point, const Eigen::Vector3d& normal) noexcept {
  const double band = kContactBand * min_axis_;
  Eigen::Vector3d seen_point = Eigen::Vector3d::Zero(), own = Eigen::Vector3d::Zero();
  double seen_w = 0, own_w = 0, sum = 0, most = 0;
  int heaviest_seen = -1;
  lever_point.setZero();
  touching_ = 0;
  weight_.fill(0);
  double under = 0;
  for (int j = 0; j < tool_.count; ++j) {
    const Hold& h = held_[std::size_t(j)];
    const double g = h.gap / band;
    if (!(g < 1)) continue;
    const double w = 1 - g * g;
    ++touching_;
    sum += w;
    weight_[std::size_t(j)] = w;
    under += w * std::clamp(under_[std::size_t(j)], -min_axis_, min_axis_);
    if (h.by_ring) {
      own -= w * outward_normal(parts_[std::size_t(j)], h.point);
      own_w += w;
      lever_point += w * h.point;
      continue;
    }
    seen_point += w * (h.point + h.gap * axis_);  // the seen surface under its leading point
    seen_w += w;
    if (w > most) most = w, heaviest_seen = j;
    // (at the part's surface point facing the contact: the tangent point on a surface the axis
    // meets at a slant)
    const Eigen::Vector3d facing = normal.squaredNorm() > 0 ? Eigen::Vector3d(-normal) : Eigen::Vector3d(axis_);
    lever_point += w * parts_[std::size_t(j)].surface_point(facing);
  }
  if (!(sum > 0)) return false;
  lever_point /= sum;
  tip_under_ = under / sum;
  if (seen_w > 0) {
    seen_point /= seen_w;
    // (SeenProxy's reading, on the ring of the heaviest such part's middle semi-axis)
    const double h = solid_->normal_ring(middle_[std::size_t(heaviest_seen)]);
    const double back = std::min(std::max(0.0, (seen_point - eye_).dot(axis_)), kNormalEye * middle_[std::size_t(heaviest_seen)]);
    seen_normal_ = normal_reading_.update(*solid_, seen_point, axis_, h, back, kNormalReuse * min_axis_, scratch_);
  }
  own_share_ = own_w / sum;
  target = seen_w * seen_normal_ + own;
  target = target.norm() > 1e-12 ? Eigen::Vector3d(target.normalized()) : Eigen::Vector3d(-axis_);
  return true;
}

RenderOutput SeenCompoundProxy::render(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                                       const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                       double dt) noexcept {
  RenderOutput out;
  out.proxy = position;
  contact_count_ = 0;
  if (!position.allFinite() || !orientation.coeffs().allFinite() || !(orientation.norm() > 0) ||
      !velocity.allFinite() || !angular_velocity.allFinite() || !(dt > 0)) {
    out.status = QueryStatus::kInvalidTool;
    return out;
  }
  const Eigen::Quaterniond q = orientation.normalized();
  if (!started_) {
    x_ = last_device_ = position;
    q_ = q;
    started_ = true;
  }
  const Eigen::Vector3d device_step = position - last_device_;
  last_device_ = position;
  const bool was_in_contact = in_contact_;
  if (in_contact_) {  // (before the climb asks what is paid for)
    const Eigen::AngleAxisd turn(q * q_.conjugate());
    ledger_.pay(device_step, turn.angle() * turn.axis());  // (the hand's turn against the torque pays too)
  }
  if (!in_contact_) in_contact_ = begin_contact(position, q);
  if (in_contact_ && !was_in_contact) ledger_.forget();  // (a new contact's ledger starts empty)
  const Eigen::Vector3d before = x_;
  // (Until a contact's first reading its normal is none; the last contact's stays in normal_,
  // which says whether the tool is leaving a surface, should the new contact fail at once.)
  const Eigen::Vector3d held = fresh_normal_ ? Eigen::Vector3d::Zero() : normal_;
  if (in_contact_) {
    friction_step_ = friction_.update(was_in_contact, held, position, x_, device_step, radius_);
    in_contact_ = hold(position, friction_step_.goal, q);
  }
  q_ = q;
  Eigen::Vector3d target, lever_point;
  if (!in_contact_ || !contact(target, lever_point, held)) {
    x_ = position;
    pose(x_, q_);
    release();
    return out;
  }
  // The normal follows its target over kNormalTau and over kNormalPath of the proxy's slide,
  // whichever is slower (SeenProxy's: the seen surface's relief finer than the tool does not turn
  // it); where footprints hold the tool more than its leading points, over kNormalTau alone (the
  // parts' own normals on an edge are geometry, refined by the edge search as the tool rests), and
  // over kNormalTau alone while the seen reading refines its spot (SeenNormalReading::settling).
  if (fresh_normal_ || normal_.squaredNorm() == 0) {
    normal_ = target;
    fresh_normal_ = false;
  } else {
    const Eigen::Vector3d moved = x_ - before;
    const double slide = (moved - moved.dot(axis_) * axis_).norm();
    const double by_time = -std::expm1(-dt / kNormalTau);
    const double rate = own_share_ > 0.5 || (normal_reading_.settling() && slide < kSlideMin * min_axis_)
                            ? by_time
                            : std::min(by_time, -std::expm1(-slide / (kNormalPath * min_axis_)));
    const Eigen::Vector3d blended = normal_ + rate * (target - normal_);
    normal_ = blended.norm() > 1e-9 ? Eigen::Vector3d(blended.normalized()) : target;
  }
  out.proxy = x_;
  out.constraints = 1;
  if (follower_) apply_material(lever_point);
  const double mu_k = follower_ ? follower_->blend().mu_k : params_.mu_k;
  out.force = coupling_.force(x_ - position, normal_, velocity, dt, {}, friction_step_, mu_k);
  // The proxy's own step against the coupling, and the hand's payment for a rise still owed.
  ledger_.book(x_ - before, out.force, normal_, min_axis_);
  out.force = coupling_.clamp(out.force + ledger_.reaction(deficit_, velocity, normal_, min_axis_, dt));
  if (follower_) {
    // The texture tip: below the touching parts, the relief they do not ride (SeenProxy's).
    out.force = follower_->add_forces_at_tip(-tip_under_, out.force, lever_point, normal_, velocity, min_axis_,
                                             coupling_.f_max(), dt);
    out.texture_rms = float(follower_->texture_rms());
    out.vibration = float(follower_->blend().vibration);
  }
  out.torque = (lever_point - x_).cross(out.force);
  ledger_.torque_on_device(out.torque);
  if (wall_.squaredNorm() > 0) out.force = coupling_.add_wall(out.force, wall_, normal_, x_ - position, velocity, dt);
  out.counts.contacts = std::uint32_t(touching_);
  gather_contacts();
  return out;
}

void SeenCompoundProxy::gather_contacts() noexcept {
  contact_count_ = 0;
  for (int j = 0; j < tool_.count; ++j) {
    const std::size_t k = std::size_t(j);
    if (!(weight_[k] > 0) || held_[k].by_ring) continue;
    for (std::size_t i = 0; i < part_layer_count_[k]; ++i) contacts_[contact_count_++] = part_layers_[k][i];
  }
}

}  // namespace gshaptics
