// The support normal of a tool part on a patch of Gaussians (support_normal.h): the support gap
// against ellipsoid surface points sampled by brute force, the maximiser against a dense search
// over the sphere computed independently here, and the answers on a face and across an edge.

#include "gshaptics/force/support_normal.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

namespace gshaptics {
namespace {

constexpr double kPi = 3.14159265358979323846;

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180 / kPi;
}

// A flat disc (semi-axes r, r, t) centred at c with normal n.
PatchGaussian disc(const Eigen::Vector3d& c, const Eigen::Vector3d& n, double r, double t, double weight = 1.0) {
  const Eigen::Matrix3d rot = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n).toRotationMatrix();
  PatchGaussian g;
  g.center = c;
  g.shape = rot * Eigen::Vector3d(r * r, r * r, t * t).asDiagonal() * rot.transpose();
  g.weight = weight;
  return g;
}

// Points on an ellipsoid {x : (x - c)^T M^-1 (x - c) = 1}, Fibonacci-spread.
std::vector<Eigen::Vector3d> surface(const Eigen::Vector3d& c, const Eigen::Matrix3d& m, int count) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(m);
  const Eigen::Matrix3d root = es.eigenvectors() * es.eigenvalues().cwiseSqrt().asDiagonal() * es.eigenvectors().transpose();
  std::vector<Eigen::Vector3d> out;
  for (int s = 0; s < count; ++s) {
    const double z = -1 + 2 * (s + 0.5) / count, phi = s * 2.399963229728653;
    const Eigen::Vector3d u(std::sqrt(1 - z * z) * std::cos(phi), std::sqrt(1 - z * z) * std::sin(phi), z);
    out.push_back(c + root * u);
  }
  return out;
}

// The soft minimum S(n) computed here from its definition, in long double.
long double soft_min(const ToolEllipsoid& part, const std::vector<PatchGaussian>& patch, const Eigen::Vector3d& n,
                     double tau) {
  const Eigen::Matrix3d r = part.rotation.toRotationMatrix();
  const Eigen::Matrix3d mp = r * part.semi_axes.array().square().matrix().asDiagonal() * r.transpose();
  std::vector<long double> gaps;
  long double lo = INFINITY;
  for (const PatchGaussian& g : patch) {
    const long double gap = (long double)n.dot(part.center - g.center) - std::sqrt((long double)n.dot(mp * n)) -
                            std::sqrt((long double)n.dot(g.shape * n));
    gaps.push_back(gap);
    lo = std::min(lo, gap);
  }
  long double z = 0;
  for (std::size_t i = 0; i < patch.size(); ++i) z += patch[i].weight * std::exp(-(gaps[i] - lo) / tau);
  return lo - tau * std::log(z);
}

// The maximiser of S by a dense search: a Fibonacci sphere, then finer rings around the best.
Eigen::Vector3d dense_maximiser(const ToolEllipsoid& part, const std::vector<PatchGaussian>& patch, double tau) {
  Eigen::Vector3d best = Eigen::Vector3d::UnitZ();
  long double bs = -INFINITY;
  const int count = 40000;
  for (int s = 0; s < count; ++s) {
    const double z = -1 + 2 * (s + 0.5) / count, phi = s * 2.399963229728653;
    const Eigen::Vector3d n(std::sqrt(1 - z * z) * std::cos(phi), std::sqrt(1 - z * z) * std::sin(phi), z);
    const long double v = soft_min(part, patch, n, tau);
    if (v > bs) {
      bs = v;
      best = n;
    }
  }
  for (double radius = 0.02; radius > 1e-6; radius *= 0.5) {
    const Eigen::Vector3d u = best.unitOrthogonal(), w = best.cross(u);
    Eigen::Vector3d next = best;
    for (int k = 0; k < 64; ++k)
      for (double f : {0.5, 1.0}) {
        const double a = 2 * kPi * k / 64;
        const Eigen::Vector3d n = (best + f * radius * (std::cos(a) * u + std::sin(a) * w)).normalized();
        const long double v = soft_min(part, patch, n, tau);
        if (v > bs) {
          bs = v;
          next = n;
        }
      }
    best = next;
  }
  return best;
}

TEST(SupportNormal, TheGapIsTheDistanceBetweenTheSupportPlanesOfSampledSurfaces) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 20; ++trial) {
    ToolEllipsoid part;
    part.center = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.02;
    part.rotation = Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng)).normalized());
    part.semi_axes = Eigen::Vector3d(0.002 + 0.01 * std::abs(u(rng)), 0.002 + 0.01 * std::abs(u(rng)), 0.003);
    const PatchGaussian g = disc(Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.02,
                                 Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized(), 0.004, 0.0005);
    const Eigen::Vector3d n = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    double part_low = INFINITY, g_high = -INFINITY;
    for (const Eigen::Vector3d& x : surface(part.center, shape_matrix(part), 20000)) part_low = std::min(part_low, n.dot(x));
    for (const Eigen::Vector3d& y : surface(g.center, g.shape, 20000)) g_high = std::max(g_high, n.dot(y));
    EXPECT_NEAR(support_gap(part, g, n), part_low - g_high, 2e-5);  // sampling resolution
  }
}

TEST(SupportNormal, OnAFaceOfDiscsItIsTheFaceNormalFromATiltedStart) {
  // A 5 mm sphere 0.3 mm above a grid of 2 mm discs on z = 0, with 0.1 mm height jitter.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter(-1e-4, 1e-4);
  std::vector<PatchGaussian> patch;
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j)
      patch.push_back(disc({i * 0.0015, j * 0.0015, jitter(rng)}, Eigen::Vector3d::UnitZ(), 0.001, 1e-5));
  ToolEllipsoid sphere;
  sphere.semi_axes = Eigen::Vector3d::Constant(0.005);
  sphere.center = {0, 0, 0.0053};
  const Eigen::Vector3d start = Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitX()) * Eigen::Vector3d::UnitZ();
  const SupportNormal sn = support_normal(sphere, patch, start, 0.0005);
  ASSERT_NEAR(sn.normal.norm(), 1.0, 1e-12);
  EXPECT_LT(angle_deg(sn.normal, Eigen::Vector3d::UnitZ()), 1.0);
  EXPECT_LT(angle_deg(sn.normal, dense_maximiser(sphere, patch, 0.0005)), 0.05);
  EXPECT_GT(sn.iterations, 0);
}

TEST(SupportNormal, AcrossAnEdgeItIsTheToolsOwnNormalWhereItRestsOnTheEdge) {
  // Discs on the top face (z = 0, x < 0) and the side face (x = 0, z < 0) of a block whose edge
  // runs along y; a stylus-like ellipsoid (15 x 5 x 5 mm) crossing the edge at 30 deg downward,
  // resting on it. The contact normal of a cylinder on a line is perpendicular to both: here it
  // is tilted 30 deg from +z toward +x, which neither face's normal nor their blend gives.
  std::vector<PatchGaussian> patch;
  for (int i = 0; i < 6; ++i)
    for (int j = -5; j <= 5; ++j) {
      patch.push_back(disc({-0.001 - i * 0.002, j * 0.002, 0}, Eigen::Vector3d::UnitZ(), 0.0012, 1e-5));
      patch.push_back(disc({0, j * 0.002, -0.001 - i * 0.002}, Eigen::Vector3d::UnitX(), 0.0012, 1e-5));
    }
  const double tilt = 30 * kPi / 180;
  const Eigen::Vector3d axis(std::cos(tilt), 0, -std::sin(tilt));  // the stylus's long axis, down across the edge
  const Eigen::Vector3d expected(std::sin(tilt), 0, std::cos(tilt));
  ToolEllipsoid stylus;
  stylus.semi_axes = {0.015, 0.005, 0.005};
  stylus.rotation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitX(), axis);
  stylus.center = expected * 0.0051;  // its side 0.1 mm off the edge
  const double tau = 0.0005;
  for (const Eigen::Vector3d& start : {Eigen::Vector3d(Eigen::Vector3d::UnitZ()), Eigen::Vector3d(Eigen::Vector3d::UnitX()),
                                       Eigen::Vector3d(1, 0, 1).normalized()}) {
    const SupportNormal sn = support_normal(stylus, patch, start, tau);
    EXPECT_LT(angle_deg(sn.normal, dense_maximiser(stylus, patch, tau)), 0.05);
    EXPECT_LT(angle_deg(sn.normal, expected), 3.0);
    EXPECT_GT(angle_deg(sn.normal, Eigen::Vector3d(1, 0, 1).normalized()), 10.0);  // not the faces' blend
  }
}

TEST(SupportNormal, AnEmptyPatchOrABadStartGivesNoNormal) {
  ToolEllipsoid part;
  std::vector<PatchGaussian> none;
  EXPECT_EQ(support_normal(part, none, Eigen::Vector3d::UnitZ(), 1e-3).normal, Eigen::Vector3d::Zero());
  std::vector<PatchGaussian> one{disc({0, 0, -0.02}, Eigen::Vector3d::UnitZ(), 0.002, 1e-4)};
  EXPECT_EQ(support_normal(part, one, Eigen::Vector3d::Zero(), 1e-3).normal, Eigen::Vector3d::Zero());
  EXPECT_EQ(support_normal(part, one, Eigen::Vector3d(NAN, 0, 1), 1e-3).normal, Eigen::Vector3d::Zero());
  EXPECT_EQ(support_normal(part, one, Eigen::Vector3d::UnitZ(), 0).normal, Eigen::Vector3d::Zero());
  // One Gaussian straight below: the normal points from it to the part.
  const SupportNormal sn = support_normal(part, one, Eigen::Vector3d(0.3, 0, 1).normalized(), 1e-3);
  EXPECT_LT(angle_deg(sn.normal, Eigen::Vector3d::UnitZ()), 0.01);
  EXPECT_NEAR(sn.separation, 0.02 - 0.01 - 1e-4, 1e-9);
}

}  // namespace
}  // namespace gshaptics
