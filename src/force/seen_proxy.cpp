#include "gshaptics/force/seen_proxy.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace gshaptics {

SeenProxy::SeenProxy(const CollisionWorld& world, const ProxyParams& params, double f_max)
    : solid_(world), params_(params), coupling_(params, f_max) {}

void SeenProxy::reset() noexcept {
  started_ = false;
  in_contact_ = false;
  normal_.setZero();
  coupling_.release();
}

bool SeenProxy::begin_contact(const Eigen::Vector3d& device, double radius) noexcept {
  const Eigen::Vector3d d = device - proxy_;
  const double len = d.norm();
  if (!(len > 1e-9 * radius)) return false;
  const Eigen::Vector3d u = d / len;
  // The eye: as far behind the proxy as it is still seen from (at most seen_window R), so a
  // surface behind it (the floor it lifted off) does not hold it, and a faint layer it is in does.
  double eye = 0;
  const bool leaving = u.dot(normal_) > 0;  // away from the surface it last rested on
  const SeenHit hit = solid_.push(proxy_, u, radius, params_.seen_window * radius, len, leaving, eye, scratch_);
  if (!hit.hit) return false;
  const double back = radius + eye;
  axis_ = u;
  eye_ = proxy_ + (radius - back) * u;
  normal_.setZero();  // read afresh by hold()
  pending_ray_ = -1;
  last_hit_ = std::numeric_limits<double>::quiet_NaN();
  return true;
}

bool SeenProxy::hold(const Eigen::Vector3d& device, double radius, double dt) noexcept {
  const Eigen::Vector3d& a = axis_;
  const double depth = (device + radius * a - eye_).dot(a);  // the device's leading point, from the eye plane
  if (!(depth > 0)) return false;
  const Eigen::Vector3d foot = device + (radius - depth) * a;  // its ray's origin on the eye plane
  // (The surface moves little from tick to tick: the layers up to just past the last hit are
  // read first, those deeper only when the surface is not among them.)
  const double guess = std::isfinite(last_hit_) ? last_hit_ + kGuessMargin * radius : depth;
  const SeenHit hit = solid_.first_inside(foot, a, 0, 0, depth, scratch_, guess);
  if (!hit.hit || hit.t >= depth) return false;  // the device is out of the surface
  last_hit_ = hit.t;
  const double t = std::max(0.0, hit.t - 1e-6 * radius);
  proxy_ = foot + (t - radius) * a;
  read_normal(foot + hit.t * a, radius, hit.t);
  const Eigen::Vector3d blended = normal_ + (1 - std::exp(-dt / kNormalTau)) * (target_normal_ - normal_);
  normal_ = blended.norm() > 1e-9 ? Eigen::Vector3d(blended.normalized()) : target_normal_;
  return true;
}

void SeenProxy::read_normal(const Eigen::Vector3d& point, double radius, double depth) noexcept {
  // The normal is read afresh once the point moved kNormalReuse R from the last reading, and
  // smoothed over kNormalTau (each reading carries the seen surface's noise). The first reading of
  // a contact takes its four rays at once; a later one takes one ray a tick (the solid does not
  // move, so the rays of a reading fixed at its start give the same normal, three ticks later,
  // and no tick pays for four).
  const Eigen::Vector3d& a = axis_;
  const double h = kNormalSpan * radius, back = std::min(depth, kNormalEye * radius);
  if (normal_.squaredNorm() == 0) {
    target_normal_ = solid_.normal(point, a, h, radius, back, scratch_);
    normal_at_ = point;
    normal_ = target_normal_;
    pending_ray_ = -1;
    return;
  }
  if (pending_ray_ < 0 && (point - normal_at_).norm() >= kNormalReuse * radius) {
    pending_ray_ = 0;
    pending_at_ = point;
    pending_back_ = back;
  }
  if (pending_ray_ < 0) return;
  pending_hits_[std::size_t(pending_ray_)] = solid_.normal_ray(pending_at_, a, pending_ray_, h, radius, pending_back_, scratch_);
  if (++pending_ray_ < 4) return;
  target_normal_ = SeenSolid::normal_from(pending_at_, a, pending_hits_, h);
  normal_at_ = pending_at_;
  pending_ray_ = -1;
}

RenderOutput SeenProxy::render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept {
  RenderOutput out;
  out.proxy = tool.center;
  if (!tool.valid() || !velocity.allFinite() || !(dt > 0)) {
    out.status = QueryStatus::kInvalidTool;
    return out;
  }
  const double r = tool.bounding_radius();
  if (!started_) {
    proxy_ = tool.center;
    started_ = true;
  }
  // A contact lasts while the device's leading point is past the seen surface along the axis it
  // came in on: the proxy rests on that surface above the device (a height field along the axis).
  if (!in_contact_) in_contact_ = begin_contact(tool.center, r);
  if (in_contact_) in_contact_ = hold(tool.center, r, dt);
  if (!in_contact_) {
    proxy_ = tool.center;
    coupling_.release();
    return out;
  }
  out.proxy = proxy_;
  out.constraints = 1;
  const Eigen::Vector3d e = proxy_ - tool.center;
  const Eigen::Vector3d& n = normal_;
  out.force = coupling_.force(e, n, velocity, dt, {}, FrictionStep{}, 0.0);
  out.counts.contacts = 1;
  return out;
}

}  // namespace gshaptics
