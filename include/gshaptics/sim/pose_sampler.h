#pragma once
/// @file
/// Seeded tool-pose sets for tests, benchmarks and the `gshaptics poses` command.

#include <cstdint>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/tool_ellipsoid.h"

namespace gshaptics {

/// How poses are drawn. Tool sizes are fractions of the scene's robust extent: the largest
/// 1st-to-99th-percentile span of the kept Gaussians' centres (world frame).
struct PoseSamplerParams {
  std::size_t count = 1000;
  std::uint64_t seed = 1;
  double radius_min = 0.01;  ///< smallest tool radius, fraction of the robust extent
  double radius_max = 0.02;  ///< largest tool radius, fraction of the robust extent
  bool near_surface = true;  ///< centre within one tool radius of a kept Gaussian's centre;
                             ///< otherwise uniform in the 1-99 pct box
  bool anisotropic = false;  ///< random orientation and axis ratios down to 1/3
};

/// The 1st-to-99th-percentile box of the world's Gaussian centres, per axis (world frame).
void robust_box(const CollisionWorld& world, Eigen::Vector3d& p1, Eigen::Vector3d& p99);

/// Largest 1st-to-99th-percentile span of the world's Gaussian centres (world units).
[[nodiscard]] double robust_extent(const CollisionWorld& world);

/// Draws `params.count` tool poses (deterministic for a seed).
[[nodiscard]] std::vector<ToolEllipsoid> sample_poses(const CollisionWorld& world,
                                                      const PoseSamplerParams& params);

}  // namespace gshaptics
