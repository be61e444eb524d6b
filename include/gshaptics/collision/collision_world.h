#pragma once
/// @file
/// The immutable collision representation of a scene: filtered, registered Gaussians as k-sigma
/// ellipsoids plus the broad-phase BVH over their exact bounding boxes (docs/design.md Sec. 1-4).
///
/// Threading: a CollisionWorld is immutable after build(); every const member is safe to call
/// from several threads at once. Per-device mutable state lives in ContactQuery and ForceModel.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "gshaptics/broadphase/bvh.h"
#include "gshaptics/io/gaussian_scene.h"
#include "gshaptics/narrowphase/k_min_batch.h"
#include "gshaptics/scene/opacity_filter.h"
#include "gshaptics/scene/registration.h"

namespace gshaptics {

/// How a scene becomes a collision world.
struct WorldConfig {
  float min_opacity = kDefaultMinOpacity;  ///< keep alpha > tau (paper Sec. III-A)
  double sigma = 1.0;                      ///< ellipsoid at k sigma: semi-axes k * s_i (paper: 1)
  /// Scene direction turned to world +z before `registration` (UpAxis::kAuto: from the
  /// scene's file convention, GaussianScene::frame).
  UpAxis up = UpAxis::kNone;
  SimilarityTransform registration;        ///< scene -> world (paper eq. 3), after `up`
  int leaf_size = 8;                       ///< BVH leaf capacity (one narrow-phase batch)
};

/// One Gaussian as a collision ellipsoid {c + R diag(a) u : |u| <= 1} in the world frame.
/// One record is one 64-byte cache line: the query's pre-filter and narrow phase touch one line
/// per candidate. The rotation is kept as a unit quaternion; the narrow phase turns it into
/// the matrix (rotation_from_quaternion) vectorised, and rotation_matrix() gives the same one.
struct alignas(64) CollisionGaussian {
  double center[3];       ///< c_i = s R_g mu_i + t (world units)
  /// World rotation R_g R_i as a unit quaternion (w, x, y, z), normalised in double before it
  /// was rounded to float; the matrix's columns are the ellipsoid's axes.
  float quaternion[4];
  float semi_axes[3];     ///< a_i = k * s * scale_i (world units)
  float radius;           ///< r_i of paper eq. 4: the largest semi-axis
  float opacity;          ///< alpha_i
  std::uint32_t source_index;  ///< index of the Gaussian in the original scene file
  /// r_i of paper eq. 4: the largest semi-axis.
  [[nodiscard]] float bounding_radius() const noexcept { return radius; }
};
static_assert(sizeof(CollisionGaussian) == 64);

/// What building the world did.
struct WorldBuildReport {
  OpacityFilterReport filter;
  double build_seconds = 0;  ///< filter + registration + BVH
  std::size_t memory_bytes = 0;
};

/// Filtered, registered Gaussians in BVH order plus the BVH.
class CollisionWorld {
 public:
  /// Filters `scene` by opacity, registers it and builds the BVH. Throws InputError for an
  /// invalid config (sigma <= 0, scale <= 0) and when no Gaussian passes the filter.
  ///
  /// Built in place: the records are written once into their final storage, the BVH is built
  /// over 24-byte float boxes and the records are then permuted into BVH order within that
  /// storage. Peak memory besides the scene: ~105 bytes per kept Gaussian (records 64, boxes 24,
  /// BVH order 4, nodes ~13).
  static CollisionWorld build(const GaussianScene& scene, const WorldConfig& config,
                              WorldBuildReport* report = nullptr);
  /// As above, consuming the scene: its per-Gaussian arrays are freed as soon as the records
  /// are written, before the boxes and the BVH, so the peak is the larger of scene + records
  /// (48 + 64 bytes per Gaussian for the collision fields) and the BVH build (~105 bytes).
  /// `scene` is left with its metadata (frame, report fields) and no Gaussians.
  static CollisionWorld build(GaussianScene&& scene, const WorldConfig& config,
                              WorldBuildReport* report = nullptr);

  /// One world joined into another (joined()): `world`'s records placed by the rigid motion
  /// x -> rotation x + offset (m) into base's frame.
  struct PlacedWorld {
    const CollisionWorld* world = nullptr;
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();
    Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  };
  /// One world of `base`'s records and every part's, each placed by its rigid motion, with a BVH
  /// of its own; config, up and scene_to_world are base's. The records are taken as they are
  /// (already filtered and registered): an object's body world placed at its rest origin gives
  /// back the Gaussians the cut took out of the scene. Throws InputError for a part without a world.
  static CollisionWorld joined(const CollisionWorld& base, std::span<const PlacedWorld> parts);

  [[nodiscard]] std::size_t size() const { return gaussians_.size(); }
  /// The records in BVH order (immutable; shared by copies of this world, and mapped straight
  /// from the file when the world came from a world cache).
  [[nodiscard]] std::span<const CollisionGaussian> gaussians() const { return gaussians_; }
  [[nodiscard]] const Bvh& bvh() const { return bvh_; }
  [[nodiscard]] const WorldConfig& config() const { return config_; }
  /// The whole scene -> world transform the world was built with: `config().up` then
  /// `config().registration` (with_up_axis). A renderer of the original file places it with this.
  [[nodiscard]] const SimilarityTransform& scene_to_world() const { return scene_to_world_; }
  /// The world's up direction (world_up of the config and the scene's file convention), unit.
  /// Probes approach along -up; viewers show it as up.
  [[nodiscard]] const Eigen::Vector3d& up() const { return up_; }
  /// Bounds of all ellipsoids (world frame).
  [[nodiscard]] const Eigen::Vector3d& bounds_lo() const { return lo_; }
  [[nodiscard]] const Eigen::Vector3d& bounds_hi() const { return hi_; }
  /// Heap bytes held (Gaussians + BVH nodes).
  [[nodiscard]] std::size_t memory_bytes() const;

 private:
  WorldConfig config_;
  SimilarityTransform scene_to_world_;
  Eigen::Vector3d up_ = Eigen::Vector3d::UnitZ();
  static CollisionWorld build_impl(const GaussianScene& scene, GaussianScene* consume,
                                   const WorldConfig& config, WorldBuildReport* report);
  // Boxes, bounds and the BVH over `records`, then the records permuted into BVH order and kept.
  template <class Records>
  void index(std::shared_ptr<Records> records);
  friend struct WorldCacheAccess;  // world_cache.cpp assembles a world from a mapped file
  std::span<const CollisionGaussian> gaussians_;
  std::shared_ptr<const void> storage_;  // keeps gaussians_ alive: a vector, or a mapped file
  Bvh bvh_;
  Eigen::Vector3d lo_ = Eigen::Vector3d::Zero(), hi_ = Eigen::Vector3d::Zero();
};

/// The index (0-2) of a Gaussian's shortest semi-axis (the first of equal ones): a disc's normal
/// is that column of its rotation.
[[nodiscard]] inline int thinnest_axis(const CollisionGaussian& g) noexcept {
  int j = 0;
  for (int k = 1; k < 3; ++k)
    if (g.semi_axes[k] < g.semi_axes[j]) j = k;
  return j;
}

/// The middle of a Gaussian's three semi-axes (world units).
[[nodiscard]] inline double middle_semi_axis(const CollisionGaussian& g) noexcept {
  const float* a = g.semi_axes;
  return std::max({std::min(a[0], a[1]), std::min(a[1], a[2]), std::min(a[0], a[2])});
}

/// How flat a Gaussian is, 1 - a_min / a_mid in [0, 1]: 1 for a disc (it states a normal), 0
/// when its two shortest semi-axes are equal (a rod or a ball states none); 0 when degenerate.
[[nodiscard]] inline double flatness(const CollisionGaussian& g) noexcept {
  const double mid = middle_semi_axis(g);
  return mid > 0 ? 1.0 - double(g.semi_axes[thinnest_axis(g)]) / mid : 0.0;
}

/// Rotation matrix of a stored Gaussian (world frame), from its quaternion exactly as the batch
/// kernel makes it (rotation_from_quaternion). Inline: the sweeps' bounds call it per candidate
/// (as a call it was 6 % of a compound tool's sweep profile).
[[nodiscard]] inline Eigen::Matrix3d rotation_matrix(const CollisionGaussian& g) noexcept {
  double r[9];
  rotation_from_quaternion<double>(g.quaternion[0], g.quaternion[1], g.quaternion[2], g.quaternion[3], r[0], r[1], r[2],
                                   r[3], r[4], r[5], r[6], r[7], r[8]);
  Eigen::Matrix3d R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R(i, j) = r[3 * i + j];
  return R;
}

/// Half-extents of the exact axis-aligned box of a rotated ellipsoid: sqrt(sum_k R_jk^2 a_k^2).
[[nodiscard]] Eigen::Vector3d ellipsoid_half_extent(const Eigen::Matrix3d& R,
                                                    const Eigen::Vector3d& semi_axes) noexcept;

}  // namespace gshaptics
