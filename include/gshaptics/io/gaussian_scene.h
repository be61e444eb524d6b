#pragma once
/// @file
/// The Gaussians of a trained 3DGS scene, as loaded (structure of arrays).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

namespace gshaptics {

/// The coordinate convention a file's Gaussians are stored in (loaders do not convert).
enum class SceneFrame {
  kRdf,  ///< x right, y down, z forward: the 3DGS / COLMAP / OpenCV convention (PLY, .splat)
  kRub,  ///< x right, y up, z back: the OpenGL convention of SPZ
};

[[nodiscard]] std::string_view to_string(SceneFrame frame);

/// The scene's up direction in its own coordinates (RDF: -y; RUB: +y), unit vector.
[[nodiscard]] Eigen::Vector3d up_of(SceneFrame frame);

/// Rotation taking a frame's "up" to world +z (RDF: -y up; RUB: +y up), for z-up worlds.
[[nodiscard]] Eigen::Quaterniond frame_to_z_up(SceneFrame frame);

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
  /// Convention of `means` and `rotations`, set by the loader from the file's format.
  SceneFrame frame = SceneFrame::kRdf;

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
