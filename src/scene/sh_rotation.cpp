#include "gshaptics/scene/sh_rotation.h"

#include <Eigen/Dense>
#include <cmath>

namespace gshaptics {

std::array<double, 15> sh_basis_bands_1_to_3(const Eigen::Vector3d& d) {
  // Constants of the real SH basis as the 3DGS reference renderer uses them.
  constexpr double c1 = 0.4886025119029199;
  constexpr double c2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
                            -1.0925484305920792, 0.5462742152960396};
  constexpr double c3[7] = {-0.5900435899266435, 2.890611442640554, -0.4570457994644658,
                            0.3731763325901154,  -0.4570457994644658, 1.445305721320277,
                            -0.5900435899266435};
  const double x = d.x(), y = d.y(), z = d.z();
  const double xx = x * x, yy = y * y, zz = z * z;
  return {-c1 * y,
          c1 * z,
          -c1 * x,
          c2[0] * x * y,
          c2[1] * y * z,
          c2[2] * (2 * zz - xx - yy),
          c2[3] * x * z,
          c2[4] * (xx - yy),
          c3[0] * y * (3 * xx - yy),
          c3[1] * x * y * z,
          c3[2] * y * (4 * zz - xx - yy),
          c3[3] * z * (2 * zz - 3 * xx - 3 * yy),
          c3[4] * x * (4 * zz - xx - yy),
          c3[5] * z * (xx - yy),
          c3[6] * x * (xx - 3 * yy)};
}

namespace {

template <int N>
Eigen::Matrix<double, N, N> band_matrix(const Eigen::Matrix3d& r, int first) {
  constexpr int kDirections = 32;
  Eigen::Matrix<double, kDirections, N> a, b;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int j = 0; j < kDirections; ++j) {
    // Fibonacci sphere: well spread, fixed directions.
    const double z = 1.0 - (2.0 * j + 1.0) / kDirections;
    const double rho = std::sqrt(1.0 - z * z);
    const Eigen::Vector3d d(rho * std::cos(golden * j), rho * std::sin(golden * j), z);
    const auto ya = sh_basis_bands_1_to_3(d);
    const auto yb = sh_basis_bands_1_to_3(r.transpose() * d);
    for (int k = 0; k < N; ++k) {
      a(j, k) = ya[std::size_t(first + k)];
      b(j, k) = yb[std::size_t(first + k)];
    }
  }
  return a.colPivHouseholderQr().solve(b);
}

template <int N>
void apply_band(const Eigen::Matrix<double, N, N>& m, float* channel, int first) {
  Eigen::Matrix<double, N, 1> c;
  for (int k = 0; k < N; ++k) c[k] = channel[first + k];
  c = m * c;
  for (int k = 0; k < N; ++k) channel[first + k] = float(c[k]);
}

}  // namespace

ShRotation::ShRotation(const Eigen::Quaterniond& rotation) {
  const Eigen::Matrix3d r = rotation.normalized().toRotationMatrix();
  m1_ = band_matrix<3>(r, 0);
  m2_ = band_matrix<5>(r, 3);
  m3_ = band_matrix<7>(r, 8);
}

bool ShRotation::apply(float* rest, int k) const {
  if (k != 3 && k != 8 && k != 15) return false;
  for (int ch = 0; ch < 3; ++ch) {
    float* c = rest + ch * k;
    apply_band<3>(m1_, c, 0);
    if (k >= 8) apply_band<5>(m2_, c, 3);
    if (k >= 15) apply_band<7>(m3_, c, 8);
  }
  return true;
}

}  // namespace gshaptics
