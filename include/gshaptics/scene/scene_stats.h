#pragma once
/// @file
/// Summary statistics of a scene, as printed by `gshaptics info` (same quantities as SOURCES.md).

#include <Eigen/Core>
#include <array>
#include <string>

#include "gshaptics/scene/registration.h"

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
  /// Median middle axis over the Gaussians a viewer draws (opacity >= 1/255): a typical disc's
  /// in-plane scale, SeenSolid::typical_scale() before the registration's scale (0: none drawn).
  double drawn_middle_scale = 0;
};

/// Computes the statistics; an empty scene gives zeros.
[[nodiscard]] SceneStats compute_scene_stats(const GaussianScene& scene);

/// The world a scene becomes, seen before any BVH is built (`gshaptics info --up/--registration`).
/// Positions are the centres of the Gaussians kept by the opacity filter, in the world frame.
struct WorldPreview {
  std::size_t kept = 0;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  ///< the world's up (unit), as given
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero(), bbox_max = Eigen::Vector3d::Zero();
  Eigen::Vector3d p01 = Eigen::Vector3d::Zero(), p99 = Eigen::Vector3d::Zero();  ///< per world axis
  double robust_size = 0;  ///< largest 1-99 percentile extent over the world axes (world units)
};

/// Previews the world of `scene` under an opacity threshold (keep alpha > min_opacity) and the
/// whole scene -> world transform, with `up` the world's up (world_up in registration.h).
[[nodiscard]] WorldPreview preview_world(const GaussianScene& scene, float min_opacity,
                                         const SimilarityTransform& scene_to_world,
                                         const Eigen::Vector3d& up);

/// A registration scale and tool radius for a device class, with the reasoning in one line.
struct ScaleAdvice {
  double reg_scale = 1;    ///< --reg-scale: world metres per current world unit
  double tool_radius = 0;  ///< tool radius after that scale, m (1 % of the object's size)
  std::string reason;
};

/// For a desktop device (a workspace of about 16 x 12 x 7 cm, a Touch or a Falcon): the object's
/// robust size fits in 0.12 m. `robust_size` in current world units.
[[nodiscard]] ScaleAdvice desktop_scale_advice(double robust_size);
/// For room scale (a tracked VR controller, an arm): keep the size when it is plausible in metres
/// (0.2..20), else the power of ten (centimetres, millimetres, ...) that brings it to 0.5..5 m.
[[nodiscard]] ScaleAdvice room_scale_advice(double robust_size);

}  // namespace gshaptics
