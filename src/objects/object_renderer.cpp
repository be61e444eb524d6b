#include "gshaptics/objects/object_renderer.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <limits>

#include "gshaptics/error.h"

namespace gshaptics {
namespace {

// A tool ellipsoid in a body frame: x_body = R^T (x_world - p).
ToolEllipsoid to_body(const ToolEllipsoid& tool, const BodyPose& pose) noexcept {
  ToolEllipsoid b = tool;
  const Eigen::Quaterniond inv = pose.rotation.conjugate();
  b.center = inv * (tool.center - pose.position);
  b.rotation = (inv * tool.rotation).normalized();
  return b;
}

// The force, torque and proxy of a body's renderer, back in the world.
RenderOutput to_world(RenderOutput out, const BodyPose& pose) noexcept {
  out.force = pose.rotation * out.force;
  out.torque = pose.rotation * out.torque;
  out.proxy = pose.rotation * out.proxy + pose.position;
  return out;
}

void add_to(RenderOutput& sum, const RenderOutput& part, bool holds_proxy) noexcept {
  sum.force += part.force;
  sum.torque += part.torque;
  sum.counts.candidates += part.counts.candidates;
  sum.counts.prefiltered += part.counts.prefiltered;
  sum.counts.contacts += part.counts.contacts;
  if (part.status != QueryStatus::kOk) sum.status = part.status;
  if (holds_proxy) {
    sum.proxy = part.proxy;
    sum.constraints = part.constraints;
  }
  sum.texture_rms = std::max(sum.texture_rms, part.texture_rms);
  sum.vibration = std::max(sum.vibration, part.vibration);
}

}  // namespace

void load_shares(std::span<const Eigen::Vector3d> forces, std::span<double> share) noexcept {
  // The box-constrained dual: maximise sum_i b_i l_i - |sum_i l_i n_i|^2 / 2 over 0 <= l_i <= b_i
  // (b_i = |F_i|, n_i = F_i / b_i), by projected Gauss-Seidel (coordinate ascent: each step is
  // exact along its coordinate, so the objective never falls); F = sum_i l_i n_i, s_i = l_i / b_i.
  constexpr std::size_t kMost = kMaxObjects + 1;
  const std::size_t n = std::min({forces.size(), share.size(), kMost});
  std::array<Eigen::Vector3d, kMost> unit{};
  std::array<double, kMost> b{}, l{};
  double largest = 0;
  for (std::size_t i = 0; i < n; ++i) {
    b[i] = forces[i].norm();
    unit[i] = b[i] > 0 ? Eigen::Vector3d(forces[i] / b[i]) : Eigen::Vector3d::Zero();
    largest = std::max(largest, b[i]);
  }
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  for (int sweep = 0; sweep < kLoadShareSweeps && largest > 0; ++sweep) {
    double moved = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (!(b[i] > 0)) continue;
      const double next = std::clamp(l[i] + (b[i] - unit[i].dot(f)), 0.0, b[i]);
      f += (next - l[i]) * unit[i];
      moved = std::max(moved, std::abs(next - l[i]));
      l[i] = next;
    }
    if (moved <= 1e-12 * largest) break;
  }
  for (std::size_t i = 0; i < n; ++i) share[i] = b[i] > 0 ? l[i] / b[i] : 0.0;
}

ObjectRenderer::ObjectRenderer(std::unique_ptr<ForceRenderer> scene, std::vector<std::unique_ptr<ForceRenderer>> bodies,
                               std::vector<std::shared_ptr<const CollisionWorld>> worlds,
                               std::shared_ptr<ObjectDynamics> dynamics, const Eigen::Vector2d& support_coupling,
                               std::vector<SupportHole> holes, WholeScene whole)
    : scene_(std::move(scene)),
      bodies_(std::move(bodies)),
      worlds_(std::move(worlds)),
      dynamics_(std::move(dynamics)),
      support_coupling_(support_coupling),
      holes_(std::move(holes)),
      whole_(std::move(whole)) {
  if (dynamics_) hole_axes_ = support_axes(dynamics_->support().normal);
  if (!scene_ || !dynamics_) throw InputError("objects: a renderer needs the scene's renderer and the dynamics");
  if (bodies_.size() != dynamics_->size() || worlds_.size() != bodies_.size())
    throw InputError("objects: " + std::to_string(bodies_.size()) + " renderers for " +
                     std::to_string(dynamics_->size()) + " objects");
  for (const auto& b : bodies_)
    if (!b) throw InputError("objects: an object has no renderer");
  for (auto& f : object_force_) f.setZero();
  for (auto& p : object_proxy_) p.setZero();
  if (whole_.renderer && !(whole_.rest_tolerance > 0))
    throw InputError("objects: the whole scene's rest tolerance must be > 0 m, got " + std::to_string(whole_.rest_tolerance));
  for (std::size_t i = 0; i < worlds_.size(); ++i) {
    const CollisionWorld& w = *worlds_[i];
    body_centre_[i] = 0.5 * (w.bounds_lo() + w.bounds_hi());
    body_radius_[i] = 0.5 * (w.bounds_hi() - w.bounds_lo()).norm();
  }
}

bool ObjectRenderer::renders_compound() const noexcept {
  bool all = scene_->renders_compound() && (!whole_.renderer || whole_.renderer->renders_compound());
  for (const auto& b : bodies_) all = all && b->renders_compound();
  return all;
}

void ObjectRenderer::set_tool(const CompoundTool& tool) {
  scene_->set_tool(tool);
  for (auto& b : bodies_) b->set_tool(tool);
  if (whole_.renderer) whole_.renderer->set_tool(tool);
}

void ObjectRenderer::reset() noexcept {
  scene_->reset();
  for (auto& b : bodies_) b->reset();
  if (whole_.renderer) whole_.renderer->reset();
  whole_weight_ = 0;
  whole_live_ = true;
  dynamics_->reset();
  for (auto& f : object_force_) f.setZero();
  for (auto& p : object_proxy_) p.setZero();
  reaction_.fill({});
  merged_.clear();
  pending_ = 0;
  support_held_.fill(false);
}

void ObjectRenderer::set_executor(ParallelExecutor* executor, std::size_t min_candidates) {
  scene_->set_executor(executor, min_candidates);
  for (auto& b : bodies_) b->set_executor(executor, min_candidates);
  if (whole_.renderer) whole_.renderer->set_executor(executor, min_candidates);
}

void ObjectRenderer::gather_contacts(std::span<const Contact> contacts, std::uint8_t body, const BodyPose* pose) noexcept {
  for (Contact c : contacts) {
    c.body = body;
    if (pose != nullptr) c.center = pose->rotation * c.center + pose->position;
    if (!merged_.push(c)) return;
  }
}

void ObjectRenderer::step_dynamics(double dt) noexcept {
  const double h = dynamics_->params().timestep;
  pending_ += dt;
  int steps = 0;
  while (pending_ >= h * (1 - 1e-6) && steps < kMaxDynamicsSteps) {
    // The coupling holds over the whole tick: each step of it gets the tick's reaction.
    for (std::size_t i = 0; i < bodies_.size(); ++i)
      if (reaction_[i].force.squaredNorm() > 0)
        dynamics_->apply_wrench(i, reaction_[i].force, reaction_[i].point, reaction_[i].couple);
    dynamics_->step();
    pending_ -= h;
    ++steps;
  }
  if (steps == kMaxDynamicsSteps) pending_ = 0;  // a stall is not made up for
}

std::vector<SupportHole> support_holes(std::span<const RigidObject> objects, const SupportPlane& plane) {
  const std::array<Eigen::Vector3d, 2> uv = support_axes(plane.normal);
  const Eigen::Vector3d n = plane.normal.normalized();
  std::vector<SupportHole> out;
  for (const RigidObject& o : objects) {
    SupportHole hole;
    hole.height = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : o.hull_points) {
      const Eigen::Vector3d x = o.rest_origin + p;
      hole.area.extend(Eigen::Vector2d(uv[0].dot(x), uv[1].dot(x)));
      hole.height = std::min(hole.height, n.dot(x));
    }
    out.push_back(hole);
  }
  return out;
}

const SupportHole* ObjectRenderer::hole_at(const Eigen::Vector3d& p) const noexcept {
  const Eigen::Vector2d q(hole_axes_[0].dot(p), hole_axes_[1].dot(p));
  for (const SupportHole& h : holes_)
    if (h.area.contains(q)) return &h;
  return nullptr;
}

void ObjectRenderer::add_support(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                                 const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                 RenderOutput& sum) noexcept {
  const SupportPlane& plane = dynamics_->support();
  const Eigen::Vector3d& n = plane.normal;
  for (std::size_t k = 0; k < parts.size() && k < support_held_.size(); ++k) {
    const ToolEllipsoid& part = parts[k];
    const Eigen::Vector3d lowest = part.surface_point(-n);  // the part's support point along -n
    const SupportHole* hole = hole_at(lowest);
    const double depth = hole != nullptr ? hole->height - n.dot(lowest) : 0.0;
    bool& held = support_held_[k];
    if (!(depth > 0)) {
      held = false;
      continue;
    }
    // A part first met under the plane is held only if it is within a semi-axis of it (it came
    // down onto it, or across from the scene beside the hole), never from deep under the scene.
    if (!held) held = depth <= double(part.semi_axes.maxCoeff());
    if (!held) continue;
    const Eigen::Vector3d v = velocity + angular_velocity.cross(lowest - tcp);
    const double push = std::max(0.0, support_coupling_.x() * depth - support_coupling_.y() * v.dot(n));
    const Eigen::Vector3d f = push * n;
    sum.force += f;
    sum.torque += (lowest - tcp).cross(f);
  }
}

template <class RenderIn>
RenderOutput ObjectRenderer::render_all(RenderOutput scene_out, RenderIn&& render_in, double dt) noexcept {
  merged_.clear();
  gather_contacts(scene_->contacts(), 0, nullptr);
  // Every proxy's output in the world: the static scene's (with the support plane's), then each object's.
  std::array<RenderOutput, kMaxObjects + 1> outs;
  std::array<Eigen::Vector3d, kMaxObjects + 1> forces;
  outs[0] = scene_out;
  for (std::size_t i = 0; i < bodies_.size(); ++i) {
    const BodyPose pose = dynamics_->pose(i);
    outs[i + 1] = to_world(render_in(*bodies_[i], pose), pose);
    object_force_[i] = outs[i + 1].force;
    object_proxy_[i] = outs[i + 1].proxy;
    gather_contacts(bodies_[i]->contacts(), std::uint8_t(i + 1), &pose);
  }
  const std::size_t n = bodies_.size() + 1;
  for (std::size_t i = 0; i < n; ++i) forces[i] = outs[i].force;
  std::array<double, kMaxObjects + 1> share{};
  load_shares(std::span<const Eigen::Vector3d>(forces.data(), n), std::span<double>(share.data(), n));
  RenderOutput sum = scene_out;
  sum.force = share[0] * scene_out.force;
  sum.torque = share[0] * scene_out.torque;
  double strongest = scene_out.force.norm();
  for (std::size_t i = 0; i < bodies_.size(); ++i) {
    RenderOutput out = outs[i + 1];
    const double f = out.force.norm();
    out.force *= share[i + 1];
    out.torque *= share[i + 1];
    add_to(sum, out, f > strongest);
    strongest = std::max(strongest, f);
    // The reaction to its share: -s F at the proxy's tool centre, plus the couple -s tau (the
    // torque is about it).
    reaction_[i] = {-out.force, out.proxy, -out.torque};
  }
  step_dynamics(dt);
  return sum;
}

double ObjectRenderer::whole_weight(std::span<const ToolEllipsoid> parts) const noexcept {
  double weight = 1;
  for (std::size_t i = 0; i < bodies_.size(); ++i) {
    const BodyPose& now = dynamics_->pose(i);
    const BodyPose& rest = whole_.scene->poses[i];
    const Eigen::Vector3d at_rest = rest.rotation * body_centre_[i] + rest.position;
    const Eigen::Vector3d at_now = now.rotation * body_centre_[i] + now.position;
    // How far the object stands, where the tool is, from where the whole scene holds it: the rigid
    // motion's displacement at each part's centre (the whole scene's proxy reads it there as held).
    const Eigen::Quaterniond turn = now.rotation * rest.rotation.conjugate();
    double moved = 0;
    for (const ToolEllipsoid& part : parts)
      moved = std::max(moved, (turn * (part.center - rest.position) + now.position - part.center).norm());
    const double standing = std::clamp(1 - moved / whole_.rest_tolerance, 0.0, 1.0);
    if (standing == 1) continue;
    // Near: a part within the object's radius of its sphere as held or now (the whole scene's
    // proxy reads its Gaussians as held; the object itself is now elsewhere), fading out over
    // one more radius.
    const double margin = body_radius_[i];
    double gap = std::numeric_limits<double>::infinity();
    for (const ToolEllipsoid& part : parts) {
      const double reach = body_radius_[i] + double(part.semi_axes.maxCoeff());
      gap = std::min({gap, (part.center - at_rest).norm() - reach, (part.center - at_now).norm() - reach});
    }
    const double near = std::clamp(2 - gap / margin, 0.0, 1.0);
    weight *= 1 - near * (1 - standing);
  }
  return weight;
}

template <class RenderWhole>
RenderOutput ObjectRenderer::blend_whole(RenderOutput cut, std::span<const ToolEllipsoid> parts,
                                         RenderWhole&& render_whole) noexcept {
  const double w = whole_weight(parts);
  whole_weight_ = 0;
  if (w == 0) {  // an object near the tool has left: the whole scene's proxy rests until it is wanted again
    whole_live_ = false;
    return cut;
  }
  if (!whole_live_) {
    // It restarts only with the tool free (no contact, no force), as a proxy starts in free space.
    if (cut.counts.contacts != 0 || cut.force.squaredNorm() > 0) return cut;
    whole_.renderer->reset();
    whole_live_ = true;
  }
  const RenderOutput whole = render_whole();
  whole_weight_ = w;
  cut.force = w * whole.force + (1 - w) * cut.force;
  cut.torque = w * whole.torque + (1 - w) * cut.torque;
  cut.texture_rms = std::max(cut.texture_rms, decltype(cut.texture_rms)(w * whole.texture_rms));
  cut.vibration = std::max(cut.vibration, decltype(cut.vibration)(w * whole.vibration));
  if (whole.status != QueryStatus::kOk) cut.status = whole.status;
  return cut;
}

RenderOutput ObjectRenderer::render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept {
  RenderOutput scene_out = scene_->render(tool, velocity, dt);
  add_support(std::span<const ToolEllipsoid>(&tool, 1), tool.center, velocity, Eigen::Vector3d::Zero(), scene_out);
  const RenderOutput cut = render_all(
      scene_out,
      [&](ForceRenderer& r, const BodyPose& pose) {
        const Eigen::Vector3d v_rel = pose.rotation.conjugate() * (velocity - pose.velocity_at(tool.center));
        return r.render(to_body(tool, pose), v_rel, dt);
      },
      dt);
  if (!whole_.renderer) return cut;
  return blend_whole(cut, std::span<const ToolEllipsoid>(&tool, 1),
                     [&] { return whole_.renderer->render(tool, velocity, dt); });
}

RenderOutput ObjectRenderer::render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                                             const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                             double dt) noexcept {
  RenderOutput scene_out = scene_->render_compound(parts, tcp, velocity, angular_velocity, dt);
  add_support(parts, tcp, velocity, angular_velocity, scene_out);
  const RenderOutput cut = render_all(
      scene_out,
      [&](ForceRenderer& r, const BodyPose& pose) {
        std::array<ToolEllipsoid, kMaxToolParts> body_parts;
        const std::size_t n = std::min(parts.size(), body_parts.size());
        for (std::size_t k = 0; k < n; ++k) body_parts[k] = to_body(parts[k], pose);
        const Eigen::Quaterniond inv = pose.rotation.conjugate();
        return r.render_compound(std::span<const ToolEllipsoid>(body_parts.data(), n), inv * (tcp - pose.position),
                                 inv * (velocity - pose.velocity_at(tcp)),
                                 inv * (angular_velocity - pose.angular_velocity), dt);
      },
      dt);
  if (!whole_.renderer) return cut;
  return blend_whole(cut, parts,
                     [&] { return whole_.renderer->render_compound(parts, tcp, velocity, angular_velocity, dt); });
}

std::shared_ptr<const WholeSceneWorld> whole_scene_world(const CollisionWorld& scene, std::span<const RigidObject> objects,
                                                         const UntouchedDrift& drift) {
  auto out = std::make_shared<WholeSceneWorld>();
  std::vector<CollisionWorld::PlacedWorld> parts;
  for (std::size_t i = 0; i < objects.size() && i < kMaxObjects; ++i) {
    const RigidObject& o = objects[i];
    const CollisionWorld& body = *o.body;
    BodyPose at;
    at.position = o.rest_origin;
    const BodyPose& settled = drift.settled[i];
    double moved = 0;  // the farthest corner of its box from where it was captured
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d x((c & 1) ? body.bounds_hi().x() : body.bounds_lo().x(),
                              (c & 2) ? body.bounds_hi().y() : body.bounds_lo().y(),
                              (c & 4) ? body.bounds_hi().z() : body.bounds_lo().z());
      moved = std::max(moved, (settled.rotation * x + settled.position - (x + o.rest_origin)).norm());
    }
    if (moved <= kWholeSceneSettleTolerance) {
      at.position = settled.position;
      at.rotation = settled.rotation;
    }
    out->poses[i] = at;
    parts.push_back({&body, at.position, at.rotation});
  }
  out->world = std::make_shared<const CollisionWorld>(CollisionWorld::joined(scene, parts));
  return out;
}

std::unique_ptr<ObjectRenderer> make_object_renderer(const RendererSpec& spec, const CollisionWorld& scene,
                                                     std::span<const RigidObject> objects,
                                                     std::shared_ptr<ObjectDynamics> dynamics, const QueryOptions& query,
                                                     WholeSceneOptions whole) {
  std::vector<std::unique_ptr<ForceRenderer>> bodies;
  std::vector<std::shared_ptr<const CollisionWorld>> worlds;
  for (const RigidObject& o : objects) {
    worlds.push_back(o.body);
    bodies.push_back(make_force_renderer(spec, *o.body, query));
  }
  // The support plane's coupling is the proxy's (the paper model's runs get the proxy's defaults).
  const ProxyParams proxy = std::holds_alternative<ProxyModelSpec>(spec) ? std::get<ProxyModelSpec>(spec).params
                                                                         : ProxyParams{};
  std::vector<SupportHole> holes = support_holes(objects, dynamics->support());
  WholeScene captured;
  if (whole.enabled) {
    captured.scene = whole.world ? std::move(whole.world)
                                 : whole_scene_world(scene, objects,
                                                     untouched_drift(objects, dynamics->support(), dynamics->params()));
    captured.renderer = make_force_renderer(spec, *captured.scene->world, query);
    captured.rest_tolerance = whole.rest_tolerance;
  }
  return std::make_unique<ObjectRenderer>(make_force_renderer(spec, scene, query), std::move(bodies), std::move(worlds),
                                          std::move(dynamics), Eigen::Vector2d(proxy.stiffness, proxy.damping),
                                          std::move(holes), std::move(captured));
}

}  // namespace gshaptics
