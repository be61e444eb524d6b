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
      seen_(params_.surface == ProxySurface::kSeen ? std::make_unique<SeenProxy>(world, params_, f_max) : nullptr) {}

void ProxyRenderer::set_tool(const CompoundTool& tool) {
  tool.validate("proxy: tool");
  const bool single = tool.is_single_at_tcp();
  if (!single && materials_)
    throw InputError("proxy: tool: a material map (--materials) serves one-part tools only, for now");
  check_proxy_params_apply(params_, single ? ProxyTool::kOnePart : ProxyTool::kCompound, "proxy: tool");
  if (single) {
    compound_.reset();
    return;
  }
  compound_ = std::make_unique<CompoundProxy>(*world_, tool, params_, f_max_);
}

void ProxyRenderer::set_materials(std::shared_ptr<const MaterialField> field) {
  if (field && seen_) throw InputError("proxy: a material map (--materials) is read on the ellipsoids only, for now (not with --surface seen)");
  if (field && compound_) throw InputError("proxy: a material map (--materials) serves one-part tools only, for now");
  materials_ = std::move(field);
  material_ = {};
  material_.stiffness = params_.stiffness;
  material_.damping = params_.damping;
  material_.mu_s = params_.mu_s;
  material_.mu_k = params_.mu_k;
}

void ProxyRenderer::apply_material(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double radius,
                                   const Eigen::Vector3d& contact, std::span<const Contact> blockers) noexcept {
  MaterialField::Weights target;  // (only the first material_count() entries are read)
  const std::size_t count = materials_->material_count();
  double held = 0;  // how much of the shares a material holds (0: none yet)
  for (std::size_t id = 0; id < count; ++id) held += shares_[id];
  if (materials_->contact_shares(blockers, target)) {
    if (!material_started_ || !(held > 0)) {
      for (std::size_t id = 0; id < count; ++id) shares_[id] = target[id];
    } else {
      // Followed along the path: a slide of ds moves the shares 1 - exp(-ds / R) of the way.
      const Eigen::Vector3d step = p - material_at_;
      const double a = 1 - std::exp(-(step - step.dot(n) * n).norm() / radius);
      for (std::size_t id = 0; id < count; ++id) shares_[id] += a * (target[id] - shares_[id]);
    }
  } else if (!material_started_) {
    for (std::size_t id = 0; id < count; ++id) shares_[id] = 0;  // the proxy's own until a Gaussian holds it
  }
  material_started_ = true;
  material_at_ = p;
  material_ = materials_->blend(shares_, contact);
  coupling_.set_gains(material_.stiffness, material_.damping);
  friction_.set_coefficients(material_.mu_s, material_.mu_k);
}

Eigen::Vector3d ProxyRenderer::add_material_forces(Eigen::Vector3d f, const Eigen::Vector3d& contact,
                                                  const Eigen::Vector3d& n, const Eigen::Vector3d& velocity,
                                                  double radius) noexcept {
  if (material_.viscosity > 0) f -= material_.viscosity * (velocity - velocity.dot(n) * n);
  if (material_.texture_gain > 0) {
    f += texture_.force(*world_, contact, n, radius, material_.stiffness, material_.texture_gain, material_.procedural);
    const double fn = f.dot(n);
    if (fn < 0) f -= fn * n;  // the relief never pulls the tool in
  } else {
    texture_.release();
  }
  if (f.norm() > f_max_) f *= f_max_ / f.norm();
  return f;
}

RenderOutput ProxyRenderer::render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                                            const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                            double dt) noexcept {
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
  texture_.release();
  material_started_ = false;
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
  solver_.reset();
  forget_contact();
  normal_.setZero();
  last_move_ = {};
}

Eigen::Vector3d ProxyRenderer::shaded_normal(const Eigen::Vector3d& center, double radius) const noexcept {
  return gshaptics::shaded_normal(*world_, center, radius, params_.shading_kernel, {}, 0, params_.shading_tail);
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
  if (seen_) return seen_->render(tool, velocity, dt);
  const Eigen::Vector3d& xd = tool.center;
  const double r = tool.bounding_radius();
  const Eigen::Vector3d device_step = follow_device(tool);

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
  // 3. The contact normal (ProxyNormal: shaded, Morgenbesser & Srinivasan 1996; device-side;
  // corner), unless the proxy is caught in a pocket: then it rejoins the device.
  Eigen::Vector3d n;
  if (!contact_normal(tool, move, n)) {
    out.proxy = xd;
    out.constraints = 0;
    return out;
  }
  normal_ = n;
  in_contact_ = true;
  // 4. The virtual coupling gives the force (Colgate, Stanley & Brown 1995), on a spring whose
  // depth along n is bounded so that the shaded normal's turns add no energy (SpringEnergyBound).
  // (With a material map, the properties under the proxy: stiffness, damping and friction from
  // this tick on, and a viscous drag on the device's tangential velocity.)
  Eigen::Vector3d contact = p;  // where the tool meets the surface (with materials: their reliefs are read there)
  if (materials_) {
    ToolEllipsoid at = tool;
    at.center = p;
    contact = at.surface_point(-n);
    apply_material(p, n, r, contact, blockers);
  }
  Eigen::Vector3d spring = e;
  spring -= (e.dot(n) - coupling_.bounded_depth(e, n)) * n;
  out.force = coupling_.force(spring, n, velocity, dt, blockers, fr, materials_ ? material_.mu_k : params_.mu_k);
  if (materials_) out.force = add_material_forces(out.force, contact, n, velocity, r);
  return out;
}

}  // namespace gshaptics
