#include "gshaptics/scene/scene_stats.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/percentile.h"

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
  std::vector<double> middle;  // (SeenSolid::typical_scale's statistic)
  for (std::size_t i = 0; i < n; ++i)
    if (scene.opacities[i] >= 1.0f / 255.0f) {
      const Eigen::Vector3f& a = scene.scales[i];
      middle.push_back(a.sum() - a.maxCoeff() - a.minCoeff());
    }
  s.drawn_middle_scale = percentile(std::move(middle), 50);
  v.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) v[3 * i + std::size_t(k)] = scene.scales[i][k];
  std::sort(v.begin(), v.end());
  for (std::size_t i = 0; i < 4; ++i) s.scale_pct[i] = sorted_percentile(v, sp[i]);
  return s;
}

WorldPreview preview_world(const GaussianScene& scene, float min_opacity,
                           const SimilarityTransform& scene_to_world, const Eigen::Vector3d& up) {
  WorldPreview w;
  w.up = up.normalized();
  std::vector<Eigen::Vector3d> p;
  p.reserve(scene.size());
  for (std::size_t i = 0; i < scene.size(); ++i)
    if (scene.opacities[i] > min_opacity) p.push_back(scene_to_world.apply(scene.means[i].cast<double>()));
  w.kept = p.size();
  if (p.empty()) return w;
  std::vector<float> v(p.size());
  for (int k = 0; k < 3; ++k) {
    for (std::size_t i = 0; i < p.size(); ++i) v[i] = float(p[i][k]);
    std::sort(v.begin(), v.end());
    w.bbox_min[k] = v.front();
    w.bbox_max[k] = v.back();
    w.p01[k] = sorted_percentile(v, 1);
    w.p99[k] = sorted_percentile(v, 99);
  }
  w.robust_size = (w.p99 - w.p01).maxCoeff();
  return w;
}

ScaleAdvice desktop_scale_advice(double robust_size) {
  ScaleAdvice a;
  if (!(robust_size > 0)) return a;
  a.reg_scale = 0.12 / robust_size;
  a.tool_radius = 0.0012;
  a.reason = "fits the object's 1-99 pct size in 0.12 m of a ~0.16 m desktop workspace; tool 1 % of that";
  return a;
}

ScaleAdvice room_scale_advice(double robust_size) {
  ScaleAdvice a;
  if (!(robust_size > 0)) return a;
  if (robust_size >= 0.2 && robust_size <= 20) {
    a.reg_scale = 1;
    a.reason = "the size is plausible in metres, so the units are probably metres already";
  } else {
    const double e = std::round(std::log10(std::sqrt(0.5 * 5) / robust_size));
    a.reg_scale = std::pow(10.0, e);
    const char* unit = e == -2 ? "centimetres" : e == -3 ? "millimetres" : e == -1 ? "decimetres" : nullptr;
    a.reason = unit ? std::string("the size is not plausible in metres; the units look like ") + unit
                    : "the size is not plausible in metres; this power of ten brings it to 0.5..5 m";
  }
  a.tool_radius = 0.01 * robust_size * a.reg_scale;
  return a;
}

}  // namespace gshaptics
