#include "support/reference.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

namespace gshaptics::test {

std::vector<RefGaussian> reference_world(const GaussianScene& scene, float min_opacity,
                                         double sigma, const SimilarityTransform& reg) {
  std::vector<RefGaussian> out;
  const Eigen::Matrix3d Rg = reg.rotation.normalized().toRotationMatrix();
  for (std::size_t i = 0; i < scene.size(); ++i) {
    if (!(scene.opacities[i] > min_opacity)) continue;
    const Eigen::Vector4f& q = scene.rotations[i];
    const Eigen::Matrix3d R =
        Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
    RefGaussian g;
    g.center = reg.scale * (Rg * scene.means[i].cast<double>()) + reg.translation;
    g.covariance = covariance(Rg * R, reg.scale * sigma * scene.scales[i].cast<double>());
    g.opacity = scene.opacities[i];
    g.index = scene.source_index[i];
    out.push_back(g);
  }
  return out;
}

LMatrix3 covariance(const Eigen::Matrix3d& R, const Eigen::Vector3d& s) {
  const LMatrix3 Rl = R.cast<long double>();
  LMatrix3 S2 = LMatrix3::Zero();
  for (int k = 0; k < 3; ++k) S2(k, k) = (long double)s[k] * (long double)s[k];
  return Rl * S2 * Rl.transpose();
}

double reference_k(const LMatrix3& cov_g, const LMatrix3& cov_t, const Eigen::Vector3d& d,
                   double lambda) {
  // Extended precision: near-singular blends (flat splats, lambda -> 1) stay accurate.
  using V3 = Eigen::Matrix<long double, 3, 1>;
  const long double l = lambda;
  const LMatrix3 A = l * cov_g + (1 - l) * cov_t;
  const V3 dl = d.cast<long double>();
  const V3 x = A.ldlt().solve(dl);
  return double(1.0L - l * (1 - l) * dl.dot(x));
}

double reference_k_min(const LMatrix3& cov_g, const LMatrix3& cov_t, const Eigen::Vector3d& d) {
  const double inv_phi = (std::sqrt(5.0) - 1) / 2;
  double a = 0, b = 1;
  double x1 = b - inv_phi * (b - a), x2 = a + inv_phi * (b - a);
  double f1 = reference_k(cov_g, cov_t, d, x1), f2 = reference_k(cov_g, cov_t, d, x2);
  for (int i = 0; i < 200 && b - a > 1e-17; ++i) {
    if (f1 < f2) {
      b = x2; x2 = x1; f2 = f1;
      x1 = b - inv_phi * (b - a); f1 = reference_k(cov_g, cov_t, d, x1);
    } else {
      a = x1; x1 = x2; f1 = f2;
      x2 = a + inv_phi * (b - a); f2 = reference_k(cov_g, cov_t, d, x2);
    }
  }
  return std::min(f1, f2);
}

LMatrix3 tool_covariance(const ToolEllipsoid& tool) {
  return covariance(tool.rotation.normalized().toRotationMatrix(), tool.semi_axes);
}

std::vector<RefContact> reference_contacts(const std::vector<RefGaussian>& world,
                                           const ToolEllipsoid& tool, double band,
                                           std::vector<RefContact>* near) {
  const LMatrix3 cov_t = tool_covariance(tool);
  std::vector<RefContact> out;
  for (const RefGaussian& g : world) {
    const Eigen::Vector3d d = g.center - tool.center;
    // Any lambda with K < 0 proves separation (the min is below it); 0.5 settles most pairs.
    if (reference_k(g.covariance, cov_t, d, 0.5) < -band) continue;
    const double k = reference_k_min(g.covariance, cov_t, d);
    if (k > 0) out.push_back({g.index, k});
    if (near != nullptr && std::fabs(k) <= band) near->push_back({g.index, k});
  }
  std::sort(out.begin(), out.end(), [](auto& a, auto& b) { return a.index < b.index; });
  return out;
}

double reference_k_min_of(const std::vector<RefGaussian>& world, const ToolEllipsoid& tool,
                          std::uint32_t index) {
  for (const RefGaussian& g : world)
    if (g.index == index)
      return reference_k_min(g.covariance, tool_covariance(tool), g.center - tool.center);
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace gshaptics::test
