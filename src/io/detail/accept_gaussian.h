#pragma once
// Shared validation for every loader: decodes nothing, only checks and counts.

#include <cmath>
#include <cstdint>

#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics::detail {

/// Checks one decoded Gaussian (linear scales, raw quaternion w,x,y,z, opacity after sigmoid),
/// normalises its quaternion and appends it to `out`, or counts why it was skipped.
/// `raw_finite` is false when any value as stored in the file was NaN/Inf (a logit of +inf
/// decodes to a finite opacity, but the file is still broken there).
inline bool accept_gaussian(const float pos[3], const float scale[3], const float quat[4],
                            float opacity, std::uint32_t source, GaussianScene& out,
                            LoadReport& report, bool raw_finite = true) {
  bool finite = raw_finite && std::isfinite(opacity);
  for (int k = 0; k < 3; ++k) finite = finite && std::isfinite(pos[k]) && std::isfinite(scale[k]);
  for (int k = 0; k < 4; ++k) finite = finite && std::isfinite(quat[k]);
  if (!finite) {
    ++report.skipped_non_finite;
    return false;
  }
  const double norm2 = double(quat[0]) * quat[0] + double(quat[1]) * quat[1] +
                       double(quat[2]) * quat[2] + double(quat[3]) * quat[3];
  if (!(norm2 > 1e-12)) {
    ++report.skipped_zero_quaternion;
    return false;
  }
  if (!(scale[0] > 0.f && scale[1] > 0.f && scale[2] > 0.f)) {
    ++report.skipped_bad_scale;
    return false;
  }
  const double inv = 1.0 / std::sqrt(norm2);
  const Eigen::Vector4f q(float(quat[0] * inv), float(quat[1] * inv), float(quat[2] * inv),
                          float(quat[3] * inv));
  // Opacity of a well-formed file is already in [0, 1]; clamp guards rounding of a sigmoid.
  const float alpha = opacity < 0.f ? 0.f : (opacity > 1.f ? 1.f : opacity);
  out.push_back(Eigen::Vector3f(pos[0], pos[1], pos[2]),
                Eigen::Vector3f(scale[0], scale[1], scale[2]), q, alpha, source);
  ++report.loaded;
  return true;
}

/// Starts every reader's result: the report's identity fields and room for `in_file` Gaussians.
inline LoadedScene start_load(const std::string& path, SceneFormat format, SceneFrame frame,
                              std::uint64_t in_file) {
  LoadedScene out;
  out.report.path = path;
  out.report.format = format;
  out.report.frame = frame;
  out.scene.frame = frame;
  out.report.in_file = in_file;
  out.scene.reserve(in_file);
  return out;
}

/// Ends every reader: final progress, and an error for a file with no valid Gaussian at all
/// (a loader never returns an empty scene without saying why).
inline void finish_load(const LoadedScene& out, const std::string& path, std::uint64_t in_file,
                        const ProgressFn& progress) {
  if (progress) progress(1.0);
  if (out.scene.empty())
    throw file_error(path, "no valid Gaussian among " + std::to_string(in_file) +
                               " (all had NaN/Inf, zero quaternions or bad scales)");
}

/// SH band-0 constant: colour = 0.5 + kShC0 * f_dc.
inline constexpr float kShC0 = 0.28209479177387814f;

/// Logistic sigmoid in double, stable for large |x| (opacity logits of +-40 occur in real files).
inline float sigmoid(float logit) {
  const double x = logit;
  return float(x >= 0 ? 1.0 / (1.0 + std::exp(-x)) : std::exp(x) / (1.0 + std::exp(x)));
}

}  // namespace gshaptics::detail
