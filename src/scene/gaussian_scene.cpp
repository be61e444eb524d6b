#include "gshaptics/scene/gaussian_scene.h"

namespace gshaptics {

void GaussianScene::reserve(std::size_t n) {
  means.reserve(n);
  scales.reserve(n);
  rotations.reserve(n);
  opacities.reserve(n);
  source_index.reserve(n);
}

void GaussianScene::push_back(const Eigen::Vector3f& mean, const Eigen::Vector3f& scale,
                              const Eigen::Vector4f& rotation_wxyz, float opacity,
                              std::uint32_t source) {
  means.push_back(mean);
  scales.push_back(scale);
  rotations.push_back(rotation_wxyz);
  opacities.push_back(opacity);
  source_index.push_back(source);
}

}  // namespace gshaptics
