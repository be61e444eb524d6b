// The continuous first-contact query under the proxy (SweepQuery): exact first contact against
// bisection on the exact overlap test, thin plates crossed in one motion, ellipsoidal tools,
// grazing paths, ignore lists and hints.

#include "gshaptics/collision/sweep_query.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

#include "support/gaussian_worlds.h"

namespace gshaptics {
namespace {

using test::add_layer;
using test::GaussianSpec;
using test::world_of;

TEST(SweepQuery, FirstContactMatchesBisectionOnTheExactOverlapTest) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-1, 1), lg(-2.5, -1);
  int hits = 0;
  for (int i = 0; i < 300; ++i) {
    const Eigen::Quaternionf q = Eigen::Quaternionf(float(u(rng)), float(u(rng)), float(u(rng)), float(u(rng))).normalized();
    Eigen::Vector3f a(float(std::pow(10, lg(rng))), float(std::pow(10, lg(rng))), float(std::pow(10, lg(rng))));
    if (i % 3 == 0) a.z() = 1e-6f;  // flat splats
    const CollisionWorld w = world_of({{Eigen::Vector3f::Zero(), a, q}});
    ToolEllipsoid tool;
    tool.semi_axes = i % 2 ? Eigen::Vector3d::Constant(0.01)
                           : Eigen::Vector3d(0.01, 0.02, 0.005);  // ellipsoidal tools too
    tool.rotation = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    const Eigen::Vector3d dir = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    tool.center = -dir * 0.15 + Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.02;
    const Eigen::Vector3d motion = dir * 0.3;
    SweepQuery sweep(w);
    const SweepHit hit = sweep.first_contact(tool, motion);
    // Reference: the first overlapping sample on a fine grid, refined by bisection.
    ToolEllipsoid t = tool;
    double lo = 0, hi = -1;
    for (int k = 1; k <= 3000; ++k) {
      t.center = tool.center + motion * (k / 3000.0);
      if (test::overlaps(w, t)) {
        hi = k / 3000.0;
        lo = (k - 1) / 3000.0;
        break;
      }
    }
    if (hi < 0) {
      EXPECT_FALSE(hit.hit) << i;
      continue;
    }
    for (int it = 0; it < 40; ++it) {
      t.center = tool.center + motion * (0.5 * (lo + hi));
      (test::overlaps(w, t) ? hi : lo) = 0.5 * (lo + hi);
    }
    ++hits;
    ASSERT_TRUE(hit.hit) << i;
    EXPECT_NEAR(hit.t, lo, 2e-6) << i;        // 0.6 um of a 30 cm motion
    EXPECT_LE(hit.t, hi + 1e-7) << i;  // never past the contact (the reference decides K_min > 0 to 1e-6)
    EXPECT_NEAR(hit.normal.norm(), 1.0, 1e-9);
    EXPECT_LT(hit.normal.dot(motion), 0) << i;  // it opposes the motion
  }
  EXPECT_GT(hits, 60);
}

TEST(SweepQuery, AThinPlateIsHitWhenTheWholePlateIsCrossedInOneMotion) {
  // Discs 2 um thick; the motion starts 10 mm above and ends 10 mm below: a one-tick crossing.
  std::vector<GaussianSpec> gs;
  for (float x = -0.03f; x <= 0.03f; x += 0.003f)
    for (float y = -0.03f; y <= 0.03f; y += 0.003f)
      gs.emplace_back(Eigen::Vector3f(x, y, 0), Eigen::Vector3f(0.003f, 0.003f, 1e-6f), Eigen::Quaternionf::Identity());
  const CollisionWorld w = world_of(gs);
  const double r = 0.004;
  for (const double z0 : {0.014, 0.02, 0.1}) {
    const ToolEllipsoid tool = ToolEllipsoid::sphere({0.0011, -0.0007, z0}, r);
    const Eigen::Vector3d motion(0, 0, -2 * z0);
    SweepQuery sweep(w);
    const SweepHit hit = sweep.first_contact(tool, motion);
    ASSERT_TRUE(hit.hit) << z0;
    // First contact: the sphere's bottom on the discs' top, at most 1 um above z = 0.
    const double z_hit = z0 + motion.z() * hit.t;
    EXPECT_GE(z_hit, r - 1e-9) << z0;
    EXPECT_LE(z_hit, r + 1e-6 + 1e-7) << z0;
    EXPECT_GT(hit.normal.z(), 0.99) << z0;
  }
}

TEST(SweepQuery, ALimitKeepsContactsUpToItAndDropsTheLaterOnes) {
  // A grid of discs at z = 0 and a second one at z = -0.02: a sphere moving down 60 mm.
  std::vector<GaussianSpec> gs;
  for (float x = -0.03f; x <= 0.03f; x += 0.003f)
    for (float y = -0.03f; y <= 0.03f; y += 0.003f)
      for (float z : {0.0f, -0.02f})
        gs.emplace_back(Eigen::Vector3f(x, y, z), Eigen::Vector3f(0.003f, 0.003f, 1e-6f), Eigen::Quaternionf::Identity());
  const CollisionWorld w = world_of(gs);
  const ToolEllipsoid tool = ToolEllipsoid::sphere({0.0011, -0.0007, 0.03}, 0.004);
  const Eigen::Vector3d motion(0, 0, -0.06);
  SweepQuery sweep(w);
  const SweepHit free = sweep.first_contact(tool, motion);
  ASSERT_TRUE(free.hit);
  EXPECT_NEAR(free.t, (0.03 - 0.004) / 0.06, 1e-4);  // the upper grid
  for (const double limit : {1.0, 0.9, free.t + 1e-9}) {
    const SweepHit h = sweep.first_contact(tool, motion, {}, {}, {}, limit);
    ASSERT_TRUE(h.hit) << limit;
    EXPECT_NEAR(h.t, free.t, 1e-9) << limit;  // the same contact (the search's start cache moves it by ~1e-12)
    EXPECT_EQ(h.slot, free.slot) << limit;
  }
  for (const double limit : {free.t * 0.99, 0.1, 0.0, -1.0})
    EXPECT_FALSE(sweep.first_contact(tool, motion, {}, {}, {}, limit).hit) << limit;
}

TEST(SweepQuery, AnEllipsoidalToolTouchesAPlateAtItsSupportHeight) {
  std::vector<GaussianSpec> gs;
  for (float x = -0.05f; x <= 0.05f; x += 0.002f)
    for (float y = -0.05f; y <= 0.05f; y += 0.002f)
      gs.emplace_back(Eigen::Vector3f(x, y, 0), Eigen::Vector3f(0.002f, 0.002f, 1e-7f), Eigen::Quaternionf::Identity());
  const CollisionWorld w = world_of(gs);
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 20; ++i) {
    ToolEllipsoid tool;
    tool.semi_axes = Eigen::Vector3d(0.01, 0.02, 0.005);
    tool.rotation = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    tool.center = Eigen::Vector3d(0.005 * u(rng), 0.005 * u(rng), 0.05);
    // The support height of the ellipsoid along z: sqrt(sum_i (R^T z)_i^2 a_i^2).
    const Eigen::Vector3d zl = tool.rotation.toRotationMatrix().transpose() * Eigen::Vector3d::UnitZ();
    const double support = std::sqrt(zl.cwiseProduct(tool.semi_axes).squaredNorm());
    SweepQuery sweep(w);
    const SweepHit hit = sweep.first_contact(tool, Eigen::Vector3d(0, 0, -0.1));
    ASSERT_TRUE(hit.hit) << i;
    const double z_hit = 0.05 - 0.1 * hit.t;
    EXPECT_GE(z_hit, support - 1e-9) << i;
    EXPECT_LE(z_hit, support + 1e-7 + 2e-7) << i;
  }
}

TEST(SweepQuery, GrazingPathsTouchOnlyWithinReach) {
  const float R = 0.01f;
  const CollisionWorld w = world_of({{Eigen::Vector3f::Zero(), Eigen::Vector3f::Constant(R), Eigen::Quaternionf::Identity()}});
  const double r = 0.005, reach = R + r;
  SweepQuery sweep(w);
  for (const double delta : {1e-4, 1e-5, 1e-6}) {
    const Eigen::Vector3d motion(0.2, 0, 0);
    const SweepHit miss = sweep.first_contact(ToolEllipsoid::sphere({-0.1, reach + delta, 0}, r), motion);
    EXPECT_FALSE(miss.hit) << delta;
    const double y = reach - delta;
    const SweepHit hit = sweep.first_contact(ToolEllipsoid::sphere({-0.1, y, 0}, r), motion);
    ASSERT_TRUE(hit.hit) << delta;
    const double x_hit = -std::sqrt(reach * reach - y * y);  // where |centre| = R + r
    EXPECT_NEAR(-0.1 + 0.2 * hit.t, x_hit, 2e-6) << delta;
    EXPECT_LE(-0.1 + 0.2 * hit.t, x_hit + 1e-8) << delta;  // never past the contact
  }
}

TEST(SweepQuery, TouchingAtTheStartBlocksOnlyMotionInward) {
  const float R = 0.01f;
  const CollisionWorld w = world_of({{Eigen::Vector3f::Zero(), Eigen::Vector3f::Constant(R), Eigen::Quaternionf::Identity()}});
  SweepQuery sweep(w);
  const ToolEllipsoid touching = ToolEllipsoid::sphere({0, 0, R + 0.005 - 1e-7}, 0.005);
  const SweepHit in = sweep.first_contact(touching, {0, 0, -0.001});
  ASSERT_TRUE(in.hit);
  EXPECT_EQ(in.t, 0.0);
  EXPECT_FALSE(sweep.first_contact(touching, {0, 0, 0.001}).hit);
  EXPECT_FALSE(sweep.first_contact(touching, Eigen::Vector3d::Zero()).hit);
  EXPECT_FALSE(sweep.first_contact(touching, {0, 0, NAN}).hit);
}

// A warm start (the Gaussian's maximiser at an earlier sweep, SweepQuery's start cache) changes
// the search's work, never its answer: random ellipsoidal parts a hair from flat and round
// Gaussians, moving along, toward and away from them, with starts anywhere on [-16, 16] against
// the search with none. (A stale start once had Newton's method settle where the start lies
// inside every member it reached and report a contact at t = 0 for a part moving off a Gaussian
// that only the reverse motion touches.)
TEST(SweepQuery, AWarmStartNeverChangesTheContact) {
  std::mt19937_64 rng(36);
  std::uniform_real_distribution<double> u(-1, 1), pos(0.1, 1);
  std::normal_distribution<double> n01;
  int hits = 0, misses = 0, touching = 0;
  for (int i = 0; i < 4000; ++i) {
    CollisionGaussian g{};
    const Eigen::Vector3d ga(0.004 * pos(rng), 0.004 * pos(rng), i % 2 ? 0.0002 * pos(rng) : 0.004 * pos(rng));
    const Eigen::Quaterniond gq = Eigen::Quaterniond(n01(rng), n01(rng), n01(rng), n01(rng)).normalized();
    for (int k = 0; k < 3; ++k) g.semi_axes[k] = float(ga[k]);
    g.quaternion[0] = float(gq.w()), g.quaternion[1] = float(gq.x()), g.quaternion[2] = float(gq.y()),
    g.quaternion[3] = float(gq.z());
    g.radius = float(ga.maxCoeff());
    ToolEllipsoid t;
    t.semi_axes = Eigen::Vector3d(0.01 * pos(rng), 0.003 * pos(rng), 0.003 * pos(rng));
    t.rotation = Eigen::Quaterniond(n01(rng), n01(rng), n01(rng), n01(rng)).normalized();
    // Placed a hair (up to 0.2 mm) off the Gaussian along a random direction: the tool's support
    // point there meets the Gaussian's.
    const Eigen::Vector3d dir = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized();
    const Eigen::Matrix3d Rg = gq.toRotationMatrix();
    const Eigen::Vector3d g_support = Rg * (ga.cwiseAbs2().asDiagonal() * (Rg.transpose() * dir)) /
                                      (ga.asDiagonal() * (Rg.transpose() * dir)).norm();
    t.center = g_support - (t.surface_point(-dir) - t.center) + dir * 0.0002 * (u(rng) + 1) / 2;
    const Eigen::Vector3d motion = (dir * u(rng) + Eigen::Vector3d(u(rng), u(rng), u(rng))).normalized() * 0.0005;
    for (int k = 0; k < 3; ++k) g.center[k] = 0.0;
    // (A value past 1, the motion's end, only says "not within the motion".)
    const double plain = sweep_time(g, t, motion);
    for (int k = 0; k < 4; ++k) {
      double s = 16 * u(rng);
      const double warm = sweep_time(g, t, motion, nullptr, 1.0, &s);
      ASSERT_EQ(plain <= 1, warm <= 1) << "pair " << i << " start " << k << ": " << plain << " vs " << warm;
      if (plain <= 1) {
        EXPECT_NEAR(warm, plain, 1e-9) << "pair " << i << " start " << k;
      }
    }
    (plain <= 1 ? (plain == 0 ? touching : hits) : misses) += 1;
  }
  EXPECT_GT(hits, 200);
  EXPECT_GT(misses, 200);
}

TEST(SweepQuery, IgnoredRecordsAndHintsChangeOnlyWhatTheyShould) {
  // Two layers: ignoring the upper layer's first blocker still stops on the upper layer (its
  // neighbours), ignoring the whole upper layer stops on the lower one; hints never change a hit
  // (beyond the search's tolerance: each exact search starts at the Gaussian's last maximiser).
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.01f, 0.004f, 0.02f);
  const std::size_t upper = gs.size();
  add_layer(gs, 0.0f, 0.004f, 0.02f);
  const CollisionWorld w = world_of(gs);
  SweepQuery sweep(w);
  const ToolEllipsoid tool = ToolEllipsoid::sphere({0.0013, 0.0009, 0.03}, 0.003);
  const Eigen::Vector3d motion(0, 0, -0.04);
  const SweepHit first = sweep.first_contact(tool, motion);
  ASSERT_TRUE(first.hit);
  std::vector<std::uint32_t> all_upper;
  for (std::uint32_t s = 0; s < w.gaussians().size(); ++s)
    if (w.gaussians()[s].center[2] > 0.005f) all_upper.push_back(s);
  ASSERT_EQ(all_upper.size(), upper);
  const SweepHit lower = sweep.first_contact(tool, motion, all_upper);
  ASSERT_TRUE(lower.hit);
  EXPECT_LT(w.gaussians()[lower.slot].center[2], 0.005f);
  EXPECT_GT(lower.t, first.t + 0.2);
  std::mt19937_64 rng(2);
  std::uniform_int_distribution<std::uint32_t> pick(0, std::uint32_t(w.gaussians().size() - 1));
  for (int i = 0; i < 50; ++i) {
    const std::uint32_t hints[3] = {pick(rng), pick(rng), first.slot};
    const SweepHit h = sweep.first_contact(tool, motion, {}, {hints, std::size_t(i % 4)});
    ASSERT_TRUE(h.hit);
    EXPECT_NEAR(h.t, first.t, 1e-12) << i;  // (each search starts at the Gaussian's last maximiser)
  }
}

TEST(SweepQuery, AHintThatHoldsTheToolBoundsTheTraversalAndIsSearchedOnlyWhereItCanBlock) {
  // A tool resting on a layer and pressed deep into it (ten radii down and seven aside, as the proxy's
  // first sweep toward a device far inside): with the resting contact as a hint, the hint's
  // exact search sets the bar at ~0 and only the box swept up to it is traversed, so far fewer
  // candidates are read, for the same contact.
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.002f, 0.05f);
  const CollisionWorld w = world_of(gs);
  SweepQuery sweep(w);
  const double r = 0.004;
  const ToolEllipsoid free_tool = ToolEllipsoid::sphere({0.0007, -0.0003, 0.02}, r);
  const SweepHit rest = sweep.first_contact(free_tool, {0, 0, -0.04});
  ASSERT_TRUE(rest.hit);
  const ToolEllipsoid resting = ToolEllipsoid::sphere(free_tool.center + Eigen::Vector3d(0, 0, -0.04 * rest.t + 1e-7), r);
  const Eigen::Vector3d press(6 * r, 4 * r, -10 * r);
  const SweepHit cold = sweep.first_contact(resting, press);
  const std::uint32_t cold_candidates = sweep.counts().candidates;
  ASSERT_TRUE(cold.hit);
  EXPECT_LT(cold.t, 1e-3);
  const SweepHit hinted = sweep.first_contact(resting, press, {}, {&rest.slot, 1});
  const std::uint32_t hinted_candidates = sweep.counts().candidates, hinted_exact = sweep.counts().exact;
  ASSERT_TRUE(hinted.hit);
  EXPECT_NEAR(hinted.t, cold.t, 1e-12);
  EXPECT_LT(3 * hinted_candidates, cold_candidates) << hinted_candidates << " vs " << cold_candidates;
  // A compound tool: the hint (the lower part's blocker) is searched only against the parts its
  // bounds do not rule out: the upper part, twenty radii up, is not searched (the same searches
  // as the lower part alone).
  const ToolEllipsoid parts[2] = {resting, ToolEllipsoid::sphere(resting.center + Eigen::Vector3d(0, 0, 20 * r), r)};
  const SweepHit both = sweep.first_contact(parts, press, {}, {&rest.slot, 1});
  ASSERT_TRUE(both.hit);
  EXPECT_EQ(both.part, 0);
  EXPECT_NEAR(both.t, cold.t, 1e-12);
  EXPECT_EQ(sweep.counts().exact, hinted_exact) << "the upper part was searched against the hint";
}

TEST(SweepQuery, APartSettledByItsHintReadsNoCandidates) {
  // A hint whose contact lies within the tolerance of the start takes the part's bar below 0.
  // Every contact time and every lower bound is >= 0, so no other Gaussian can come first: the
  // sweep answers with the hint and reads none of that part's candidates. Another part, which
  // no hint settles, still reads its own and finds its own first contact.
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.002f, 0.05f);
  const CollisionWorld w = world_of(gs);
  SweepQuery sweep(w);
  const double r = 0.004, tol = 0.01;
  const ToolEllipsoid free_tool = ToolEllipsoid::sphere({0.0007, -0.0003, 0.02}, r);
  const SweepHit rest = sweep.first_contact(free_tool, {0, 0, -0.04});
  ASSERT_TRUE(rest.hit);
  const ToolEllipsoid resting = ToolEllipsoid::sphere(free_tool.center + Eigen::Vector3d(0, 0, -0.04 * rest.t + 1e-7), r);
  const Eigen::Vector3d press(r, 0.5 * r, -2 * r);
  const SweepHit cold = sweep.first_contact(resting, press);
  ASSERT_TRUE(cold.hit);
  ASSERT_LT(cold.t, 0.1 * tol);
  const SweepHit settled = sweep.first_contact(resting, press, {}, {&rest.slot, 1}, {}, 1.0, tol);
  ASSERT_TRUE(settled.hit);
  EXPECT_EQ(settled.slot, rest.slot);
  EXPECT_LE(settled.t, cold.t + tol);
  EXPECT_EQ(sweep.counts().candidates, 0u);
  // Without the tolerance the bar stays >= 0 and the same sweep reads the layer round the tool.
  (void)sweep.first_contact(resting, press, {}, {&rest.slot, 1});
  EXPECT_GT(sweep.counts().candidates, 0u);
  // Two parts, each its own first contact: the second, 2 cm along and half a radius above the
  // layer with no hint, is not settled by the first's.
  const ToolEllipsoid other = ToolEllipsoid::sphere(resting.center + Eigen::Vector3d(0.02, 0, 0.5 * r), r);
  const ToolEllipsoid parts[2] = {resting, other};
  SweepHit hits[2];
  sweep.first_contacts(parts, press, hits, {&rest.slot, 1}, {}, tol);
  const std::uint32_t both_candidates = sweep.counts().candidates;
  const SweepHit alone = sweep.first_contact(other, press, {}, {}, {}, 1.0, tol);
  ASSERT_TRUE(alone.hit);
  EXPECT_EQ(sweep.counts().candidates, both_candidates) << "the settled part read candidates";
  ASSERT_TRUE(hits[0].hit);
  EXPECT_EQ(hits[0].slot, rest.slot);
  ASSERT_TRUE(hits[1].hit);
  EXPECT_NEAR(hits[1].t, alone.t, tol);
}

// The first-contact time of an ellipsoidal tool against one Gaussian, computed plainly in the
// world frame: the largest entry time over the family E_lambda (lambda on a fine grid of
// s = logit(lambda), then golden-section refinement), with M = (lambda Sigma_g + (1 - lambda)
// Sigma_t)^-1 inverted directly (never, when the line misses one member); the normal is
// -M (d - t u) at the maximiser.
double plain_sweep_time(const CollisionGaussian& g, const ToolEllipsoid& tool, const Eigen::Vector3d& u,
                        Eigen::Vector3d* normal) {
  const Eigen::Matrix3d Rg = rotation_matrix(g);
  const Eigen::Vector3d a(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
  const Eigen::Matrix3d Sg = Rg * a.cwiseAbs2().asDiagonal() * Rg.transpose();
  const Eigen::Matrix3d Rt = tool.rotation.toRotationMatrix();
  const Eigen::Matrix3d St = Rt * tool.semi_axes.cwiseAbs2().asDiagonal() * Rt.transpose();
  const Eigen::Vector3d d = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]) - tool.center;
  const auto entry = [&](double s, Eigen::Vector3d* md, double t) {
    const double lam = 1.0 / (1.0 + std::exp(-s));
    const Eigen::Matrix3d M = (lam * Sg + (1 - lam) * St).inverse();
    const double qa = u.dot(M * u), qb = -2 * u.dot(M * d), qc = d.dot(M * d) - 1.0 / (lam * (1 - lam));
    if (md != nullptr) *md = M * (d - t * u);
    const double disc = qb * qb - 4 * qa * qc;
    if (disc < 0) return 1e300;  // the line misses E_lambda: the two never touch
    const double t1 = (-qb - std::sqrt(disc)) / (2 * qa), t2 = (-qb + std::sqrt(disc)) / (2 * qa);
    return t2 < 0 ? 1e300 : t1;
  };
  double best_s = 0, best_t = -1e300;
  for (int i = 0; i <= 6400; ++i) {
    const double s = -16 + 32.0 * i / 6400;
    const double t = entry(s, nullptr, 0);
    if (t > best_t) best_t = t, best_s = s;
  }
  if (best_t > 1e299) return std::numeric_limits<double>::infinity();
  double lo = best_s - 0.01, hi = best_s + 0.01;
  for (int it = 0; it < 100; ++it) {
    const double m1 = lo + 0.382 * (hi - lo), m2 = hi - 0.382 * (hi - lo);
    (entry(m1, nullptr, 0) < entry(m2, nullptr, 0) ? lo : hi) = (entry(m1, nullptr, 0) < entry(m2, nullptr, 0) ? m1 : m2);
  }
  best_s = 0.5 * (lo + hi);
  best_t = entry(best_s, nullptr, 0);
  Eigen::Vector3d md;
  (void)entry(best_s, &md, best_t);
  *normal = -md.normalized();
  return best_t;
}

TEST(SweepQuery, AnEllipsoidalToolsSearchMatchesThePlainWorldFrameComputation) {
  // The search diagonalises both shapes at once (the tool whitened to the unit sphere); the
  // plain computation inverts the family's matrix in the world frame. Random Gaussians (flat
  // ones too) and turned ellipsoidal tools (up to 5:1), on paths that touch.
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(-1, 1), lg(-2.5, -1.2), ax(0.2, 1.0);
  int touched = 0;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Quaternionf q = Eigen::Quaternionf(float(u(rng)), float(u(rng)), float(u(rng)), float(u(rng))).normalized();
    Eigen::Vector3f a(float(std::pow(10, lg(rng))), float(std::pow(10, lg(rng))), float(std::pow(10, lg(rng))));
    if (i % 4 == 0) a.z() = 1e-5f;  // flat splats
    const CollisionWorld w = world_of({{Eigen::Vector3f::Zero(), a, q}});
    ToolEllipsoid tool;
    tool.semi_axes = 0.01 * Eigen::Vector3d(1.0, ax(rng), ax(rng));
    tool.rotation = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    const Eigen::Vector3d dir = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    tool.center = -dir * 0.12 + Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.01;
    const Eigen::Vector3d motion = dir * 0.2;
    Eigen::Vector3d n, n_ref;
    const double t = sweep_time(w.gaussians()[0], tool, motion, &n);
    const double t_ref = plain_sweep_time(w.gaussians()[0], tool, motion, &n_ref);
    if (!(t_ref > 0 && t_ref <= 1)) continue;
    ++touched;
    EXPECT_NEAR(t, t_ref, 1e-9) << i;  // 0.2 nm of a 20 cm motion
    EXPECT_GT(n.dot(n_ref), std::cos(1e-4)) << i;
  }
  EXPECT_GT(touched, 60);
}

// The earliest contact of `part` moved by `motion` over every Gaussian's own exact search: the
// brute-force reference of the candidate-bound tests below.
void expect_brute_force_first_contact(const CollisionWorld& w, const ToolEllipsoid& part, const Eigen::Vector3d& motion,
                                      const SweepHit& hit) {
  double t_ref = 2;
  std::uint32_t slot_ref = 0;
  for (std::uint32_t k = 0; k < w.size(); ++k) {
    const double t = sweep_time(w.gaussians()[k], part, motion);
    if (t < t_ref) t_ref = t, slot_ref = k;
  }
  EXPECT_NEAR(hit.t, t_ref, 1e-12);
  EXPECT_EQ(hit.slot, slot_ref);
}

TEST(SweepQuery, AnEllipsoidalPartsCandidatesAreBoundedByTheFamilyMembers) {
  // A long part (a stylus's segment, 30 x 4 x 4 mm, lying 20 degrees off the layer) over a dense
  // layer of discs, moved down and aside: its box and capsule hold many discs, most of which it
  // cannot reach before the first contact. The family members' bound (the one spheres get,
  // here through the family's matrix in the world frame) spares them the exact search, and the
  // contact is the earliest of every Gaussian's own exact search.
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.002f, 0.05f);
  const CollisionWorld w = world_of(gs);
  SweepQuery sweep(w);
  ToolEllipsoid part;
  part.semi_axes = {0.03, 0.004, 0.004};
  part.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitY())) *
                  Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()));
  for (const Eigen::Vector3d& motion : {Eigen::Vector3d(0.004, 0.002, -0.03), Eigen::Vector3d(-0.01, 0.006, -0.02)}) {
    part.center = {0.0013, -0.0007, 0.018};
    const SweepHit hit = sweep.first_contact(part, motion);
    ASSERT_TRUE(hit.hit);
    const std::uint32_t exact = sweep.counts().exact, candidates = sweep.counts().candidates;
    expect_brute_force_first_contact(w, part, motion, hit);
    EXPECT_LT(10 * exact, candidates) << exact << " exact searches of " << candidates << " candidates";
  }
}

// How many Gaussians have their centre in the box `part` sweeps along `motion` (what a traversal
// of that box reads, leaves' spill aside).
std::uint32_t centres_in_swept_box(const CollisionWorld& w, const ToolEllipsoid& part, const Eigen::Vector3d& motion) {
  const Eigen::Vector3d h = part.aabb_half_extent();
  const Eigen::Vector3d lo = part.center.cwiseMin(part.center + motion) - h;
  const Eigen::Vector3d hi = part.center.cwiseMax(part.center + motion) + h;
  std::uint32_t n = 0;
  for (const CollisionGaussian& g : w.gaussians()) {
    const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
    n += (c.array() >= lo.array()).all() && (c.array() <= hi.array()).all() ? 1 : 0;
  }
  return n;
}

TEST(SweepQuery, AnElongatedPartsCandidatesAreTheGaussiansWithinReachOfItsAxis) {
  // A stylus segment (40 x 4 x 4 mm) lying on a dense layer, moved down and a little aside: its
  // bounding sphere's capsule holds every disc within 40 mm of its centre, but only those whose
  // centre comes within their bounding radius + 4 mm of the segment's axis can touch it. Those
  // (found here by sampling the path) are all the bounds may pass; the contact is the earliest
  // of every Gaussian's own exact search.
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.002f, 0.06f);
  const CollisionWorld w = world_of(gs);
  SweepQuery sweep(w);
  ToolEllipsoid part;
  part.semi_axes = {0.04, 0.004, 0.004};
  part.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY())) *
                  Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()));
  const Eigen::Vector3d axis = part.rotation * Eigen::Vector3d::UnitX();
  for (const Eigen::Vector3d& motion : {Eigen::Vector3d(0.001, -0.002, -0.01), Eigen::Vector3d(0.0, 0.0, -0.012)}) {
    part.center = {0.0011, -0.0006, 0.0062};
    const SweepHit hit = sweep.first_contact(part, motion);
    ASSERT_TRUE(hit.hit);
    expect_brute_force_first_contact(w, part, motion, hit);
    std::uint32_t within = 0, beside = 0;
    for (std::uint32_t k = 0; k < w.size(); ++k) {
      const CollisionGaussian& g = w.gaussians()[k];
      const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
      double nearest = 1e9;  // the centre's nearest distance to the moving axis's line
      for (int i = 0; i <= 2000; ++i) {
        const Eigen::Vector3d rel = c - part.center - motion * (i / 2000.0);
        nearest = std::min(nearest, (rel - rel.dot(axis) * axis).norm());
      }
      const double reach = g.bounding_radius() + 0.004;
      if (nearest <= reach + 1e-5 && (c - part.center).norm() <= g.bounding_radius() + 0.04 + motion.norm()) ++within;
      if (nearest > reach + 1e-5 && (c - part.center).norm() <= g.bounding_radius() + 0.04) ++beside;
    }
    ASSERT_GT(beside, within) << "the set-up puts most discs in the bounding sphere beside the axis";
    // The leaves read are those whose bounding sphere comes within reach of the axis (about half
    // of the swept box's discs here; every leaf overlapping the box holds more than the box).
    const std::uint32_t in_box = centres_in_swept_box(w, part, motion);
    EXPECT_LT(3 * sweep.counts().candidates, 2 * in_box) << sweep.counts().candidates << " read of " << in_box;
    EXPECT_LE(sweep.counts().prefiltered, within)
        << sweep.counts().prefiltered << " candidates past the bounds of " << sweep.counts().candidates;
  }
}

// A layer of thin discs on a grid `step` apart over [-half, half]^2, with heights jittered by up to
// `height` and tilts by up to `tilt` radians about a random horizontal axis.
std::vector<GaussianSpec> bumpy_layer(std::mt19937& rng, float half, float step, float height, float tilt,
                                      const Eigen::Vector3f& axes) {
  std::uniform_real_distribution<float> jitter(-1.0f, 1.0f);
  std::vector<GaussianSpec> gs;
  for (float x = -half; x <= half; x += step)
    for (float y = -half; y <= half; y += step) {
      const Eigen::Quaternionf q(Eigen::AngleAxisf(tilt * jitter(rng), Eigen::Vector3f(jitter(rng), jitter(rng), 0).normalized()));
      gs.emplace_back(Eigen::Vector3f(x, y, height * jitter(rng)), axes, q);
    }
  return gs;
}

// Rests `part` on the layer below it (swept down by `drop` from where it is, stopped 1 um short of
// the contact), slides it by `motion`, and checks the slide's contact against every Gaussian's own
// exact search; whether the slide met one.
bool slide_meets_the_first_contact(const CollisionWorld& w, SweepQuery& sweep, ToolEllipsoid& part, double drop,
                                   const Eigen::Vector3d& motion) {
  const SweepHit rest = sweep.first_contact(part, Eigen::Vector3d(0, 0, -drop));
  EXPECT_TRUE(rest.hit);
  part.center.z() -= drop * rest.t - 1e-6;
  const SweepHit hit = sweep.first_contact(part, motion);
  double t_ref = INFINITY;
  for (const CollisionGaussian& g : w.gaussians()) t_ref = std::min(t_ref, sweep_time(g, part, motion));
  EXPECT_EQ(hit.hit, t_ref <= 1.0) << "brute force: t = " << t_ref;
  if (hit.hit) expect_brute_force_first_contact(w, part, motion, hit);
  return hit.hit;
}

TEST(SweepQuery, AnElongatedPartSlidingOnABumpyLayerMeetsTheFirstContact) {
  // A stylus segment (40 x 4 x 4 mm) resting on a layer of thin discs with jittered heights
  // and tilts, sliding along it in every direction (a little down, or a little up): the
  // Gaussians beside its axis are ruled out by their support toward the axis and the motion
  // across it (Capsule's bound); each contact is still the earliest of every Gaussian's own
  // exact search.
  std::mt19937 rng(38);
  std::uniform_real_distribution<float> jitter(-1.0f, 1.0f);
  const CollisionWorld w = world_of(bumpy_layer(rng, 0.04f, 0.002f, 0.0005f, 0.3f, {0.002f, 0.0015f, 0.0002f}));
  SweepQuery sweep(w);
  ToolEllipsoid part;
  part.semi_axes = {0.02, 0.004, 0.004};
  int hits = 0;
  for (int i = 0; i < 48; ++i) {
    part.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.05 * jitter(rng), Eigen::Vector3d::UnitY())) *
                    Eigen::Quaterniond(Eigen::AngleAxisd(3.2 * jitter(rng), Eigen::Vector3d::UnitZ()));
    part.center = {0.005 * jitter(rng), 0.005 * jitter(rng), 0.0};
    // Rest it on the layer: lift it out, then sweep it down to its first contact. Then slide it
    // 0.1 to 5 mm (a short slide leaves little margin to the motion's part of the bound).
    part.center.z() = 0.02;
    const double heading = 3.2 * jitter(rng), slope = 0.3 * jitter(rng), len = 0.0001 * std::pow(50.0, 0.5 * (1 + jitter(rng)));
    const Eigen::Vector3d motion =
        len * Eigen::Vector3d(std::cos(heading), std::sin(heading), slope).normalized();
    SCOPED_TRACE(i);
    hits += slide_meets_the_first_contact(w, sweep, part, 0.03, motion) ? 1 : 0;
  }
  EXPECT_GE(hits, 8) << "many slides meet a bump";
}

TEST(SweepQuery, AnUprightTipAndARestingSphereSlideOnADenseLayerToTheFirstContact) {
  // A dense layer of thin discs (1 mm apart, jittered heights and tilts) under two tools that
  // rest on it and slide 0.05-2 mm: a stylus's part standing on its tip (5 x 5 x 20 mm, tilted
  // up to 15 degrees; the capsule round its axis and its box hold every disc within about 5 mm
  // of the tip, the separating axis along the centres keeps the few under it) and a 5 mm sphere
  // (its swept box's floor holds a hundred discs; the leaves beyond its radius from its path are
  // not read). Each contact is the earliest of every Gaussian's own exact search, and the sphere
  // reads under half the Gaussians that reach into its swept box.
  std::mt19937 rng(71);
  std::uniform_real_distribution<float> jitter(-1.0f, 1.0f);
  const CollisionWorld w = world_of(bumpy_layer(rng, 0.03f, 0.001f, 0.0002f, 0.2f, {0.0008f, 0.0006f, 0.0001f}));
  SweepQuery sweep(w);
  for (const bool upright : {true, false}) {
    ToolEllipsoid part = upright ? ToolEllipsoid{} : ToolEllipsoid::sphere(Eigen::Vector3d::Zero(), 0.005);
    if (upright) part.semi_axes = {0.005, 0.005, 0.02};
    int hits = 0;
    std::uint64_t read = 0, in_box = 0;
    for (int i = 0; i < 40; ++i) {
      if (upright)
        part.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(
            0.26 * jitter(rng), Eigen::Vector3d(jitter(rng), jitter(rng), 0).normalized()));
      part.center = {0.01 * jitter(rng), 0.01 * jitter(rng), 0.03};
      const double heading = 3.2 * jitter(rng), slope = 0.2 * jitter(rng),
                   len = 0.00005 * std::pow(40.0, 0.5 * (1 + jitter(rng)));
      const Eigen::Vector3d motion = len * Eigen::Vector3d(std::cos(heading), std::sin(heading), slope).normalized();
      SCOPED_TRACE(::testing::Message() << (upright ? "upright part " : "sphere ") << i);
      hits += slide_meets_the_first_contact(w, sweep, part, 0.05, motion) ? 1 : 0;
      read += sweep.counts().candidates;  // (the slide's)
      // The Gaussians whose bounding box overlaps the slide's swept box: what a box traversal reads at least.
      const Eigen::Vector3d h = part.aabb_half_extent();
      const Eigen::Vector3d lo = part.center.cwiseMin(part.center + motion) - h;
      const Eigen::Vector3d hi = part.center.cwiseMax(part.center + motion) + h;
      for (const CollisionGaussian& g : w.gaussians()) {
        const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
        const double gr = g.bounding_radius();
        in_box += ((c.array() + gr) >= lo.array()).all() && ((c.array() - gr) <= hi.array()).all() ? 1 : 0;
      }
    }
    EXPECT_GE(hits, 8) << "many slides meet a bump";
    if (!upright) {
      EXPECT_LT(2 * read, in_box) << read << " Gaussians read of " << in_box << " reaching into the swept boxes";
    }
  }
}

TEST(SweepQuery, AGaussianTheFilterKnowsToPassIsNotSearched) {
  // A tool resting in a lone Gaussian above a layer, moved down onto the layer: the filter lets
  // the lone one pass. Asked only after its search, it costs a search at every sweep; known
  // beforehand (a cached answer), it is left out: the same contact, one search fewer.
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.04f);
  gs.emplace_back(Eigen::Vector3f(0.0f, 0.0f, 0.012f), Eigen::Vector3f(0.002f, 0.002f, 0.002f), Eigen::Quaternionf::Identity());
  const CollisionWorld w = world_of(gs);
  std::uint32_t lone = 0;
  for (std::uint32_t k = 0; k < w.size(); ++k)
    if (w.gaussians()[k].center[2] > 0.01) lone = k;
  struct Lone {
    std::uint32_t slot;
    static bool blocks(void* c, std::uint32_t k) noexcept { return k != static_cast<Lone*>(c)->slot; }
    static bool known(void* c, std::uint32_t k) noexcept { return k == static_cast<Lone*>(c)->slot; }
  } ctx{lone};
  const ToolEllipsoid tool = ToolEllipsoid::sphere({0.001, 0.0, 0.013}, 0.005);  // overlaps the lone Gaussian
  const Eigen::Vector3d motion(0, 0, -0.02);
  SweepQuery sweep(w);
  BlockFilter asked{&Lone::blocks, &ctx};
  const SweepHit a = sweep.first_contact(tool, motion, {}, {}, asked);
  const SweepCounts ca = sweep.counts();
  BlockFilter known = asked;
  known.known_to_pass = &Lone::known;
  const SweepHit b = sweep.first_contact(tool, motion, {}, {}, known);
  const SweepCounts cb = sweep.counts();
  ASSERT_TRUE(a.hit);
  ASSERT_TRUE(b.hit);
  EXPECT_NE(a.slot, lone);
  EXPECT_EQ(a.slot, b.slot);
  EXPECT_NEAR(a.t, b.t, 1e-12);
  EXPECT_EQ(ca.passed, 1u);
  EXPECT_EQ(cb.passed, 0u);
  EXPECT_EQ(cb.exact + 1, ca.exact);
}

TEST(SweepQuery, AFlatPartsCandidatesAreTheGaussiansThatReachItsPlane) {
  // A disc (20 x 20 x 2 mm) tilted 30 degrees, then 3 degrees, over a dense layer and moved
  // down: its bounding sphere and its slab along the motion hold the disc's whole footprint, but
  // a Gaussian touches it only while its centre is within 2 mm + its own reach along the disc's
  // axis of the disc's mid-plane (the slab bound; nearly face-on, the contact is at that
  // distance). Those (found here by sampling the path) are all the bounds may pass; the contact
  // is the earliest of every Gaussian's own exact search, rim first or face first.
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.002f, 0.04f);
  const CollisionWorld w = world_of(gs);
  SweepQuery sweep(w);
  ToolEllipsoid part;
  part.semi_axes = {0.02, 0.02, 0.002};
  for (const double tilt : {0.52, 0.05})
  for (const Eigen::Vector3d& motion : {Eigen::Vector3d(0.0005, -0.001, -0.003), Eigen::Vector3d(0.0, 0.0, -0.004)}) {
    part.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(tilt, Eigen::Vector3d(0.3, 1, 0).normalized()));
    const Eigen::Vector3d axis = part.rotation * Eigen::Vector3d::UnitZ();
    part.center = {0.0007, -0.0011, tilt > 0.1 ? 0.0125 : 0.0039};
    SCOPED_TRACE(tilt);
    const SweepHit hit = sweep.first_contact(part, motion);
    ASSERT_TRUE(hit.hit);
    expect_brute_force_first_contact(w, part, motion, hit);
    std::uint32_t within = 0, beside = 0;
    for (std::uint32_t k = 0; k < w.size(); ++k) {
      const CollisionGaussian& g = w.gaussians()[k];
      const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
      const Eigen::Matrix3d R = rotation_matrix(g);
      const Eigen::Vector3d a(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
      const double reach = 0.002 + a.cwiseProduct(R.transpose() * axis).norm();
      double nearest = 1e9;  // the centre's nearest distance to the moving mid-plane
      for (int i = 0; i <= 2000; ++i) nearest = std::min(nearest, std::fabs(axis.dot(c - part.center - motion * (i / 2000.0))));
      const double from_centre = (c - part.center).norm();
      if (nearest <= reach + 1e-5 && from_centre <= g.bounding_radius() + 0.02 + motion.norm()) ++within;
      if (nearest > reach + 1e-5 && from_centre <= g.bounding_radius() + 0.02) ++beside;
    }
    if (tilt > 0.1) {
      ASSERT_GT(beside, within) << "the set-up puts most discs in the bounding sphere off the disc's plane";
      // The leaves read are those whose bounding sphere reaches the disc's slab: fewer than the
      // swept box holds (every leaf overlapping the box, more).
      const std::uint32_t in_box = centres_in_swept_box(w, part, motion);
      EXPECT_LT(sweep.counts().candidates, in_box) << sweep.counts().candidates << " read of " << in_box;
    }
    EXPECT_LE(sweep.counts().prefiltered, within)
        << sweep.counts().prefiltered << " candidates past the bounds of " << sweep.counts().candidates;
  }
}

}  // namespace
}  // namespace gshaptics
