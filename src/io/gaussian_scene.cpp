#include "gshaptics/io/gaussian_scene.h"

#include <cmath>

namespace gshaptics {

std::string_view to_string(SceneFrame frame) {
  switch (frame) {
    case SceneFrame::kRdf: return "RDF (x right, y down, z forward: 3DGS/COLMAP)";
    case SceneFrame::kRub: return "RUB (x right, y up, z back: OpenGL/SPZ)";
  }
  return "unknown";
}

Eigen::Vector3d up_of(SceneFrame frame) {
  return Eigen::Vector3d(0, frame == SceneFrame::kRub ? 1.0 : -1.0, 0);
}

Eigen::Quaterniond frame_to_z_up(SceneFrame frame) {
  // RDF: up is -y; (x, y, z) -> (x, z, -y) is -90 deg about x. RUB: up is +y; +90 deg about x.
  const double h = std::sqrt(0.5);
  return frame == SceneFrame::kRdf ? Eigen::Quaterniond(h, -h, 0, 0) : Eigen::Quaterniond(h, h, 0, 0);
}

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
