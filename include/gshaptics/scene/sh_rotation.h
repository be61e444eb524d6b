#pragma once
/// @file
/// Rotating the view-dependent colour (real spherical harmonics, bands 1-3) of 3DGS Gaussians
/// with the scene, so a registered or converted scene keeps its look from every side.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

namespace gshaptics {

/// The real SH basis of bands 1..3 exactly as 3DGS evaluates it (Kerbl et al., 2023, the
/// reference renderer's sh_utils constants), at a unit direction d = (x, y, z): 15 values,
/// band 1 first, in the order of the INRIA f_rest coefficients of one colour channel.
[[nodiscard]] std::array<double, 15> sh_basis_bands_1_to_3(const Eigen::Vector3d& d);

/// Per-band rotation matrices for SH coefficients: when a scene turns by `rotation` (directions
/// d -> R d), a channel's coefficients c (band l, 2l+1 values) become M_l c, so that the colour
/// seen along R d afterwards equals the colour seen along d before. Band l's matrix is the
/// least-squares solution of Y(d_j) M_l = Y(R^T d_j) over 32 fixed directions d_j, which is exact
/// because each band is closed under rotation.
class ShRotation {
 public:
  explicit ShRotation(const Eigen::Quaterniond& rotation);

  /// Rotates the coefficients of one Gaussian in place. `rest` holds 3 * k values, channel-
  /// major (INRIA f_rest order: all of red, then green, then blue), k = 3, 8 or 15 (bands up to
  /// 1, 2 or 3). Other k leave `rest` unchanged and return false.
  bool apply(float* rest, int k) const;

  [[nodiscard]] const Eigen::Matrix3d& band1() const { return m1_; }
  [[nodiscard]] const Eigen::Matrix<double, 5, 5>& band2() const { return m2_; }
  [[nodiscard]] const Eigen::Matrix<double, 7, 7>& band3() const { return m3_; }

 private:
  Eigen::Matrix3d m1_;
  Eigen::Matrix<double, 5, 5> m2_;
  Eigen::Matrix<double, 7, 7> m3_;
};

}  // namespace gshaptics
