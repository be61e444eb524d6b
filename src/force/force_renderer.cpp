#include "gshaptics/force/force_renderer.h"

#include "gshaptics/error.h"
#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/force/renderer_spec.h"

namespace gshaptics {

std::string_view force_model_names() noexcept { return "proxy, paper"; }

bool is_force_model(std::string_view name) noexcept { return name == "paper" || name == "proxy"; }

std::string_view renderer_name(const RendererSpec& spec) noexcept {
  return std::holds_alternative<PaperModelSpec>(spec) ? "paper" : "proxy";
}

RendererSpec renderer_spec(std::string_view name) {
  if (name == "paper") return PaperModelSpec{};
  if (name == "proxy") return ProxyModelSpec{};
  throw InputError("force model '" + std::string(name) + "' is not known (expected one of: " +
                   std::string(force_model_names()) + ")");
}

std::unique_ptr<ForceRenderer> make_force_renderer(const RendererSpec& spec, const CollisionWorld& world,
                                                   const QueryOptions& query) {
  if (const auto* paper = std::get_if<PaperModelSpec>(&spec))
    return std::make_unique<PaperRenderer>(world, paper->params, query);
  return std::make_unique<ProxyRenderer>(world, std::get<ProxyModelSpec>(spec).params);
}

RenderOutput PaperRenderer::render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept {
  RenderOutput out;
  out.status = query_.run(tool);
  out.counts = query_.result().counts;
  out.force = model_.update(query_.result().contacts(), tool.center, velocity, dt).force;
  out.proxy = tool.center;
  return out;
}

}  // namespace gshaptics
