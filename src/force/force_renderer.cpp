#include "gshaptics/force/force_renderer.h"

#include "gshaptics/error.h"
#include "gshaptics/force/proxy_renderer.h"

namespace gshaptics {

std::string_view force_model_names() noexcept { return "proxy, paper"; }

const ProxyParams& default_proxy_params() noexcept {
  static const ProxyParams kDefault{};
  return kDefault;
}

bool is_force_model(std::string_view name) noexcept { return name == "paper" || name == "proxy"; }

std::unique_ptr<ForceRenderer> make_force_renderer(std::string_view name, const CollisionWorld& world,
                                                   const ForceParams& force, const QueryOptions& query,
                                                   const ProxyParams& proxy) {
  if (name == "paper") return std::make_unique<PaperRenderer>(world, force, query);
  if (name == "proxy") return std::make_unique<ProxyRenderer>(world, proxy, force.f_max);
  throw InputError("force model '" + std::string(name) + "' is not known (expected one of: " +
                   std::string(force_model_names()) + ")");
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
