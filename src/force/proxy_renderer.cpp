#include "gshaptics/force/proxy_renderer.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/error.h"
#include "gshaptics/force/shaded_normal.h"

namespace gshaptics {

namespace {

const ProxyParams& validated(const ProxyParams& p, double f_max) {
  if (!(p.stiffness > 0) || !std::isfinite(p.stiffness)) throw InputError("proxy: stiffness must be > 0 N/m");
  if (!(p.damping >= 0) || !std::isfinite(p.damping)) throw InputError("proxy: damping must be >= 0 N s/m");
  if (!(f_max > 0)) throw InputError("proxy: f_max must be > 0 N");
  if (!(p.mu_s >= 0 && p.mu_k >= 0 && p.mu_k <= p.mu_s) || !std::isfinite(p.mu_s))
    throw InputError("proxy: friction needs 0 <= mu_k <= mu_s");
  if (p.substeps < 1 || p.substeps > 16) throw InputError("proxy: substeps must be in [1, 16]");
  if (!(p.isolation_gap >= 0) || !std::isfinite(p.isolation_gap)) throw InputError("proxy: isolation_gap must be >= 0");
  if (p.floater_cluster < 1 || p.floater_cluster > FloaterTest::kLargestCluster)
    throw InputError("proxy: floater_cluster must be in [1, " + std::to_string(FloaterTest::kLargestCluster) + "]");
  if (!(p.shading_turn >= 0) || !std::isfinite(p.shading_turn)) throw InputError("proxy: shading_turn must be >= 0 degrees");
  if (!(p.shading_tail > 0) || !std::isfinite(p.shading_tail)) throw InputError("proxy: shading_tail must be > 0");
  if (!(p.device_shading >= 0) || !std::isfinite(p.device_shading))
    throw InputError("proxy: device_shading must be >= 0 tool radii");
  if (!(p.shading_kernel > 0) || !(p.teleport > 0) || !(p.tau_opacity >= 0))
    throw InputError("proxy: shading_kernel and teleport must be > 0, tau_opacity >= 0");
  return p;
}

ProxySolverParams solver_params(const ProxyParams& p) {
  ProxySolverParams s;
  s.substeps = p.substeps;
  s.lift = p.lift;
  s.pass_isolated = p.pass_isolated;
  s.isolation_gap = p.isolation_gap;
  s.floater_cluster = p.floater_cluster;
  s.shading_kernel = p.shading_kernel;
  return s;
}

}  // namespace

ProxyRenderer::ProxyRenderer(const CollisionWorld& world, const ProxyParams& params, double f_max)
    : world_(&world),
      params_(validated(params, f_max)),
      solver_(world, solver_params(params)),
      friction_(params.mu_s, params.mu_k),
      coupling_(params.stiffness, params.damping, f_max, params.opacity_stiffness, params.tau_opacity),
      corners_(world) {
  shade_.set_turn_tolerance(params_.shading_turn * M_PI / 180);
}

void ProxyRenderer::set_tool(const CompoundTool& tool) {
  tool.validate("proxy: tool");
  if (tool.is_single_at_tcp()) {
    compound_.reset();
    return;
  }
  CompoundProxyParams c;
  c.stiffness = params_.stiffness;
  c.damping = params_.damping;
  c.substeps = params_.substeps;
  c.pass_isolated = params_.pass_isolated;
  c.shading_kernel = params_.shading_kernel;
  c.shading_reuse = params_.shading_reuse;
  c.shading_tail = params_.shading_tail;
  c.shading_turn = params_.shading_turn;
  c.isolation_gap = params_.isolation_gap;
  c.floater_cluster = params_.floater_cluster;
  c.teleport = params_.teleport;
  c.mu_s = params_.mu_s;
  c.mu_k = params_.mu_k;
  c.energy_bound = params_.energy_bound;
  c.near_lists = params_.near_lists;
  c.face_average = params_.face_average;
  compound_ = std::make_unique<CompoundProxy>(*world_, tool, c);
  tool_ = tool;
}

RenderOutput ProxyRenderer::render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                                            const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                            double dt) noexcept {
  if (!compound_ || parts.size() != std::size_t(tool_.count)) {
    compound_active_ = false;
    return ForceRenderer::render_compound(parts, tcp, velocity, angular_velocity, dt);
  }
  compound_active_ = true;
  // The device's orientation from any part: its world rotation is orientation x its own.
  const Eigen::Quaterniond orientation = parts[0].rotation * tool_.parts[0].rotation.conjugate();
  return compound_->render(tcp, orientation, velocity, angular_velocity, dt);
}

void ProxyRenderer::leave_contact() noexcept {
  friction_.reset();
  coupling_.release();
  bound_.release();
  in_contact_ = sticking_ = false;
}

void ProxyRenderer::forget_contact() noexcept {
  leave_contact();
  shade_.reset();
  shade_device_.reset();
  face_.setZero();
  corner_cache_.reset();
}

void ProxyRenderer::restart_at(const ToolEllipsoid& tool) noexcept {
  solver_.place(tool);
  forget_contact();
}

void ProxyRenderer::reset() noexcept {
  if (compound_) compound_->reset();
  solver_.reset();
  forget_contact();
  normal_.setZero();
  last_move_ = {};
}

Eigen::Vector3d ProxyRenderer::shaded_normal(const Eigen::Vector3d& center, double radius) const noexcept {
  return gshaptics::shaded_normal(*world_, center, radius, params_.shading_kernel, {}, 0, params_.shading_tail);
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
  bool replace = !solver_.placed() || (xd - last_device_).norm() > params_.teleport * r;
  if (!replace && !tool.rotation.isApprox(last_rotation_, 1e-12)) {
    ToolEllipsoid at = tool;
    at.center = solver_.position();
    replace = solver_.blocked(at);  // the tool turned into geometry
  }
  if (replace) restart_at(tool);
  const Eigen::Vector3d device_step = xd - last_device_;
  last_device_ = xd;
  last_rotation_ = tool.rotation;

  // 1. Friction decides where the proxy heads (Salisbury et al. 1995).
  const FrictionStep fr = friction_.update(in_contact_, normal_, xd, solver_.position(), device_step, r);
  sticking_ = fr.sticking;
  // 2. The god-object moves toward it (Zilles & Salisbury 1995).
  const ProxyMove move = solver_.move_toward(tool, fr.goal, fr.sticking);
  last_move_ = move;
  const Eigen::Vector3d& p = move.position;
  const std::span<const Contact> blockers = solver_.blockers();
  out.proxy = p;
  out.constraints = std::uint8_t(move.constraints);
  out.counts.candidates = move.candidates;
  out.counts.contacts = std::uint32_t(blockers.size());

  const Eigen::Vector3d e = p - xd;
  if (move.constraints == 0 && e.norm() <= 1e-6 * r) {  // free: the proxy is on the device
    leave_contact();
    return out;
  }
  // 3. The contact normal: shaded (Morgenbesser & Srinivasan 1996), recomputed once the proxy
  // has moved `shading_reuse` tool radii (the next reading prepared over the ticks before, a
  // `shading_budget` a tick), unless it disagrees with where the proxy holds the device.
  // (The spacing is the blockers' largest middle semi-axis; the scale, the larger of it and r.)
  // The tool's inscribed ball rests free at p, and the surface under it is the tool's support
  // distance along the support normal away (FreeBall).
  const double spacing = shading_spacing(*world_, blockers);
  const Eigen::Vector3d& up = solver_.support_normal();
  const bool resting = !up.isZero(0);
  const double surface = resting ? tool.semi_axes.cwiseProduct(tool.rotation.conjugate() * up).norm() : 0.0;
  // (Where a disc of the other face overhangs a convex edge and blocks the tool beside it, its
  // flat side is not this face: FreeBall::face.)
  const FrontFace front =
      params_.overhang_falloff && resting ? front_face(*world_, blockers, p, kOverhangMargin * surface) : FrontFace{};
  const FreeBall ball{resting ? tool.semi_axes.minCoeff() : 0.0, up, surface, front.normal, front.height,
                      front.strength};
  // (The cached readings were made for the face they were given: one found, lost or turned by
  // more than kFaceTurn makes them stale, though the proxy did not move.)
  if (ball.face.isZero(0) != face_.isZero(0) || (!face_.isZero(0) && ball.face.dot(face_) < kFaceTurn)) {
    shade_.forget();
    shade_device_.forget();
  }
  face_ = ball.face;
  Eigen::Vector3d n = shade_.read_ahead(*world_, p, std::max(r, spacing), params_.shading_kernel,
                                        params_.shading_reuse * r, shading_scratch_, params_.shading_budget, ball, spacing,
                                        params_.shading_tail);
  if (n.dot(e) < 0 && !solver_.blocked(tool)) {
    // The surface says the device is on its free side, and the device's own pose is free: the
    // proxy is caught in a Gaussian-scale pocket (a sharp tool rim under a neighbouring disc's
    // rim) and would pull the hand into the surface. It rejoins the device instead.
    restart_at(tool);
    out.proxy = xd;
    out.constraints = 0;
    return out;
  }
  if (!(n.dot(e) > 0)) {
    // (The first plane is known only when the proxy moved this tick; a sticking proxy keeps normal_.)
    const Eigen::Vector3d fallback = !sticking_ && move.constraints > 0 ? move.first_normal : normal_;
    n = e.norm() > 0 ? Eigen::Vector3d(e.normalized()) : fallback;
  }
  // Where the field turns slowly, it is also read where the device would rest: the device lifted
  // along n to the proxy's level, at most device_shading tool radii from the proxy. A
  // frictionless god-object slides off the Gaussians' rims into the hollows between them, up to
  // half the spacing from where the device presses (6 mm round the 5 cm fidelity cylinder at 8 mm
  // spacing), and the field read there is right for a place the device is not at (force shading
  // of the device's contact point, as Morgenbesser & Srinivasan 1996 shade the surface point the
  // device presses). The two readings are blended while they agree (fully within
  // kDeviceShadingFrom degrees, not past kDeviceShadingTo): a crease's other wall, or the turn of
  // an edge, is not this face.
  if (params_.device_shading > 0 &&
      shade_.reuse_within(params_.shading_reuse * r) >= params_.shading_reuse * r) {
    Eigen::Vector3d lateral = (xd + e.dot(n) * n) - p;
    const double shift = lateral.norm(), cap = params_.device_shading * r;
    if (shift > 2 * params_.shading_reuse * r) {  // (nearer, the proxy's own reading holds)
      if (shift > cap) lateral *= cap / shift;
      const Eigen::Vector3d& nd =
          shade_device_.read(*world_, p + lateral, std::max(r, spacing), params_.shading_kernel,
                             params_.shading_reuse * r, device_scratch_, ball, spacing, params_.shading_tail);
      const double apart = std::atan2(nd.cross(n).norm(), nd.dot(n)) * 180 / M_PI;
      const double w = std::clamp((kDeviceShadingTo - apart) / (kDeviceShadingTo - kDeviceShadingFrom), 0.0, 1.0);
      if (w > 0 && nd.dot(e) > 0) n = ((1 - w) * n + w * nd).normalized();
    }
  }
  // At a clean convex corner the patch's support normal (edge_normal.h): the shaded field of the
  // face the proxy came to rest on tilts out of the corner's normal cone by its discs' jitter,
  // and a disc overhanging the corner (a fin) turns it further; the hull's normal stays in it.
  if (params_.corner_normal) {
    ToolEllipsoid at = tool;
    at.center = p;
    FloaterTest::Filter floaters(solver_.floater_test(), params_.isolation_gap * r);
    const BlockFilter filter = params_.pass_isolated ? floaters.block_filter() : BlockFilter{};
    // (Where the last reading found a messy patch, the thin axes in more than three directions as
    // on most of a real scene, it is re-read only kCornerSearch radii on: its gather costs about
    // what a shaded reading does, and at the shaded normal's distance burger's probe run
    // gathered on 1.7 % of its contact ticks. Elsewhere at the shaded normal's reuse distance.)
    const double rho = tool.semi_axes.minCoeff();
    const double reuse = (corner_cache_.answer.messy ? kCornerSearch : params_.shading_reuse) * rho;
    const Eigen::Vector3d cornered = EdgeNormal::blend(
        n, corners_.read(at, n, kCornerBand * rho, reuse, filter, corner_cache_, ConvexFeatures::kCorners, e), e);
    // (Where a disc of the other face overhangs and blocks the tool (front_face), the shaded
    // normal already leaves it out, and the patch's hull does not: the tool rests against the
    // fin's flat side, inside the hull's corner, and its support normal leans off the fin, out
    // of the corner's normal cone. The hull's answer fades out as the overhang's strength rises.)
    n = EdgeNormal::turned_toward(n, cornered, 1.0 - front.strength);
  }
  normal_ = n;
  in_contact_ = true;
  // 4. The virtual coupling gives the force (Colgate, Stanley & Brown 1995), on a spring whose
  // depth along n is bounded so that the shaded normal's turns add no energy (SpringEnergyBound).
  Eigen::Vector3d spring = e;
  if (params_.energy_bound) {
    const double k = params_.stiffness * coupling_.opacity_factor();
    spring -= (e.dot(n) - bound_.depth(e, n, k)) * n;
  }
  out.force = coupling_.force(spring, n, velocity, dt, blockers, fr, params_.mu_k);
  return out;
}

}  // namespace gshaptics
