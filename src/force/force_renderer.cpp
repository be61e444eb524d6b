#include "gshaptics/force/force_renderer.h"

#include "gshaptics/error.h"
#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/force/renderer_spec.h"

namespace gshaptics {

namespace {
constexpr RendererName kRenderers[] = {{"proxy", RendererKind::kProxy}, {"paper", RendererKind::kPaper}};
}  // namespace

std::span<const RendererName> renderer_names() noexcept { return kRenderers; }

std::string_view force_model_names() noexcept {
  static const std::string names = [] {
    std::string s;
    for (const RendererName& r : kRenderers) s += (s.empty() ? "" : ", ") + std::string(r.name);
    return s;
  }();
  return names;
}

RendererKind renderer_kind(std::string_view name) {
  for (const RendererName& r : kRenderers)
    if (r.name == name) return r.kind;
  throw InputError("force model '" + std::string(name) + "' is not known (expected one of: " +
                   std::string(force_model_names()) + ")");
}

RendererKind renderer_kind(const RendererSpec& spec) noexcept {
  return std::holds_alternative<PaperModelSpec>(spec) ? RendererKind::kPaper : RendererKind::kProxy;
}

std::string_view renderer_name(RendererKind kind) noexcept {
  for (const RendererName& r : kRenderers)
    if (r.kind == kind) return r.name;
  return "?";
}

std::string_view renderer_name(const RendererSpec& spec) noexcept { return renderer_name(renderer_kind(spec)); }

RendererSpec renderer_spec(RendererKind kind, const ProxyParams& proxy, const ForceParams& paper) {
  if (kind == RendererKind::kPaper) return PaperModelSpec{paper};
  return ProxyModelSpec{proxy, nullptr};
}

RendererSpec renderer_spec(std::string_view name) { return renderer_spec(renderer_kind(name)); }

float default_min_opacity(const RendererSpec& spec) noexcept {
  const auto* proxy = std::get_if<ProxyModelSpec>(&spec);
  return proxy && proxy->params.surface == ProxySurface::kSeen ? kSeenMinOpacity : kDefaultMinOpacity;
}

RendererSpec renderer_spec_for(const RendererSpec& spec, ProxyTool tool) {
  if (const auto* proxy = std::get_if<ProxyModelSpec>(&spec))
    return ProxyModelSpec{proxy_params_for(proxy->params, tool), proxy->materials};
  return spec;
}

std::unique_ptr<ForceRenderer> make_force_renderer(const RendererSpec& spec, const CollisionWorld& world,
                                                   const QueryOptions& query) {
  if (const auto* paper = std::get_if<PaperModelSpec>(&spec))
    return std::make_unique<PaperRenderer>(world, paper->params, query);
  const ProxyModelSpec& proxy = std::get<ProxyModelSpec>(spec);
  auto renderer = std::make_unique<ProxyRenderer>(world, proxy.params);
  if (proxy.materials) renderer->set_materials(MaterialField::resolve(*proxy.materials, world, proxy.params));
  return renderer;
}

Eigen::Vector3d contact_torque(const ToolEllipsoid& tool, const Eigen::Vector3d& tcp,
                               const Eigen::Vector3d& force) noexcept {
  if (!(force.squaredNorm() > 0)) return Eigen::Vector3d::Zero();
  return (tool.surface_point(-force) - tcp).cross(force);
}

RenderOutput ForceRenderer::render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                                            const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                            double dt) noexcept {
  (void)angular_velocity;
  if (parts.size() == 1 && parts[0].center == tcp) {
    RenderOutput out = render(parts[0], velocity, dt);
    out.torque = contact_torque(parts[0], tcp, out.force);
    return out;
  }
  RenderOutput out;
  out.proxy = tcp;
  out.status = QueryStatus::kInvalidTool;  // a renderer of one ellipsoid at the TCP
  return out;
}

namespace {

std::array<ForceModel, kMaxToolParts> part_models(const ForceParams& force) {
  std::array<ForceModel, kMaxToolParts> m;
  m.fill(ForceModel(force));
  return m;
}

}  // namespace

PaperRenderer::PaperRenderer(const CollisionWorld& world, const ForceParams& force, const QueryOptions& query)
    : query_(world, query), model_(force), part_models_(part_models(force)), merged_(query_.result().capacity()) {}

RenderOutput PaperRenderer::render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                                            const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                            double dt) noexcept {
  if (parts.size() == 1 && parts[0].center == tcp && parts[0].is_sphere()) {
    compound_ = false;
    return render(parts[0], velocity, dt);
  }
  compound_ = true;
  merged_.clear();
  RenderOutput out;
  out.proxy = tcp;
  bool valid = !parts.empty() && parts.size() <= std::size_t(kMaxToolParts) && tcp.allFinite() &&
               velocity.allFinite() && angular_velocity.allFinite();
  for (std::size_t j = 0; valid && j < parts.size(); ++j) valid = parts[j].valid();
  if (!valid) {  // one bad part: no force from any, and no part's filters advance (as for one ellipsoid)
    out.status = QueryStatus::kInvalidTool;
    return out;
  }
  for (std::size_t j = 0; j < parts.size(); ++j) {
    const QueryStatus st = query_.run(parts[j]);  // every part is valid: ok, or an overflow
    if (st != QueryStatus::kOk) out.status = st;
    const ContactSet& r = query_.result();
    out.counts.candidates += r.counts.candidates;
    out.counts.prefiltered += r.counts.prefiltered;
    out.counts.contacts += r.counts.contacts;
    const Eigen::Vector3d arm = parts[j].center - tcp;
    const Eigen::Vector3d v = velocity + angular_velocity.cross(arm);
    const ForceOutput f = part_models_[j].update(r.contacts(), parts[j].center, v, dt);
    out.force += f.force;
    if (f.contacts > 0) out.torque += (f.centroid - tcp).cross(f.force);
    std::size_t granted = 0;
    Contact* dst = merged_.append(r.contacts().size(), granted);
    for (std::size_t k = 0; k < granted; ++k) {
      dst[k] = r.contacts()[k];
      dst[k].part = std::uint8_t(j);
    }
    if (granted < r.contacts().size()) out.status = QueryStatus::kContactOverflow;
  }
  merged_.counts = out.counts;
  return out;
}

RenderOutput PaperRenderer::render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept {
  compound_ = false;
  RenderOutput out;
  out.status = query_.run(tool);
  out.counts = query_.result().counts;
  out.force = model_.update(query_.result().contacts(), tool.center, velocity, dt).force;
  out.proxy = tool.center;
  return out;
}

}  // namespace gshaptics
