#include "gshaptics/force/proxy_renderer.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/error.h"
#include "gshaptics/force/shaded_normal.h"

namespace gshaptics {

namespace {

const ProxyParams& validated(const ProxyParams& p, double f_max) {
  validate_proxy_params(p, "proxy");
  if (!(f_max > 0)) throw InputError("proxy: f_max must be > 0 N");
  return p;
}

}  // namespace

ProxyRenderer::ProxyRenderer(const CollisionWorld& world, const ProxyParams& params, double f_max)
    : world_(&world),
      params_(validated(params, f_max)),
      f_max_(f_max),
      solver_(world, params_),
      normals_(world, params_),
      friction_(params_.mu_s, params_.mu_k),
      coupling_(params_, f_max),
      seen_(params_.surface == ProxySurface::kSeen ? std::make_unique<SeenProxy>(world, params_, f_max) : nullptr) {
  own_material_.stiffness = params_.stiffness;
  own_material_.damping = params_.damping;
  own_material_.mu_s = params_.mu_s;
  own_material_.mu_k = params_.mu_k;
}

void ProxyRenderer::set_tool(const CompoundTool& tool) {
  tool.validate("proxy: tool");
  const bool single = tool.is_single_at_tcp();
  check_proxy_params_apply(params_, single ? ProxyTool::kOnePart : ProxyTool::kCompound, "proxy: tool");
  compound_.reset();
  seen_compound_.reset();
  // On the seen solid the one-part proxy is a sphere of the tool's bounding radius: any other
  // shape, one ellipsoid at the TCP included, gets the seen compound proxy.
  if (seen_ && !(single && ToolEllipsoid::is_sphere(tool.parts[0].semi_axes))) {
    seen_compound_ = std::make_unique<SeenCompoundProxy>(seen_->solid(), tool, params_, f_max_);
    if (follower_) seen_compound_->set_materials(follower_->shared_field());
    return;
  }
  if (single) return;
  compound_ = std::make_unique<CompoundProxy>(*world_, tool, params_, f_max_);
  if (follower_) compound_->set_materials(follower_->shared_field());
}

void ProxyRenderer::set_materials(std::shared_ptr<const MaterialField> field) {
  follower_ = field ? std::make_unique<MaterialFollower>(field, params_) : nullptr;
  if (seen_) seen_->set_follower(follower_.get());
  if (compound_) compound_->set_materials(field);
  if (seen_compound_) seen_compound_->set_materials(field);
}

const MaterialBlend& ProxyRenderer::material() const noexcept {
  if (compound_active_ && compound_->material() != nullptr) return *compound_->material();
  if (seen_compound_active_ && seen_compound_->material() != nullptr) return *seen_compound_->material();
  return follower_ ? follower_->blend() : own_material_;
}

void ProxyRenderer::apply_material(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double radius,
                                   const Eigen::Vector3d& contact, std::span<const Contact> blockers) noexcept {
  apply_blend(follower_->update(p, n, radius, contact, blockers), coupling_, friction_);
}

RenderOutput ProxyRenderer::render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                                            const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                            double dt) noexcept {
  seen_compound_active_ = false;
  if (seen_compound_ && parts.size() == std::size_t(seen_compound_->tool().count)) {
    compound_active_ = false;
    seen_compound_active_ = true;
    const Eigen::Quaterniond orientation = parts[0].rotation * seen_compound_->tool().parts[0].rotation.conjugate();
    return seen_compound_->render(tcp, orientation, velocity, angular_velocity, dt);
  }
  if (!compound_ || parts.size() != std::size_t(compound_->tool().count)) {
    compound_active_ = false;
    return ForceRenderer::render_compound(parts, tcp, velocity, angular_velocity, dt);
  }
  compound_active_ = true;
  // The device's orientation from any part: its world rotation is orientation x its own.
  const Eigen::Quaterniond orientation = parts[0].rotation * compound_->tool().parts[0].rotation.conjugate();
  return compound_->render(tcp, orientation, velocity, angular_velocity, dt);
}

void ProxyRenderer::leave_contact() noexcept {
  friction_.reset();
  coupling_.release();
  if (follower_) follower_->release();
  in_contact_ = sticking_ = false;
}

void ProxyRenderer::forget_contact() noexcept {
  leave_contact();
  normals_.forget();
}

void ProxyRenderer::restart_at(const ToolEllipsoid& tool) noexcept {
  solver_.place(tool);
  forget_contact();
}

void ProxyRenderer::reset() noexcept {
  if (compound_) compound_->reset();
  if (seen_) seen_->reset();
  if (seen_compound_) seen_compound_->reset();
  solver_.reset();
  forget_contact();
  normal_.setZero();
  last_move_ = {};
}

Eigen::Vector3d ProxyRenderer::shaded_normal(const Eigen::Vector3d& center, double radius) const noexcept {
  return gshaptics::shaded_normal(*world_, center, radius, params_.shading_kernel, {}, 0, params_.shading_tail,
                                  params_.shading_visits);
}

Eigen::Vector3d ProxyRenderer::follow_device(const ToolEllipsoid& tool) noexcept {
  const Eigen::Vector3d& xd = tool.center;
  bool replace = !solver_.placed() || (xd - last_device_).norm() > params_.teleport * tool.bounding_radius();
  if (!replace && !tool.rotation.isApprox(last_rotation_, 1e-12)) {
    ToolEllipsoid at = tool;
    at.center = solver_.position();
    replace = solver_.blocked(at);  // the tool turned into geometry
  }
  if (replace) restart_at(tool);
  const Eigen::Vector3d device_step = xd - last_device_;
  last_device_ = xd;
  last_rotation_ = tool.rotation;
  return device_step;
}

bool ProxyRenderer::held_on_crest(const Eigen::Vector3d& xd, const Eigen::Vector3d& velocity, double radius) const noexcept {
  // A god-object on a polyhedron rests on an edge or a vertex while the device lies in that
  // feature's normal cone from it: two or three constraints are active (Zilles & Salisbury 1995).
  // On the Gaussians the crest is the discs' rims, bumpy at their scale, and the frictionless
  // proxy rolls off it toward either face as soon as the device passes under it. So while the
  // spring lies inside the crest's cone (by kCrestMargin) and the device moves along it (a press
  // or its release, or rests), the proxy holds. A device moving across the spring (a slide over
  // the edge) lets the proxy roll over the crest as before.
  if (!params_.crest_hold || !in_contact_) return false;
  const EdgeNormalAnswer* crest = normals_.crest();
  if (crest == nullptr) return false;
  const Eigen::Vector3d e = solver_.position() - xd;
  const double speed = velocity.norm();
  const bool along = speed <= kCrestStill || std::abs(velocity.dot(e)) >= kCrestAlong * speed * e.norm();
  // ... and the device lies on the line from the proxy through the crest's apex (across an
  // edge's line), within kCrestCorridor tool radii: short of the crest or under it. A device
  // beside it, as one sliding down the side face after passing over the edge, is not pressing
  // into it.
  const Eigen::Vector3d& t = crest->edge_line;  // (zero at a corner)
  Eigen::Vector3d axis = solver_.position() - crest->apex, from_apex = xd - crest->apex;
  axis -= axis.dot(t) * t;
  from_apex -= from_apex.dot(t) * t;
  if (!(axis.norm() > 0)) return false;
  const double off_axis = from_apex.cross(axis.normalized()).norm();
  return along && off_axis <= kCrestCorridor * radius && EdgeNormal::crest_depth(*crest, e) >= kCrestMargin;
}

bool ProxyRenderer::contact_normal(const ToolEllipsoid& tool, const ProxyMove& move, Eigen::Vector3d& n) noexcept {
  const Eigen::Vector3d& p = move.position;
  const Eigen::Vector3d e = p - tool.center;
  n = normals_.shaded(tool, p, solver_.blockers(), solver_.support_normal());
  if (caught_in_pocket(n, e, [&] { return !solver_.blocked(tool); })) {
    restart_at(tool);
    return false;
  }
  if (!(n.dot(e) > 0)) {
    // (The first plane is known only when the proxy moved this tick; a sticking proxy keeps normal_.)
    const Eigen::Vector3d fallback = !sticking_ && move.constraints > 0 ? move.first_normal : normal_;
    n = e.norm() > 0 ? Eigen::Vector3d(e.normalized()) : fallback;
  }
  n = normals_.refined(n, tool, p, tool.center, solver_.floater_rule());
  return true;
}

RenderOutput ProxyRenderer::render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept {
  RenderOutput out;
  out.proxy = tool.center;
  if (!tool.valid() || !velocity.allFinite() || !(dt > 0)) {
    out.status = QueryStatus::kInvalidTool;
    return out;
  }
  if (seen_compound_) {  // (set_tool gave a tool that is not a sphere)
    const Eigen::Quaterniond orientation = tool.rotation * seen_compound_->tool().parts[0].rotation.conjugate();
    return seen_compound_->render(tool.center, orientation, velocity, Eigen::Vector3d::Zero(), dt);
  }
  if (seen_) return seen_->render(tool, velocity, dt);
  const Eigen::Vector3d& xd = tool.center;
  const double r = tool.bounding_radius();
  const Eigen::Vector3d device_step = follow_device(tool);

  // 1. Friction decides where the proxy heads (Salisbury et al. 1995).
  const FrictionStep fr = friction_.update(in_contact_, normal_, xd, solver_.position(), device_step, r);
  sticking_ = fr.sticking;
  // 2. The god-object moves toward it (Zilles & Salisbury 1995), or holds on a crest it is
  // pressed into.
  const bool on_crest = !fr.sticking && held_on_crest(xd, velocity, r);
  const Eigen::Vector3d crest_line = on_crest ? normals_.crest()->edge_line : Eigen::Vector3d::Zero();
  const ProxyMove move = solver_.move_toward(tool, fr.goal, fr.sticking || on_crest);
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
  // 3. The contact normal (ProxyNormal: shaded, Morgenbesser & Srinivasan 1996; device-side;
  // corner), unless the proxy is caught in a pocket: then it rejoins the device.
  Eigen::Vector3d n;
  if (!contact_normal(tool, move, n)) {
    out.proxy = xd;
    out.constraints = 0;
    return out;
  }
  // On a crest the spring's part across it (all of it at a corner) pushes back: along an edge the
  // god-object is free to slide, so the spring's part along the line is no force.
  if (on_crest) n = (e - e.dot(crest_line) * crest_line).normalized();
  normal_ = n;
  in_contact_ = true;
  // 4. The virtual coupling gives the force (Colgate, Stanley & Brown 1995), on a spring whose
  // depth along n is bounded so that the shaded normal's turns add no energy (SpringEnergyBound).
  // (With a material map, the properties under the proxy: stiffness, damping and friction from
  // this tick on, and a viscous drag on the device's tangential velocity.)
  Eigen::Vector3d contact = p;  // where the tool meets the surface (with materials: their reliefs are read there)
  if (follower_) {
    ToolEllipsoid at = tool;
    at.center = p;
    contact = at.surface_point(-n);
    apply_material(p, n, r, contact, blockers);
  }
  Eigen::Vector3d spring = e;
  spring -= (e.dot(n) - coupling_.bounded_depth(e, n)) * n;
  out.force = coupling_.force(spring, n, velocity, dt, blockers, fr, follower_ ? follower_->blend().mu_k : params_.mu_k);
  if (follower_) {
    out.force = follower_->add_forces(*world_, out.force, contact, n, velocity, r, f_max_, dt);
    out.texture_rms = float(follower_->texture_rms());
    out.vibration = float(follower_->blend().vibration);
  }
  return out;
}

}  // namespace gshaptics
