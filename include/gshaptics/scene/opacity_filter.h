#pragma once
/// @file
/// Opacity filter of paper Sec. III-A: keep Gaussians with alpha > tau.

#include <cstddef>

#include "gshaptics/io/gaussian_scene.h"

namespace gshaptics {

/// Paper Sec. III-A recommends tau in 0.1 .. 0.3; the default is 0.2 (WorldConfig::min_opacity).
inline constexpr float kDefaultMinOpacity = 0.2f;
/// The filter for a world whose solid composites every Gaussian a viewer draws (the seen solid,
/// force/seen_solid.h): just under 1/255, the 3DGS rasterizer's skip threshold.
inline constexpr float kSeenMinOpacity = 0.0039f;

/// How much the filter removed.
struct OpacityFilterReport {
  float min_opacity = kDefaultMinOpacity;
  std::size_t before = 0;
  std::size_t after = 0;
  [[nodiscard]] double kept_fraction() const { return before ? double(after) / double(before) : 0.0; }
};

/// Returns the Gaussians with opacity strictly above `min_opacity`, in their original order and
/// keeping `source_index`. `min_opacity` of 0 keeps every Gaussian with alpha > 0.
[[nodiscard]] GaussianScene filter_by_opacity(const GaussianScene& scene, float min_opacity,
                                              OpacityFilterReport* report = nullptr);

}  // namespace gshaptics
