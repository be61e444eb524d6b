#pragma once
/// @file
/// Summary statistics of a scene, as printed by `gshaptics info` (same quantities as SOURCES.md).

#include <Eigen/Core>
#include <array>

#include "gshaptics/io/gaussian_scene.h"

namespace gshaptics {

/// Statistics over every Gaussian of a scene (scene frame and units).
struct SceneStats {
  std::size_t count = 0;
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero(), bbox_max = Eigen::Vector3d::Zero();
  Eigen::Vector3d p01 = Eigen::Vector3d::Zero(), p99 = Eigen::Vector3d::Zero();  ///< 1st/99th pct of means per axis
  Eigen::Vector3d median = Eigen::Vector3d::Zero();  ///< per-axis median of the means
  std::array<double, 5> opacity_pct{};     ///< opacity at percentiles 1, 10, 25, 50, 75
  std::array<double, 3> opacity_above{};   ///< fraction with opacity > 0.1, 0.2, 0.3
  std::array<double, 4> scale_pct{};       ///< all axes pooled, percentiles 1, 50, 99, 99.9
  std::array<double, 4> max_scale_pct{};   ///< largest axis, percentiles 1, 50, 99, 99.9
};

/// Computes the statistics; an empty scene gives zeros.
[[nodiscard]] SceneStats compute_scene_stats(const GaussianScene& scene);

}  // namespace gshaptics
