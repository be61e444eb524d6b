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

void GaussianScene::push_back_from(const GaussianScene& other, std::size_t i) {
  push_back(other.means[i], other.scales[i], other.rotations[i], other.opacities[i],
            other.source_index[i]);
  if (!other.colors_dc.empty()) colors_dc.push_back(other.colors_dc[i]);
  if (other.sh_rest_count > 0) {
    sh_rest_count = other.sh_rest_count;
    const auto* first = other.sh_rest.data() + i * std::size_t(other.sh_rest_count);
    sh_rest.insert(sh_rest.end(), first, first + other.sh_rest_count);
  }
}

}  // namespace gshaptics
