#include "gshaptics/scene/scene_stats.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  const double pos = std::clamp(p, 0.0, 100.0) / 100.0 * double(values.size() - 1);
  const auto k = std::size_t(std::llround(pos));
  std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(k), values.end());
  return values[k];
}

SceneStats compute_scene_stats(const GaussianScene& scene) {
  SceneStats s;
  s.count = scene.size();
  if (scene.empty()) return s;
  s.bbox_min = Eigen::Vector3d::Constant(INFINITY);
  s.bbox_max = Eigen::Vector3d::Constant(-INFINITY);
  std::array<std::vector<double>, 3> axis;
  for (auto& a : axis) a.reserve(scene.size());
  std::vector<double> scales, max_scales, opac(scene.opacities.begin(), scene.opacities.end());
  scales.reserve(3 * scene.size());
  max_scales.reserve(scene.size());
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const Eigen::Vector3d m = scene.means[i].cast<double>();
    s.bbox_min = s.bbox_min.cwiseMin(m);
    s.bbox_max = s.bbox_max.cwiseMax(m);
    for (int k = 0; k < 3; ++k) {
      axis[std::size_t(k)].push_back(m[k]);
      scales.push_back(scene.scales[i][k]);
    }
    max_scales.push_back(scene.scales[i].maxCoeff());
  }
  for (int k = 0; k < 3; ++k) {
    s.p01[k] = percentile(axis[std::size_t(k)], 1);
    s.p99[k] = percentile(axis[std::size_t(k)], 99);
    s.median[k] = percentile(axis[std::size_t(k)], 50);
  }
  const double op[5] = {1, 10, 25, 50, 75};
  for (std::size_t i = 0; i < 5; ++i) s.opacity_pct[i] = percentile(opac, op[i]);
  const double thr[3] = {0.1, 0.2, 0.3};
  for (std::size_t i = 0; i < 3; ++i) {
    const double t = double(float(thr[i]));  // the filter compares in float
    const auto n = std::count_if(opac.begin(), opac.end(), [&](double a) { return a > t; });
    s.opacity_above[i] = double(n) / double(opac.size());
  }
  const double sp[4] = {1, 50, 99, 99.9};
  for (std::size_t i = 0; i < 4; ++i) {
    s.scale_pct[i] = percentile(scales, sp[i]);
    s.max_scale_pct[i] = percentile(max_scales, sp[i]);
  }
  return s;
}

}  // namespace gshaptics
