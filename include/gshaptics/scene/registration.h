#pragma once
/// @file
/// Registration of a scene into the device's world frame by a similarity transform (paper eq. 3).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <string_view>

#include "gshaptics/io/gaussian_scene.h"

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
  /// A Gaussian's orientation in the world: R_g q for a quaternion (w, x, y, z) of any
  /// non-zero norm (raw trainer output is not normalised), normalised. Its scales map to
  /// `scale` * s_i.
  [[nodiscard]] Eigen::Quaterniond apply_rotation(const Eigen::Vector4f& q_wxyz) const {
    return (rotation * Eigen::Quaterniond(q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3]).normalized())
        .normalized();
  }
  [[nodiscard]] bool is_identity() const;
  /// JSON text in the registration-file format (see parse_registration_json).
  [[nodiscard]] std::string to_json() const;
};

/// Which of the scene's directions is "up": turned to world +z before the registration, so a
/// scene never comes out upside down by surprise. kAuto takes the file's convention (SceneFrame:
/// -y for PLY/.splat, +y for SPZ); kNone leaves the scene's axes as they are.
enum class UpAxis { kNone, kAuto, kYDown, kYUp, kZUp, kZDown, kXUp, kXDown };

/// "none", "auto", "y-down", "y-up", "z-up", "z-down", "x-up", "x-down" -> UpAxis. Throws
/// InputError naming `source` (an option or a field) for any other text.
[[nodiscard]] UpAxis parse_up_axis(std::string_view text, const std::string& source);
[[nodiscard]] std::string_view to_string(UpAxis up);

/// The scene direction `up` names, in scene coordinates (unit vector; zero for kNone).
[[nodiscard]] Eigen::Vector3d up_vector(UpAxis up, SceneFrame frame);

/// The whole scene -> world transform: first the rotation taking `up` to +z, then
/// `registration`: x_world = s R_g (R_up x) + t (paper eq. 3 with R_g R_up). kNone returns
/// `registration` unchanged.
[[nodiscard]] SimilarityTransform with_up_axis(const SimilarityTransform& registration, UpAxis up,
                                               SceneFrame frame);

/// The world's up direction (unit vector, world frame) after with_up_axis(registration, up,
/// frame): the scene's up -- the axis `up` names, or the file's convention (up_of) for kNone and
/// kAuto -- carried through the whole rotation. A registration that already turns the scene
/// z-up (the bundled Truck's) gives +z with UpAxis::kNone; so does kAuto without a registration.
[[nodiscard]] Eigen::Vector3d world_up(const SimilarityTransform& registration, UpAxis up,
                                       SceneFrame frame);

/// True when both `up` (not kNone) and the registration's rotation turn the scene (rotation
/// angle above 1e-6 rad): the scene is then rotated twice, which is rarely meant.
[[nodiscard]] bool rotates_twice(const SimilarityTransform& registration, UpAxis up);

/// True when `up` names an axis (not kNone or kAuto) that points against the file's own
/// convention's up (up_of(frame)): a PLY or .splat scene (y down) given --up y-up, say, which
/// stands it on its head. A captured object seen from above is then its underside.
[[nodiscard]] bool turns_upside_down(UpAxis up, SceneFrame frame);

/// The transform `convert` applies so that the written file, read in its own format's
/// convention `to`, gives the same world under --up auto as the source (convention `from`)
/// gives under `up` and `registration`:
///   T = R_z(to)^-1 * A * with_up_axis(registration, up, from),
/// where R_z(to) = frame_to_z_up(to) and A turns world_up(...) to +z by the shortest arc (the
/// identity when the world is already z-up). Converting SPZ (RUB) to PLY (RDF) with no options
/// is then the half turn about x, (x, y, z) -> (x, -y, -z).
[[nodiscard]] SimilarityTransform conversion_transform(const SimilarityTransform& registration,
                                                       UpAxis up, SceneFrame from, SceneFrame to);

/// Applies a registration to every Gaussian (eq. 3): means s R mu + t, rotations R q, scales
/// s * scale. Colour is copied and SH bands 1-3 are rotated with the scene (ShRotation), so the
/// view-dependent colour turns with it exactly.
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
