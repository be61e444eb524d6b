// Narrow phase: K_min against closed forms and the dense float64 reference.

#include "gshaptics/narrowphase/k_min.h"

#include <gtest/gtest.h>

#include <random>

#include "support/reference.h"

namespace gshaptics {
namespace {

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}

test::LMatrix3 cov(const Eigen::Matrix3d& R, const Eigen::Vector3d& s) { return test::covariance(R, s); }

// Two spheres: K_min = 1 - D^2 / (r1 + r2)^2 (lambda* = r1 / (r1 + r2)), overlap iff D <= r1 + r2.
TEST(KMin, SphereSphereClosedForm) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.01, 2.0);
  for (int i = 0; i < 2000; ++i) {
    const double r_tool = u(rng), r_g = u(rng);
    const double D = u(rng) * 2 * (r_tool + r_g) / 2.0;
    const Eigen::Matrix3d Rr = random_rotation(rng);
    const Eigen::Vector3d d = Rr.col(0) * D;
    const PairCoefficients c = pair_coefficients(d, random_rotation(rng), Eigen::Vector3d::Constant(r_g),
                                                 random_rotation(rng), Eigen::Vector3d::Constant(r_tool));
    const KMinResult r = k_min(c);
    const double expected = 1 - D * D / ((r_tool + r_g) * (r_tool + r_g));
    EXPECT_NEAR(r.k_min, expected, 1e-12) << "D=" << D << " r1=" << r_tool << " r2=" << r_g;
    EXPECT_EQ(r.k_min > 0, D < r_tool + r_g);
  }
}

TEST(KMin, TouchingSpheresAreAtZero) {
  const PairCoefficients c = pair_coefficients(Eigen::Vector3d(3, 0, 0), Eigen::Matrix3d::Identity(),
                                               Eigen::Vector3d::Constant(2), Eigen::Matrix3d::Identity(),
                                               Eigen::Vector3d::Constant(1));
  EXPECT_NEAR(k_min(c).k_min, 0.0, 1e-14);
  EXPECT_NEAR(k_min(c).lambda, 1.0 / 3.0, 1e-7);
}

TEST(KMin, CoincidentCentresGiveOne) {
  const PairCoefficients c = pair_coefficients(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(),
                                               Eigen::Vector3d(1e-7, 1, 2), Eigen::Matrix3d::Identity(),
                                               Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(k_min(c).k_min, 1.0);
}

// Random ellipsoid pairs with aspect ratios up to 1e6 and size ratios up to 1e4, against the
// dense reference; both must agree to 1e-9 (the issue asks for 1e-5).
TEST(KMin, MatchesDenseReferenceOnRandomEllipsoids) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> logu(-4, 0.5);
  std::uniform_real_distribution<double> u(0, 1);
  double worst = 0;
  for (int i = 0; i < 5000; ++i) {
    const Eigen::Matrix3d Rg = random_rotation(rng), Rt = random_rotation(rng);
    Eigen::Vector3d sg, st;
    for (int k = 0; k < 3; ++k) {
      sg[k] = std::pow(10.0, logu(rng));
      st[k] = std::pow(10.0, 0.3 * logu(rng));
    }
    if (i % 5 == 0) sg[i % 3] = 1e-6;  // flat splats
    const Eigen::Vector3d dir = random_rotation(rng).col(0);
    const double reach = sg.maxCoeff() + st.maxCoeff();
    const Eigen::Vector3d d = dir * reach * 1.2 * u(rng);
    const double ref = test::reference_k_min(cov(Rg, sg), cov(Rt, st), d);
    const KMinResult r = k_min(pair_coefficients(d, Rg, sg, Rt, st));
    worst = std::max(worst, std::fabs(r.k_min - ref) / std::max(1.0, std::fabs(ref)));
    ASSERT_NEAR(r.k_min, ref, 1e-9 * std::max(1.0, std::fabs(ref))) << "pair " << i;
    ASSERT_LE(r.iterations, 60);
  }
  RecordProperty("worst_abs_error", std::to_string(worst));
}

TEST(KMin, GoldenSectionMatchesNewtonOnOrdinaryPairs) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.2, 1.0);
  KMinOptions golden{Minimiser::kGoldenSection, 30, false};
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d sg(u(rng), u(rng), u(rng)), st(u(rng), u(rng), u(rng));
    const Eigen::Vector3d d = random_rotation(rng).col(0) * 2 * u(rng);
    const PairCoefficients c = pair_coefficients(d, random_rotation(rng), sg, random_rotation(rng), st);
    const double newton = k_min(c).k_min;
    const double gs = k_min(c, golden).k_min;
    EXPECT_GE(gs, newton - 1e-12);  // golden can only be above the true minimum
    EXPECT_NEAR(gs, newton, 1e-6);
  }
}

TEST(KMin, EarlyExitOnlyWhenSeparated) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.05, 1.0);
  KMinOptions early;
  early.stop_when_separated = true;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d sg(u(rng), u(rng), u(rng)), st(u(rng), u(rng), u(rng));
    const Eigen::Vector3d d = random_rotation(rng).col(0) * 3 * u(rng);
    const PairCoefficients c = pair_coefficients(d, random_rotation(rng), sg, random_rotation(rng), st);
    const KMinResult full = k_min(c);
    const KMinResult fast = k_min(c, early);
    if (fast.separated_early) {
      EXPECT_LT(full.k_min, 0);
      EXPECT_LT(fast.k_min, 0);
    } else {
      EXPECT_DOUBLE_EQ(fast.k_min, full.k_min);
    }
  }
}

// The coefficient form must agree with K(lambda) evaluated densely at every lambda.
TEST(KMin, KOfLambdaMatchesDenseFormula) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0.01, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Matrix3d Rg = random_rotation(rng), Rt = random_rotation(rng);
    const Eigen::Vector3d sg(u(rng), u(rng), u(rng)), st(u(rng), u(rng), u(rng));
    const Eigen::Vector3d d = random_rotation(rng).col(1) * 2 * u(rng);
    const PairCoefficients c = pair_coefficients(d, Rg, sg, Rt, st);
    for (double l : {0.0, 0.1, 0.37, 0.5, 0.81, 0.999})
      EXPECT_NEAR(k_of_lambda(c, l), test::reference_k(cov(Rg, sg), cov(Rt, st), d, l), 1e-10);
  }
}

}  // namespace
}  // namespace gshaptics
