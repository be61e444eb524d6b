#pragma once
/// @file
/// Registration of a scene into the device's world frame by a similarity transform (paper eq. 3).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>

namespace gshaptics {

/// x_world = scale * R_g * x_scene + translation (paper eq. 3); covariances map as
/// Sigma_world = scale^2 R_g Sigma R_g^T. Units: `translation` in world units (metres for a
/// registered scene), `scale` in world units per scene unit.
struct SimilarityTransform {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  ///< R_g, unit quaternion
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  [[nodiscard]] Eigen::Vector3d apply(const Eigen::Vector3d& p) const {
    return scale * (rotation * p) + translation;
  }
  [[nodiscard]] bool is_identity() const;
  /// JSON text in the registration-file format (see parse_registration_json).
  [[nodiscard]] std::string to_json() const;
};

struct GaussianScene;

/// Applies a registration to every Gaussian (eq. 3): means s R mu + t, rotations R q, scales
/// s * scale. Colour is copied; SH bands above 0 are not rotated (view-dependent colour then
/// turns with the scene only approximately).
[[nodiscard]] GaussianScene transform_scene(const GaussianScene& scene, const SimilarityTransform& t);

/// Parses `{"scale": s, "rotation": [w, x, y, z], "translation": [x, y, z]}`; every key is
/// optional, and `"matrix"` (3x3 row-major, nested or flat) may replace `"rotation"`.
/// Quaternions are normalised; a matrix must be orthonormal with determinant +1 (tolerance 1e-6).
/// Throws InputError naming `source` (a file path or option) and the offending field.
[[nodiscard]] SimilarityTransform parse_registration_json(const std::string& text,
                                                          const std::string& source);

/// Reads a registration file (see parse_registration_json). Throws InputError.
[[nodiscard]] SimilarityTransform load_registration_file(const std::string& path);

}  // namespace gshaptics
