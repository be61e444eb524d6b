#include "gshaptics/force/seen_compound_proxy.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The middle of a part's three semi-axes (a stylus segment's radius, a disc's radius).
double middle_semi_axis(const ToolEllipsoid& part) noexcept {
  Eigen::Vector3d s = part.semi_axes;
  std::sort(s.data(), s.data() + 3);
  return s[1];
}

}  // namespace

SeenCompoundProxy::SeenCompoundProxy(const SeenSolid& solid, const CompoundTool& tool, const ProxyParams& params,
                                     double f_max)
    : solid_(&solid),
      tool_(tool),
      params_(params),
      f_max_(f_max),
      coupling_(params, f_max),
      friction_(params.mu_s, params.mu_k) {
  tool_.validate("seen proxy: tool");
  radius_ = tool_.largest_semi_axis();
  min_axis_ = kInf;
  for (const ToolPart& p : tool_.view()) min_axis_ = std::min(min_axis_, p.semi_axes.minCoeff());
  reset();
}

void SeenCompoundProxy::reset() noexcept {
  started_ = false;
  release();
  normal_.setZero();
}

void SeenCompoundProxy::release() noexcept {
  in_contact_ = false;
  touching_ = 0;
  coupling_.release();
  friction_.reset();
  friction_step_ = {};
  gap_.fill(kInf);
  last_hit_.fill(std::numeric_limits<double>::quiet_NaN());
}

void SeenCompoundProxy::pose(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept {
  tool_.posed(x, q, std::span<ToolEllipsoid>(parts_.data(), std::size_t(tool_.count)));
}

bool SeenCompoundProxy::begin_contact(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept {
  // Each part's leading point along its own chord, searched over the whole chord; the first to
  // meet the seen solid (the least fraction of its chord) begins the contact.
  std::array<Eigen::Vector3d, kMaxToolParts> from{};
  pose(x_, q_);
  for (int j = 0; j < tool_.count; ++j) from[std::size_t(j)] = parts_[std::size_t(j)].center;
  const std::array<ToolEllipsoid, kMaxToolParts> before = parts_;
  pose(x, q);
  double first = kInf, first_eye = 0, first_lead = 0;
  Eigen::Vector3d first_u = Eigen::Vector3d::Zero(), first_centre = Eigen::Vector3d::Zero();
  for (int j = 0; j < tool_.count; ++j) {
    const Eigen::Vector3d d = parts_[std::size_t(j)].center - from[std::size_t(j)];
    const double len = d.norm();
    if (!(len > 1e-9 * radius_)) continue;
    const Eigen::Vector3d u = d / len;
    const ToolEllipsoid& part = before[std::size_t(j)];
    // The part's leading point along u, as the centre of a sphere of its support distance
    // (SeenSolid::push takes a centre and a lead along u).
    const Eigen::Vector3d tip = part.surface_point(u);
    const double s = (tip - part.center).dot(u);
    const Eigen::Vector3d centre = tip - s * u;
    double eye = 0;
    const bool leaving = u.dot(normal_) > 0;
    const SeenHit hit = solid_->push(centre, u, s, params_.seen_window * radius_, len, leaving, eye, scratch_);
    if (!hit.hit || hit.t / len >= first) continue;
    first = hit.t / len;
    first_eye = eye;
    first_lead = s;
    first_u = u;
    first_centre = centre;
  }
  if (!std::isfinite(first)) return false;
  const double back = first_lead + std::max(0.0, first_eye - kEyeMargin * min_axis_);
  axis_ = first_u;
  eye_ = first_centre + (first_lead - back) * first_u;
  normal_.setZero();  // read afresh by the contact's first hold()
  pending_ray_ = -1;
  return true;
}

bool SeenCompoundProxy::hold(const Eigen::Vector3d& device, const Eigen::Vector3d& goal,
                             const Eigen::Quaterniond& q) noexcept {
  const Eigen::Vector3d& a = axis_;
  const Eigen::Vector3d y = goal + (device - goal).dot(a) * a;  // the goal across the axis, the device's depth
  pose(y, q);
  const double band = kContactBand * min_axis_;
  std::array<double, kMaxToolParts> depth{}, at{};
  double push = -kInf;
  for (int j = 0; j < tool_.count; ++j) {
    const std::size_t k = std::size_t(j);
    depth[k] = (parts_[k].surface_point(a) - eye_).dot(a);
    at[k] = kInf;
    if (!(depth[k] > 0)) continue;  // behind the eye plane: nothing in front of it to meet
    const Eigen::Vector3d foot = parts_[k].surface_point(a) - depth[k] * a;
    // Past the part's depth by the contact band: a part just above its surface still touches.
    const double reach = depth[k] + band;
    const double guess = std::isfinite(last_hit_[k]) ? last_hit_[k] + kGuessMargin * min_axis_ : reach;
    const SeenHit hit = solid_->first_inside(foot, a, 0, 0, reach, scratch_, guess);
    if (!hit.hit) continue;
    at[k] = hit.t;
    last_hit_[k] = hit.t;
    push = std::max(push, depth[k] - hit.t);
  }
  if (!(push > 0)) return false;  // no part reaches its surface: the device is out
  const double back = push + 1e-6 * min_axis_;
  for (int j = 0; j < tool_.count; ++j) {
    const std::size_t k = std::size_t(j);
    gap_[k] = std::isfinite(at[k]) ? std::max(0.0, at[k] - (depth[k] - back)) : kInf;
  }
  x_ = y - back * a;
  pose(x_, q);
  return true;
}

bool SeenCompoundProxy::contact_point(Eigen::Vector3d& c, int& heaviest) const noexcept {
  const double band = kContactBand * min_axis_;
  double sum = 0, most = 0;
  c.setZero();
  heaviest = -1;
  for (int j = 0; j < tool_.count; ++j) {
    const double g = gap_[std::size_t(j)] / band;
    if (!(g < 1)) continue;
    const double w = 1 - g * g;
    c += w * parts_[std::size_t(j)].surface_point(axis_);
    sum += w;
    if (w > most) most = w, heaviest = j;
  }
  if (!(sum > 0)) return false;
  c /= sum;
  return true;
}

void SeenCompoundProxy::read_normal(const Eigen::Vector3d& point, double h, double depth) noexcept {
  // As SeenProxy::read_normal: a contact's first reading at once, later ones one ray a tick once
  // the point has moved kNormalReuse from the last reading.
  const Eigen::Vector3d& a = axis_;
  const double back = std::min(depth, kNormalEye * h / kNormalSpan);
  if (normal_.squaredNorm() == 0) {
    target_normal_ = solid_->normal(point, a, h, h, back, scratch_);
    normal_at_ = point;
    normal_ = target_normal_;
    pending_ray_ = -1;
    return;
  }
  if (pending_ray_ < 0 && (point - normal_at_).norm() >= kNormalReuse * min_axis_) {
    pending_ray_ = 0;
    pending_at_ = point;
    pending_back_ = back;
    pending_h_ = h;
  }
  if (pending_ray_ < 0) return;
  pending_hits_[std::size_t(pending_ray_)] =
      solid_->normal_ray(pending_at_, a, pending_ray_, pending_h_, pending_h_, pending_back_, scratch_);
  if (++pending_ray_ < SeenSolid::kNormalRays) return;
  target_normal_ = SeenSolid::normal_from(a, pending_hits_, pending_h_);
  normal_at_ = pending_at_;
  pending_ray_ = -1;
}

RenderOutput SeenCompoundProxy::render(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                                       const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                       double dt) noexcept {
  RenderOutput out;
  out.proxy = position;
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
  if (!in_contact_) in_contact_ = begin_contact(position, q);
  const Eigen::Vector3d before = x_;
  if (in_contact_) {
    friction_step_ = friction_.update(was_in_contact, normal_, position, x_, device_step, radius_);
    in_contact_ = hold(position, friction_step_.goal, q);
  }
  q_ = q;
  Eigen::Vector3d c;
  int heaviest = -1;
  if (!in_contact_ || !contact_point(c, heaviest)) {
    x_ = position;
    release();
    return out;
  }
  // The normal at the seen points under the touching parts' leading points.
  const double h = kNormalSpan * middle_semi_axis(parts_[std::size_t(heaviest)]);
  const double depth = (c - eye_).dot(axis_);
  read_normal(c, h, std::max(0.0, depth));
  const Eigen::Vector3d moved = x_ - before;
  const double slide = (moved - moved.dot(axis_) * axis_).norm();
  const double rate = std::min(-std::expm1(-dt / kNormalTau), -std::expm1(-slide / (kNormalPath * min_axis_)));
  const Eigen::Vector3d blended = normal_ + rate * (target_normal_ - normal_);
  normal_ = blended.norm() > 1e-9 ? Eigen::Vector3d(blended.normalized()) : target_normal_;

  out.proxy = x_;
  out.constraints = 1;
  out.force = coupling_.force(x_ - position, normal_, velocity, dt, {}, friction_step_, params_.mu_k);
  // Applied at the touching parts' surface points facing the contact, each weighted as in contact_point().
  const double band = kContactBand * min_axis_;
  Eigen::Vector3d lever = Eigen::Vector3d::Zero();
  double sum = 0;
  touching_ = 0;
  for (int j = 0; j < tool_.count; ++j) {
    const double g = gap_[std::size_t(j)] / band;
    if (!(g < 1)) continue;
    const double w = 1 - g * g;
    lever += w * (parts_[std::size_t(j)].surface_point(-normal_) - x_);
    sum += w;
    ++touching_;
  }
  out.torque = (lever / sum).cross(out.force);
  out.counts.contacts = std::uint32_t(touching_);
  return out;
}

}  // namespace gshaptics
