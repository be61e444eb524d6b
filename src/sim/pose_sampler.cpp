#include "gshaptics/sim/pose_sampler.h"

#include <random>

#include "gshaptics/percentile.h"

namespace gshaptics {

void robust_box(const CollisionWorld& world, Eigen::Vector3d& p1, Eigen::Vector3d& p99) {
  std::vector<double> ax[3];
  for (auto& a : ax) a.reserve(world.size());
  for (const auto& g : world.gaussians())
    for (int k = 0; k < 3; ++k) ax[k].push_back(g.center[k]);
  for (int k = 0; k < 3; ++k) {
    p1[k] = percentile(ax[k], 1);
    p99[k] = percentile(ax[k], 99);
  }
}

double robust_extent(const CollisionWorld& world) {
  Eigen::Vector3d p1, p99;
  robust_box(world, p1, p99);
  return (p99 - p1).maxCoeff();
}

std::vector<ToolEllipsoid> sample_poses(const CollisionWorld& world, const PoseSamplerParams& params) {
  Eigen::Vector3d p1, p99;
  robust_box(world, p1, p99);
  const double extent = (p99 - p1).maxCoeff();
  std::mt19937_64 rng(params.seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> n(0, 1);
  const auto unit = [&] {
    Eigen::Vector3d v(n(rng), n(rng), n(rng));
    return Eigen::Vector3d(v / std::max(v.norm(), 1e-12));
  };
  std::vector<ToolEllipsoid> poses;
  poses.reserve(params.count);
  for (std::size_t i = 0; i < params.count; ++i) {
    const double r = extent * (params.radius_min + (params.radius_max - params.radius_min) * u(rng));
    ToolEllipsoid t = ToolEllipsoid::sphere(Eigen::Vector3d::Zero(), r);
    if (params.anisotropic) {
      t.semi_axes = Eigen::Vector3d(r, r * (1.0 / 3 + 2.0 / 3 * u(rng)), r * (1.0 / 3 + 2.0 / 3 * u(rng)));
      t.rotation = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
    }
    if (params.near_surface) {
      const auto& g = world.gaussians()[std::size_t(rng() % world.size())];
      t.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]) + unit() * r * u(rng);
    } else {
      for (int k = 0; k < 3; ++k) t.center[k] = p1[k] + (p99[k] - p1[k]) * u(rng);
    }
    poses.push_back(t);
  }
  return poses;
}

}  // namespace gshaptics
