#pragma once
/// @file
/// The Gaussians of a trained 3DGS scene, as loaded (structure of arrays).

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace gshaptics {

/// All Gaussians of a scene in the scene's own frame, one entry per Gaussian in each array
/// (paper Sec. III-A, eq. 1-2). Values are in the decoded, physical form:
/// - `means`: centre mu_i (scene units), N x 3;
/// - `scales`: linear standard deviations s_i along the Gaussian's own axes (> 0), N x 3;
/// - `rotations`: unit quaternions (w, x, y, z), N x 4, so that Sigma_i = R_i S_i S_i^T R_i^T (eq. 2);
/// - `opacities`: alpha_i in [0, 1] (after the sigmoid), N;
/// - `source_index`: index of the Gaussian in the original file, N. Loaders skip invalid
///   Gaussians, so this is not always the identity; every contact reports this index.
/// Colour is kept only for conversion (the haptic pipeline does not use it):
/// - `colors_dc`: SH band-0 coefficients f_dc (N x 3), empty when the file has no colour;
/// - `sh_rest`: higher SH coefficients f_rest_* in the INRIA order (channel-major),
///   `sh_rest_count` per Gaussian (0, 9, 24 or 45), N * sh_rest_count values.
struct GaussianScene {
  std::vector<Eigen::Vector3f> means;
  std::vector<Eigen::Vector3f> scales;
  std::vector<Eigen::Vector4f> rotations;
  std::vector<float> opacities;
  std::vector<std::uint32_t> source_index;
  std::vector<Eigen::Vector3f> colors_dc;
  std::vector<float> sh_rest;
  int sh_rest_count = 0;

  /// Copies Gaussian `i` of `other` (all fields, colour included when both have it) to the end.
  void push_back_from(const GaussianScene& other, std::size_t i);

  [[nodiscard]] std::size_t size() const { return means.size(); }
  [[nodiscard]] bool empty() const { return means.empty(); }
  void reserve(std::size_t n);
  /// Appends one Gaussian; `rotation_wxyz` must already be normalised.
  void push_back(const Eigen::Vector3f& mean, const Eigen::Vector3f& scale,
                 const Eigen::Vector4f& rotation_wxyz, float opacity, std::uint32_t source);
};

}  // namespace gshaptics
