#include "gshaptics/scene/scene_stats.h"

#include <algorithm>
#include <cmath>

namespace gshaptics {

namespace {
// Percentile p of a vector sorted in place (nearest rank).
double sorted_percentile(const std::vector<float>& v, double p) {
  if (v.empty()) return 0.0;
  const double pos = std::clamp(p, 0.0, 100.0) / 100.0 * double(v.size() - 1);
  return v[std::size_t(std::llround(pos))];
}
}  // namespace

SceneStats compute_scene_stats(const GaussianScene& scene) {
  // One float array at a time, sorted in place: a 15M-Gaussian scene needs ~60 MB here.
  SceneStats s;
  s.count = scene.size();
  if (scene.empty()) return s;
  const std::size_t n = scene.size();
  std::vector<float> v(n);
  for (int k = 0; k < 3; ++k) {
    for (std::size_t i = 0; i < n; ++i) v[i] = scene.means[i][k];
    std::sort(v.begin(), v.end());
    s.bbox_min[k] = v.front();
    s.bbox_max[k] = v.back();
    s.p01[k] = sorted_percentile(v, 1);
    s.p99[k] = sorted_percentile(v, 99);
    s.median[k] = sorted_percentile(v, 50);
  }
  v.assign(scene.opacities.begin(), scene.opacities.end());
  std::sort(v.begin(), v.end());
  const double op[5] = {1, 10, 25, 50, 75};
  for (std::size_t i = 0; i < 5; ++i) s.opacity_pct[i] = sorted_percentile(v, op[i]);
  const float thr[3] = {0.1f, 0.2f, 0.3f};  // compared in float, like the filter
  for (std::size_t i = 0; i < 3; ++i)
    s.opacity_above[i] = double(v.end() - std::upper_bound(v.begin(), v.end(), thr[i])) / double(n);
  const double sp[4] = {1, 50, 99, 99.9};
  for (std::size_t i = 0; i < n; ++i) v[i] = scene.scales[i].maxCoeff();
  std::sort(v.begin(), v.end());
  for (std::size_t i = 0; i < 4; ++i) s.max_scale_pct[i] = sorted_percentile(v, sp[i]);
  v.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) v[3 * i + std::size_t(k)] = scene.scales[i][k];
  std::sort(v.begin(), v.end());
  for (std::size_t i = 0; i < 4; ++i) s.scale_pct[i] = sorted_percentile(v, sp[i]);
  return s;
}

}  // namespace gshaptics
