#include "gshaptics/scene/opacity_filter.h"

namespace gshaptics {

GaussianScene filter_by_opacity(const GaussianScene& scene, float min_opacity,
                                OpacityFilterReport* report) {
  std::size_t kept = 0;
  for (float a : scene.opacities) kept += a > min_opacity ? 1 : 0;
  GaussianScene out;
  out.frame = scene.frame;
  out.reserve(kept);
  for (std::size_t i = 0; i < scene.size(); ++i) {
    if (scene.opacities[i] > min_opacity) out.push_back_from(scene, i);
  }
  if (report != nullptr) *report = {min_opacity, scene.size(), out.size()};
  return out;
}

}  // namespace gshaptics
