#include "gshaptics/collision/collision_world.h"

#include <chrono>
#include <cmath>

#include "gshaptics/error.h"

namespace gshaptics {

Eigen::Matrix3d rotation_matrix(const CollisionGaussian& g) noexcept {
  Eigen::Matrix3d R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R(i, j) = g.rotation[3 * i + j];
  return R;
}

Eigen::Vector3d ellipsoid_half_extent(const Eigen::Matrix3d& R,
                                      const Eigen::Vector3d& semi_axes) noexcept {
  return (R.cwiseAbs2() * semi_axes.cwiseAbs2()).cwiseSqrt();
}

CollisionWorld CollisionWorld::build(const GaussianScene& scene, const WorldConfig& config,
                                     WorldBuildReport* report) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!(config.sigma > 0) || !std::isfinite(config.sigma))
    throw InputError("sigma (k of the k-sigma ellipsoid) must be > 0, got " + std::to_string(config.sigma));
  if (!(config.registration.scale > 0) || !std::isfinite(config.registration.scale))
    throw InputError("registration scale must be > 0");

  CollisionWorld w;
  w.config_ = config;
  w.scene_to_world_ = with_up_axis(config.registration, config.up, scene.frame);
  w.scene_to_world_.rotation.normalize();
  w.up_ = world_up(config.registration, config.up, scene.frame);
  const SimilarityTransform& reg = w.scene_to_world_;
  std::size_t kept = 0;
  for (float a : scene.opacities) kept += a > config.min_opacity ? 1 : 0;
  if (kept == 0)
    throw InputError("no Gaussian has opacity > " + std::to_string(config.min_opacity) + " (of " +
                     std::to_string(scene.size()) + "); lower min_opacity");

  std::vector<CollisionGaussian> unordered;
  unordered.reserve(kept);
  std::vector<Eigen::Vector3d> lo, hi;
  lo.reserve(kept);
  hi.reserve(kept);
  const double axis_scale = config.sigma * reg.scale;
  w.lo_ = Eigen::Vector3d::Constant(INFINITY);
  w.hi_ = -w.lo_;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    if (!(scene.opacities[i] > config.min_opacity)) continue;
    CollisionGaussian g{};
    const Eigen::Vector3d c = reg.apply(scene.means[i].cast<double>());
    const Eigen::Quaterniond q = reg.apply_rotation(scene.rotations[i]);
    for (int k = 0; k < 3; ++k) g.center[k] = c[k];
    const Eigen::Matrix3d R = q.toRotationMatrix();
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) g.rotation[3 * a + b] = float(R(a, b));
    Eigen::Vector3d axes;
    for (int k = 0; k < 3; ++k) {
      g.semi_axes[k] = float(axis_scale * double(scene.scales[i][k]));
      axes[k] = g.semi_axes[k];
    }
    g.opacity = scene.opacities[i];
    g.source_index = scene.source_index[i];
    // Bounds from the stored (float) values so the box holds exactly the ellipsoid we test.
    const Eigen::Vector3d h = ellipsoid_half_extent(rotation_matrix(g), axes);
    lo.push_back(c - h);
    hi.push_back(c + h);
    w.lo_ = w.lo_.cwiseMin(lo.back());
    w.hi_ = w.hi_.cwiseMax(hi.back());
    unordered.push_back(g);
  }
  w.bvh_ = Bvh::build(lo, hi, config.leaf_size);
  {
    auto records = std::make_shared<std::vector<CollisionGaussian>>(unordered.size());
    const auto& order = w.bvh_.order();
    for (std::size_t k = 0; k < order.size(); ++k) (*records)[k] = unordered[order[k]];
    w.gaussians_ = std::span<const CollisionGaussian>(*records);
    w.storage_ = std::move(records);
  }
  w.bvh_.release_order();  // records are now in BVH order: the permutation is not needed

  if (report != nullptr) {
    report->filter = {config.min_opacity, scene.size(), w.gaussians_.size()};
    report->build_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    report->memory_bytes = w.memory_bytes();
  }
  return w;
}

std::size_t CollisionWorld::memory_bytes() const {
  return gaussians_.size() * sizeof(CollisionGaussian) + bvh_.nodes().size() * sizeof(BvhNode) +
         bvh_.order().capacity() * sizeof(std::uint32_t);
}

}  // namespace gshaptics
