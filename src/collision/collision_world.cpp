#include "gshaptics/collision/collision_world.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "gshaptics/huge_pages.h"
#include "gshaptics/error.h"
#include "gshaptics/narrowphase/k_min_batch.h"

namespace gshaptics {
namespace {
// A world's records: in huge pages where the system gives them (huge_pages.h).
using RecordVector = std::vector<CollisionGaussian, internal::HugePageAllocator<CollisionGaussian>>;
}  // namespace

Eigen::Vector3d ellipsoid_half_extent(const Eigen::Matrix3d& R,
                                      const Eigen::Vector3d& semi_axes) noexcept {
  return (R.cwiseAbs2() * semi_axes.cwiseAbs2()).cwiseSqrt();
}

template <class Records>
void CollisionWorld::index(std::shared_ptr<Records> records) {
  const std::size_t n = records->size();
  // Bounds from the stored (float) values so the box holds exactly the ellipsoid we test.
  std::vector<BvhBox> boxes(n);
  lo_ = Eigen::Vector3d::Constant(INFINITY);
  hi_ = -lo_;
  for (std::size_t k = 0; k < n; ++k) {
    const CollisionGaussian& g = (*records)[k];
    const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
    const Eigen::Vector3d h = ellipsoid_half_extent(
        rotation_matrix(g), Eigen::Vector3d(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]));
    const Eigen::Vector3d lo = c - h, hi = c + h;
    for (int a = 0; a < 3; ++a) {
      boxes[k].lo[a] = round_down_to_float(lo[a]);
      boxes[k].hi[a] = round_up_to_float(hi[a]);
    }
    lo_ = lo_.cwiseMin(lo);
    hi_ = hi_.cwiseMax(hi);
  }
  bvh_ = Bvh::build(boxes, config_.leaf_size);
  std::vector<BvhBox>().swap(boxes);
  auto& r = *records;
  permute_to_order(std::span<std::uint32_t>(bvh_.mutable_order()), std::span<CollisionGaussian>(r.data(), r.size()));
  gaussians_ = std::span<const CollisionGaussian>(*records);
  storage_ = std::move(records);
  bvh_.release_order();  // records are now in BVH order: the permutation is not needed
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
  auto records = std::make_shared<RecordVector>(kept);
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
  w.index(std::move(records));
  if (report != nullptr) {
    report->filter = {config.min_opacity, n_scene, w.gaussians_.size()};
    report->build_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    report->memory_bytes = w.memory_bytes();
  }
  return w;
}

CollisionWorld CollisionWorld::joined(const CollisionWorld& base, std::span<const PlacedWorld> parts) {
  std::size_t n = base.size();
  for (const PlacedWorld& p : parts) {
    if (p.world == nullptr) throw InputError("joined world: a part has no world");
    n += p.world->size();
  }
  auto records = std::make_shared<RecordVector>();
  records->reserve(n);
  records->insert(records->end(), base.gaussians().begin(), base.gaussians().end());
  for (const PlacedWorld& p : parts) {
    const bool turned = !p.rotation.isApprox(Eigen::Quaterniond::Identity(), 0.0);
    for (CollisionGaussian g : p.world->gaussians()) {
      const Eigen::Vector3d c = p.rotation * Eigen::Vector3d(g.center[0], g.center[1], g.center[2]) + p.offset;
      for (int k = 0; k < 3; ++k) g.center[k] = c[k];
      if (turned) {
        const Eigen::Quaterniond q =
            (p.rotation * Eigen::Quaterniond(g.quaternion[0], g.quaternion[1], g.quaternion[2], g.quaternion[3])).normalized();
        g.quaternion[0] = float(q.w());
        g.quaternion[1] = float(q.x());
        g.quaternion[2] = float(q.y());
        g.quaternion[3] = float(q.z());
      }
      records->push_back(g);
    }
  }
  CollisionWorld w;
  w.config_ = base.config_;
  w.scene_to_world_ = base.scene_to_world_;
  w.up_ = base.up_;
  w.index(std::move(records));
  return w;
}

std::size_t CollisionWorld::memory_bytes() const {
  return gaussians_.size() * sizeof(CollisionGaussian) + bvh_.nodes().size() * sizeof(BvhNode) +
         bvh_.order().capacity() * sizeof(std::uint32_t);
}

}  // namespace gshaptics
