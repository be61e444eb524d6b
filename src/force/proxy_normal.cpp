#include "gshaptics/force/proxy_normal.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

ProxyNormal::ProxyNormal(const CollisionWorld& world, const ProxyParams& params)
    : world_(&world), params_(params), crests_(world) {
  shade_.set_turn_tolerance(params.shading_turn * M_PI / 180);
}

void ProxyNormal::forget() noexcept {
  shade_.reset();
  shade_device_.reset();
  face_.setZero();
  crest_cache_.reset();
}

Eigen::Vector3d ProxyNormal::shaded(const ToolEllipsoid& tool, const Eigen::Vector3d& p,
                                    std::span<const Contact> blockers, const Eigen::Vector3d& up) noexcept {
  const ProxyParams& pp = params_;
  const double r = tool.bounding_radius();
  // Recomputed once the proxy has moved `shading_reuse` tool radii (the next reading prepared
  // over the ticks before, a `shading_budget` a tick). The spacing is the blockers' largest
  // middle semi-axis; the scale, the larger of it and r. The tool's inscribed ball rests free at
  // p, and the surface under it is the tool's support distance along the support normal away.
  spacing_ = shading_spacing(*world_, blockers);
  const bool resting = !up.isZero(0);
  const double surface = resting ? tool.semi_axes.cwiseProduct(tool.rotation.conjugate() * up).norm() : 0.0;
  // (Where a disc of the other face overhangs a convex edge and blocks the tool beside it, its
  // flat side is not this face: FreeBall::face.)
  front_ = pp.overhang_falloff && resting ? front_face(*world_, blockers, p, kOverhangMargin * surface) : FrontFace{};
  ball_ = FreeBall{resting ? tool.semi_axes.minCoeff() : 0.0, up, surface, front_.normal, front_.height, front_.strength};
  // (The cached readings were made for the face they were given: one found, lost or turned by
  // more than kFaceTurn makes them stale, though the proxy did not move.)
  if (ball_.face.isZero(0) != face_.isZero(0) || (!face_.isZero(0) && ball_.face.dot(face_) < kFaceTurn)) {
    shade_.forget();
    shade_device_.forget();
  }
  face_ = ball_.face;
  return shade_.read_ahead(*world_, p, std::max(r, spacing_), pp.shading_kernel, pp.shading_reuse * r,
                           shading_scratch_, pp.shading_budget, ball_, spacing_, pp.shading_tail, pp.shading_visits);
}

Eigen::Vector3d ProxyNormal::refined(const Eigen::Vector3d& n, const ToolEllipsoid& tool, const Eigen::Vector3d& p,
                                     const Eigen::Vector3d& xd, FloaterRule& floaters) noexcept {
  const Eigen::Vector3d e = p - xd;
  const Eigen::Vector3d shaded = with_device_reading(n, p, xd, tool.bounding_radius(), e);
  return params_.corner_normal || params_.crest_hold ? with_crest_reading(shaded, tool, p, e, floaters) : shaded;
}

Eigen::Vector3d ProxyNormal::with_device_reading(const Eigen::Vector3d& n, const Eigen::Vector3d& p,
                                                 const Eigen::Vector3d& xd, double r, const Eigen::Vector3d& e) noexcept {
  // Where the field turns slowly, it is also read where the device would rest: the device lifted
  // along n to the proxy's level, at most device_shading tool radii from the proxy. A
  // frictionless god-object slides off the Gaussians' rims into the hollows between them, up to
  // half the spacing from where the device presses (6 mm round the 5 cm fidelity cylinder at 8 mm
  // spacing), and the field read there is right for a place the device is not at (force shading
  // of the device's contact point, as Morgenbesser & Srinivasan 1996 shade the surface point the
  // device presses). The two readings are blended while they agree (fully within
  // kDeviceShadingFrom degrees, not past kDeviceShadingTo): a crease's other wall, or the turn of
  // an edge, is not this face.
  const ProxyParams& pp = params_;
  if (!(pp.device_shading > 0) || shade_.reuse_within(pp.shading_reuse * r) < pp.shading_reuse * r) return n;
  Eigen::Vector3d lateral = (xd + e.dot(n) * n) - p;
  const double shift = lateral.norm(), cap = pp.device_shading * r;
  if (!(shift > 2 * pp.shading_reuse * r)) return n;  // (nearer, the proxy's own reading holds)
  if (shift > cap) lateral *= cap / shift;
  const Eigen::Vector3d& nd = shade_device_.read(*world_, p + lateral, std::max(r, spacing_), pp.shading_kernel,
                                                 pp.shading_reuse * r, device_scratch_, ball_, spacing_, pp.shading_tail,
                                                 pp.shading_visits);
  const double apart = std::atan2(nd.cross(n).norm(), nd.dot(n)) * 180 / M_PI;
  const double w = std::clamp((kDeviceShadingTo - apart) / (kDeviceShadingTo - kDeviceShadingFrom), 0.0, 1.0);
  return w > 0 && nd.dot(e) > 0 ? Eigen::Vector3d(((1 - w) * n + w * nd).normalized()) : n;
}

Eigen::Vector3d ProxyNormal::with_crest_reading(const Eigen::Vector3d& n, const ToolEllipsoid& tool,
                                                 const Eigen::Vector3d& p, const Eigen::Vector3d& e,
                                                 FloaterRule& floaters) noexcept {
  // At a clean convex corner the patch's support normal (edge_normal.h): the shaded field of the
  // face the proxy came to rest on tilts out of the corner's normal cone by its discs' jitter,
  // and a disc overhanging the corner (a fin) turns it further; the hull's normal stays in it.
  const ProxyParams& pp = params_;
  ToolEllipsoid at = tool;
  at.center = p;
  FloaterRule::Filter filter_state(floaters, pp.isolation_gap * tool.bounding_radius(), pp.pass_isolated);
  const BlockFilter filter = filter_state.block_filter();
  // (Where the last reading found a messy patch, the thin axes in more than three directions as
  // on most of a real scene, it is re-read only kCornerSearch radii on: its gather costs about
  // what a shaded reading does, and at the shaded normal's distance burger's probe run
  // gathered on 1.7 % of its contact ticks. Elsewhere at the shaded normal's reuse distance.)
  const double rho = tool.semi_axes.minCoeff();
  const double reuse = (crest_cache_.answer.messy ? kCornerSearch : pp.shading_reuse) * rho;
  // (With crest_hold, edges are read too, by their faces alone: for the renderer's hold, while the
  // force at an edge keeps the shaded field.)
  const EdgeNormalAnswer& answer = crests_.read(
      at, n, kCornerBand * rho, reuse, filter, crest_cache_,
      pp.crest_hold ? ConvexFeatures::kEdgeConesAndCorners : ConvexFeatures::kCorners, e);
  if (!pp.corner_normal || !answer.corner) return n;
  const Eigen::Vector3d cornered = EdgeNormal::blend(n, answer, e);
  // (Where a disc of the other face overhangs and blocks the tool (front_face), the shaded
  // normal already leaves it out, and the patch's hull does not: the tool rests against the
  // fin's flat side, inside the hull's corner, and its support normal leans off the fin, out
  // of the corner's normal cone. The hull's answer fades out as the overhang's strength rises.)
  return EdgeNormal::turned_toward(n, cornered, 1.0 - front_.strength);
}

}  // namespace gshaptics
