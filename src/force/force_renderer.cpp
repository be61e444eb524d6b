#include "gshaptics/force/force_renderer.h"

#include "gshaptics/error.h"

namespace gshaptics {

std::string_view force_model_names() noexcept { return "paper"; }

bool is_force_model(std::string_view name) noexcept { return name == "paper"; }

std::unique_ptr<ForceRenderer> make_force_renderer(std::string_view name, const CollisionWorld& world,
                                                   const ForceParams& force, const QueryOptions& query) {
  if (name == "paper") return std::make_unique<PaperRenderer>(world, force, query);
  static_assert(true, "is_force_model() lists the same names");
  throw InputError("force model '" + std::string(name) + "' is not known (expected one of: " +
                   std::string(force_model_names()) + ")");
}

RenderOutput PaperRenderer::render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept {
  RenderOutput out;
  out.status = query_.run(tool);
  out.counts = query_.result().counts;
  out.force = model_.update(query_.result().contacts(), tool.center, velocity, dt).force;
  return out;
}

}  // namespace gshaptics
