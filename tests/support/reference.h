#pragma once
// An independent, slow, obviously-correct float64 reference for the collision pipeline.
// It shares nothing with the fast path beyond the loaders: no BVH, no sphere pre-filter, no
// coefficient form. K(lambda) is evaluated with a dense 3x3 solve exactly as written in
// docs/design.md Sec. 3 and minimised by a 200-step golden-section search (convex on [0, 1]).

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "gshaptics/collision/tool_ellipsoid.h"
#include "gshaptics/io/gaussian_scene.h"
#include "gshaptics/scene/registration.h"

namespace gshaptics::test {

/// Extended precision: a flat splat's covariance (eigenvalues 1e-12 next to 1) is only exact to
/// ~1e-4 relative in its thin direction when stored in double.
using LMatrix3 = Eigen::Matrix<long double, 3, 3>;

struct RefGaussian {
  Eigen::Vector3d center;
  LMatrix3 covariance;  // of the k-sigma ellipsoid: k^2 s^2 R_g R S^2 R^T R_g^T
  float opacity;
  std::uint32_t index;
};

/// Filters (alpha > tau) and registers a scene in double precision (paper eq. 3).
std::vector<RefGaussian> reference_world(const GaussianScene& scene, float min_opacity,
                                         double sigma, const SimilarityTransform& reg);

/// K(lambda) = 1 - lambda (1 - lambda) d^T [lambda S_g + (1 - lambda) S_t]^-1 d.
double reference_k(const LMatrix3& cov_g, const LMatrix3& cov_t, const Eigen::Vector3d& d,
                   double lambda);

/// min over [0, 1] of reference_k (golden section to machine precision).
double reference_k_min(const LMatrix3& cov_g, const LMatrix3& cov_t, const Eigen::Vector3d& d);

/// R diag(s^2) R^T in extended precision.
LMatrix3 covariance(const Eigen::Matrix3d& R, const Eigen::Vector3d& s);

/// Tool covariance R diag(a^2) R^T.
LMatrix3 tool_covariance(const ToolEllipsoid& tool);

struct RefContact {
  std::uint32_t index;
  double k_min;
};

/// Every Gaussian with K_min > 0, by brute force over the whole world, sorted by index.
/// Also returns (in `near`) those with |K_min| <= `band`, the grazing pairs either side.
std::vector<RefContact> reference_contacts(const std::vector<RefGaussian>& world,
                                           const ToolEllipsoid& tool, double band = 0,
                                           std::vector<RefContact>* near = nullptr);

/// K_min of Gaussian `index` (source index) against the tool, or NaN when not in the world.
double reference_k_min_of(const std::vector<RefGaussian>& world, const ToolEllipsoid& tool,
                          std::uint32_t index);

}  // namespace gshaptics::test
