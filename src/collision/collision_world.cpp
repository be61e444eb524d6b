#include "gshaptics/collision/collision_world.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "../huge_pages.h"
#include "gshaptics/error.h"
#include "gshaptics/narrowphase/k_min_batch.h"

namespace gshaptics {

Eigen::Vector3d ellipsoid_half_extent(const Eigen::Matrix3d& R,
                                      const Eigen::Vector3d& semi_axes) noexcept {
  return (R.cwiseAbs2() * semi_axes.cwiseAbs2()).cwiseSqrt();
}

CollisionWorld CollisionWorld::build(const GaussianScene& scene, const WorldConfig& config,
                                     WorldBuildReport* report) {
  return build_impl(scene, nullptr, config, report);
}

CollisionWorld CollisionWorld::build(GaussianScene&& scene, const WorldConfig& config,
                                     WorldBuildReport* report) {
  return build_impl(scene, &scene, config, report);
}

namespace {
template <typename T>
void release(std::vector<T>& v) {
  std::vector<T>().swap(v);
}
}  // namespace

CollisionWorld CollisionWorld::build_impl(const GaussianScene& scene, GaussianScene* consume,
                                          const WorldConfig& config, WorldBuildReport* report) {
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
                     std::to_string(scene.size()) + "); lower the opacity threshold (--min-opacity, WorldConfig::min_opacity)");

  // In place: the records are written once into their final storage; then (the scene freed
  // if it is consumed) their float boxes; the BVH over the boxes; then the records are
  // permuted into BVH order within their storage.
  auto records = std::make_shared<std::vector<CollisionGaussian, internal::HugePageAllocator<CollisionGaussian>>>(kept);
  const double axis_scale = config.sigma * reg.scale;
  const std::size_t n_scene = scene.size();
  std::size_t j = 0;
  for (std::size_t i = 0; i < n_scene; ++i) {
    if (!(scene.opacities[i] > config.min_opacity)) continue;
    CollisionGaussian& g = (*records)[j++];
    const Eigen::Vector3d c = reg.apply(scene.means[i].cast<double>());
    const Eigen::Quaterniond q = reg.apply_rotation(scene.rotations[i]).normalized();
    for (int k = 0; k < 3; ++k) g.center[k] = c[k];
    g.quaternion[0] = float(q.w());
    g.quaternion[1] = float(q.x());
    g.quaternion[2] = float(q.y());
    g.quaternion[3] = float(q.z());
    for (int k = 0; k < 3; ++k) g.semi_axes[k] = float(axis_scale * double(scene.scales[i][k]));
    g.radius = std::max(g.semi_axes[0], std::max(g.semi_axes[1], g.semi_axes[2]));
    g.opacity = scene.opacities[i];
    g.source_index = scene.source_index[i];
  }
  if (consume != nullptr) {
    release(consume->means);
    release(consume->scales);
    release(consume->rotations);
    release(consume->opacities);
    release(consume->source_index);
    release(consume->colors_dc);
    release(consume->sh_rest);
  }
  // Bounds from the stored (float) values so the box holds exactly the ellipsoid we test.
  std::vector<BvhBox> boxes(kept);
  w.lo_ = Eigen::Vector3d::Constant(INFINITY);
  w.hi_ = -w.lo_;
  for (std::size_t k = 0; k < kept; ++k) {
    const CollisionGaussian& g = (*records)[k];
    const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
    const Eigen::Vector3d h = ellipsoid_half_extent(
        rotation_matrix(g), Eigen::Vector3d(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]));
    const Eigen::Vector3d lo = c - h, hi = c + h;
    for (int a = 0; a < 3; ++a) {
      boxes[k].lo[a] = round_down_to_float(lo[a]);
      boxes[k].hi[a] = round_up_to_float(hi[a]);
    }
    w.lo_ = w.lo_.cwiseMin(lo);
    w.hi_ = w.hi_.cwiseMax(hi);
  }
  w.bvh_ = Bvh::build(boxes, config.leaf_size);
  std::vector<BvhBox>().swap(boxes);
  // Permute into BVH order (slot k takes record order[k]) by following each cycle of the
  // permutation; a slot done is marked by order[k] = k, so no extra memory is needed.
  {
    std::vector<std::uint32_t>& order = w.bvh_.mutable_order();
    auto& r = *records;
    for (std::size_t start = 0; start < order.size(); ++start) {
      if (order[start] == start) continue;
      const CollisionGaussian first = r[start];
      std::size_t k = start;
      while (order[k] != start) {
        const std::size_t from = order[k];
        r[k] = r[from];
        order[k] = std::uint32_t(k);
        k = from;
      }
      r[k] = first;
      order[k] = std::uint32_t(k);
    }
  }
  w.gaussians_ = std::span<const CollisionGaussian>(*records);
  w.storage_ = std::move(records);
  w.bvh_.release_order();  // records are now in BVH order: the permutation is not needed

  if (report != nullptr) {
    report->filter = {config.min_opacity, n_scene, w.gaussians_.size()};
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
