// The proxy renderer's four parts on their own: the god-object's constrained goal against an
// independent projection (Dykstra's algorithm), the solver on a plane, an edge and a corner, the
// shaded normal on a plane and a sphere of Gaussians, the friction cone's stick/slide decision,
// and the virtual coupling's force law.

#include <gtest/gtest.h>

#include <array>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "gshaptics/fidelity/interaction.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/force/compound_proxy.h"
#include "gshaptics/force/friction_cone.h"
#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/force/proxy_solver.h"
#include "gshaptics/force/shaded_normal.h"
#include "gshaptics/force/virtual_coupling.h"
#include "gshaptics/percentile.h"
#include "support/allocation_counter.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/scene/registration.h"
#include "support/ellipsoid_params.h"
#include "support/gaussian_worlds.h"
#include "support/scenes.h"
#include "support/shading_reference.h"

namespace gshaptics {
namespace {

using test::add_layer;
using test::GaussianSpec;
using test::world_of;

// The ground-truth Gaussians of `shape` at `spacing` (m), as the fidelity run draws them.
CollisionWorld synthetic_world(const AnalyticShape& shape, double spacing, std::uint64_t seed) {
  SynthParams sp;
  sp.spacing = spacing;
  sp.seed = seed;
  return CollisionWorld::build(make_synthetic_scene(shape, sp).scene, WorldConfig{});
}

// The ground-truth Gaussians of `shape` at `spacing` (m), without floaters.
CollisionWorld shell_without_floaters(const AnalyticShape& shape, double spacing, std::uint64_t seed = 1) {
  SynthParams sp;
  sp.spacing = spacing;
  sp.seed = seed;
  sp.floater_share = 0;
  return CollisionWorld::build(make_synthetic_scene(shape, sp).scene, WorldConfig{});
}

// Where a tool of radius r rests at each of `count` press sites of `shape` (seed `seed`): its
// centre moved out along the site's normal until it overlaps no Gaussian of `w`.
std::vector<Eigen::Vector3d> resting_centres(const CollisionWorld& w, const AnalyticShape& shape, double r, int count,
                                             std::uint64_t seed) {
  ContactQuery query(w);
  std::vector<Eigen::Vector3d> centres;
  for (const ContactSite& site : shape.press_sites(count, seed, 0.03)) {
    Eigen::Vector3d p = site.point + r * site.normal;
    while (query.any_contact(ToolEllipsoid::sphere(p, r))) p += 2e-4 * site.normal;
    centres.push_back(p);
  }
  return centres;
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180 / M_PI;
}

// The projection of `x` onto the intersection of half-spaces by Dykstra's alternating projections
// (Boyle & Dykstra 1986): slow, independent of the subset enumeration it checks.
Eigen::Vector3d dykstra(const Eigen::Vector3d& x, const std::vector<ConstraintPlane>& planes) {
  const std::size_t n = planes.size();
  std::vector<Eigen::Vector3d> inc(n, Eigen::Vector3d::Zero());
  Eigen::Vector3d y = x;
  for (int it = 0; it < 200000; ++it)
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d z = y + inc[i];
      const double s = planes[i].normal.dot(z - planes[i].point);
      const Eigen::Vector3d proj = s < 0 ? Eigen::Vector3d(z - s * planes[i].normal) : z;
      inc[i] = z - proj;
      y = proj;
    }
  return y;
}

TEST(ClosestFeasiblePoint, MatchesDykstrasProjectionOnOneTwoAndThreePlanes) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-1, 1);
  int projected = 0;
  for (int i = 0; i < 60; ++i) {
    const int n = 1 + i % 3;
    std::vector<ConstraintPlane> planes(n);
    for (auto& p : planes) {
      // Normals in the upper half-space through points near the origin: a non-empty
      // intersection (it contains everything far enough up), as the proxy's blockers give.
      p.normal = Eigen::Vector3d(u(rng), u(rng), 0.3 + std::fabs(u(rng))).normalized();
      p.point = 0.01 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    }
    const Eigen::Vector3d goal = 0.02 * Eigen::Vector3d(u(rng), u(rng), u(rng)) - Eigen::Vector3d(0, 0, 0.01);
    const Eigen::Vector3d x = closest_feasible_point(goal, planes);
    const Eigen::Vector3d ref = dykstra(goal, planes);
    EXPECT_LT((x - ref).norm(), 1e-7) << i << " n " << n;
    for (const auto& p : planes) EXPECT_GE(p.normal.dot(x - p.point), -1e-12) << i;
    if ((x - goal).norm() > 1e-9) ++projected;
  }
  EXPECT_GT(projected, 30);
  // Two and three planes on the servo tick: no allocation.
  const std::vector<ConstraintPlane> corner = {{Eigen::Vector3d::UnitX(), Eigen::Vector3d::Zero()},
                                               {Eigen::Vector3d::UnitY(), Eigen::Vector3d::Zero()},
                                               {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::Zero()}};
  const std::size_t before = test::allocation_count();
  const Eigen::Vector3d c3 = closest_feasible_point({-1, -2, -3}, corner);
  const Eigen::Vector3d c2 = closest_feasible_point({-1, -2, 3}, std::span(corner).first(2));
  EXPECT_EQ(test::allocation_count() - before, 0u);
  EXPECT_EQ(c3, Eigen::Vector3d::Zero());
  EXPECT_EQ(c2, Eigen::Vector3d(0, 0, 3));
  // A feasible goal is its own answer; no planes, no constraint.
  EXPECT_EQ(closest_feasible_point({0, 0, 1}, std::vector<ConstraintPlane>{{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::Zero()}}),
            Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(closest_feasible_point({0, 0, -1}, {}), Eigen::Vector3d(0, 0, -1));
}

// The inside of a box corner at the origin, made of flat discs (2 um half-thickness): the
// floor z = 0 and the walls x = 0 and y = 0; free space is x, y, z > 0.
std::vector<GaussianSpec> inside_corner(float h, float extent) {
  std::vector<GaussianSpec> gs;
  const Eigen::Vector3f flat(h, h, 0.001f * h);
  const Eigen::Quaternionf to_x(Eigen::AngleAxisf(float(M_PI / 2), Eigen::Vector3f::UnitY()));
  const Eigen::Quaternionf to_y(Eigen::AngleAxisf(float(M_PI / 2), Eigen::Vector3f::UnitX()));
  for (float a = 0; a <= extent; a += h)
    for (float b = 0; b <= extent; b += h) {
      gs.emplace_back(Eigen::Vector3f(a, b, 0), flat, Eigen::Quaternionf::Identity());  // floor
      gs.emplace_back(Eigen::Vector3f(0, a, b), flat, to_x);                            // wall x = 0
      gs.emplace_back(Eigen::Vector3f(a, 0, b), flat, to_y);                            // wall y = 0
    }
  return gs;
}

TEST(ProxySolver, FaceEdgeAndCornerHoldOneTwoAndThreeConstraintsWithoutAllocating) {
  const CollisionWorld w = world_of(inside_corner(0.002f, 0.04f));
  ProxySolver solver(w, test::ellipsoid_params());
  const double r = 0.004;
  struct Case {
    Eigen::Vector3d start, goal;
    int constraints;
  };
  // Goals 3 mm behind the floor; behind the floor and a wall; behind all three.
  const Case cases[] = {{{0.02, 0.02, 0.01}, {0.021, 0.019, -0.003}, 1},
                        {{0.02, 0.01, 0.01}, {0.021, -0.003, -0.003}, 2},
                        {{0.01, 0.01, 0.01}, {-0.003, -0.003, -0.003}, 3}};
  for (const Case& c : cases) {
    solver.reset();
    const ToolEllipsoid start = ToolEllipsoid::sphere(c.start, r);
    solver.place(start);
    ASSERT_EQ(solver.position(), c.start);
    const std::size_t before = test::allocation_count();
    ProxyMove m;
    for (int k = 0; k < 5; ++k) m = solver.move_toward(start, c.goal, false);
    EXPECT_EQ(test::allocation_count() - before, 0u) << c.constraints;
    // (The count itself is not asserted: in a concave corner the lift out of "pockets between
    // bumps" fires and the planes start afresh, so the corner ends a tick on 1-3 planes.)
    EXPECT_GE(m.constraints, 1) << c.constraints;
    // It never overlaps the walls, and rests on each one the goal is behind (r from its
    // plane, plus at most the discs' 2 um half-thickness and the stand-off); along the others it
    // reaches the goal.
    ToolEllipsoid at = start;
    at.center = m.position;
    EXPECT_FALSE(test::overlaps(w, at)) << c.constraints;
    for (int a = 0; a < 3; ++a) {
      if (c.goal[a] < 0) {
        EXPECT_GE(m.position[a], r - 1e-9) << c.constraints << " axis " << a;
        EXPECT_LE(m.position[a], r + 2e-6 + ProxySolver::kStandOff * r + 1e-7) << c.constraints << " axis " << a;
      } else {
        EXPECT_NEAR(m.position[a], c.goal[a], 2e-5) << c.constraints << " axis " << a;  // the discs' rims tilt the planes
      }
    }
    EXPECT_GE(solver.blockers().size(), std::size_t(c.constraints == 3 ? 2 : 1));
  }
}

TEST(ProxySolver, HoldKeepsThePositionAndTheBlockers) {
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.04f);
  const CollisionWorld w = world_of(gs);
  ProxySolver solver(w, test::ellipsoid_params());
  const ToolEllipsoid tool = ToolEllipsoid::sphere({0.001, 0.001, 0.01}, 0.005);
  solver.place(tool);
  const ProxyMove pressed = solver.move_toward(tool, {0.001, 0.001, -0.002}, false);
  ASSERT_EQ(pressed.constraints, 1);
  const auto blocker = solver.blockers()[0].slot;
  const ProxyMove held = solver.move_toward(tool, {0.01, 0.01, -0.002}, true);
  EXPECT_EQ(held.position, pressed.position);
  EXPECT_EQ(held.constraints, 1);
  ASSERT_EQ(solver.blockers().size(), 1u);
  EXPECT_EQ(solver.blockers()[0].slot, blocker);
  EXPECT_EQ(held.candidates, 0u);  // no sweep while held
}

TEST(ProxySolver, ASlideUnderHalfTheStandOffIsNotSwept) {
  // Resting on a layer, pressed toward a goal below it and a little aside: the slide along the
  // contact plane is swept when it is longer than half the stand-off (the sweeps' tolerance),
  // and left out, the proxy staying where it rests, when it is shorter.
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.04f);
  const CollisionWorld w = world_of(gs);
  const double r = 0.005, eps = ProxySolver::kStandOff * r;
  for (const double aside : {0.3 * eps, 3.0 * eps}) {
    ProxySolver solver(w, test::ellipsoid_params());
    const ToolEllipsoid tool = ToolEllipsoid::sphere({0.0, 0.0, 0.01}, r);  // over a disc's centre
    solver.place(tool);
    const ProxyMove rest = solver.move_toward(tool, {0.0, 0.0, -0.002}, false);
    ASSERT_EQ(rest.constraints, 1);
    const ProxyMove m = solver.move_toward(tool, {aside, 0.0, -0.002}, false);
    SCOPED_TRACE(aside / eps);
    EXPECT_EQ(m.constraints, 1);
    if (aside < 0.5 * eps) {
      EXPECT_EQ(m.sweeps, 1u);
      EXPECT_LT((m.position - rest.position).norm(), 1e-12);
    } else {
      EXPECT_GE(m.sweeps, 2u);
      EXPECT_NEAR(m.position.x(), rest.position.x() + aside, 0.1 * eps);
      EXPECT_NEAR(m.position.z(), rest.position.z(), 0.1 * eps);
    }
  }
}

TEST(ProxySolver, FloatersAreSweptThroughAndCountedAsIsolated) {
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.04f);
  gs.emplace_back(Eigen::Vector3f(0, 0, 0.015f), Eigen::Vector3f::Constant(0.002f), Eigen::Quaternionf::Identity());
  const CollisionWorld w = world_of(gs);
  ProxyParams sp = test::ellipsoid_params();
  for (const bool pass : {true, false}) {
    sp.pass_isolated = pass;
    ProxySolver solver(w, sp);
    const ToolEllipsoid tool = ToolEllipsoid::sphere({0, 0, 0.03}, 0.005);
    solver.place(tool);
    const ProxyMove m = solver.move_toward(tool, {0, 0, -0.001}, false);
    if (pass) EXPECT_LT(m.position.z(), 0.0055);  // on the layer (tops 0.2 mm)
    else EXPECT_GT(m.position.z(), 0.015 + 0.002 + 0.005 - 1e-4);  // on the floater
  }
  ProxySolver solver(w, test::ellipsoid_params());
  std::uint32_t floater = 0;
  for (std::uint32_t s = 0; s < w.gaussians().size(); ++s)
    if (w.gaussians()[s].center[2] > 0.01f) floater = s;
  EXPECT_TRUE(solver.isolated(floater, 0.005));
  EXPECT_FALSE(solver.isolated(floater == 0 ? 1 : 0, 0.005));
}

TEST(ShadedNormal, PointsAwayFromAPlaneOnBothSidesAndIsZeroFarAway) {
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.04f);
  const CollisionWorld w = world_of(gs);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  for (int i = 0; i < 40; ++i) {
    const double side = i % 2 ? 1.0 : -1.0;
    const Eigen::Vector3d p(u(rng), u(rng), side * (0.004 + std::fabs(u(rng)) * 0.1));
    const Eigen::Vector3d n = shaded_normal(w, p, 0.005, 0.5);
    ASSERT_NEAR(n.norm(), 1.0, 1e-12) << i;
    EXPECT_LT(angle_deg(n, side * Eigen::Vector3d::UnitZ()), 1.0) << i;
  }
  EXPECT_EQ(shaded_normal(w, {0, 0, 0.5}, 0.005, 0.5), Eigen::Vector3d::Zero());
}

// A round floater beside a tool resting on a plane: the proxy passed it (it overlaps the tool),
// so it is not the surface. With the tool's FreeBall it is left out of the normal;
// without, its density gradient tilts the normal sideways (the fidelity cube face at 8 mm
// spacing, 11 degrees). The renderers, single and compound, read the field that way.
TEST(ShadedNormal, LeavesOutTheFloatersTheRestingToolOverlaps) {
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.04f);
  gs.emplace_back(Eigen::Vector3f(0.0085f, 0.002f, 0.006f), Eigen::Vector3f::Constant(0.004f),
                  Eigen::Quaternionf::Identity());
  const CollisionWorld w = world_of(gs, 0.5f);
  const double r = 0.005;
  const Eigen::Vector3d rest(0, 0, 0.0002 + r + 1e-5);  // on the layer (tops 0.2 mm), free of it
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  EXPECT_GT(angle_deg(shaded_normal(w, rest, r, 0.5), up), 3.0);  // the floater pulls it sideways
  const FreeBall free{r, up};
  EXPECT_LT(angle_deg(shaded_normal(w, rest, r, 0.5, free), up), 0.5);
  ShadingScratch scratch(64);
  EXPECT_EQ(shaded_normal(w, rest, r, 0.5, scratch, free), shaded_normal(w, rest, r, 0.5, free));
  // A ball of radius 0 changes nothing.
  EXPECT_EQ(shaded_normal(w, rest, r, 0.5, scratch, FreeBall{0.0, up}), shaded_normal(w, rest, r, 0.5));
  // (Passed Gaussians under the tool stay: python/tests' Truck roof, where the floater rule
  // passes much of the roof, holds only with them.)
  // A tool resting 1.2 mm high (on a proud disc): a floater 3 mm above the layer and 3.4 mm
  // (0.68 r) below the tool's centre is still beside it, not under it (the fidelity sphere's
  // seed 8, site 18: 4.1 degrees when the rule stopped at r / 2 below the centre).
  {
    std::vector<GaussianSpec> hs;
    add_layer(hs, 0.0f, 0.004f, 0.04f);
    hs.emplace_back(Eigen::Vector3f(0.0045f, 0.0f, 0.003f), Eigen::Vector3f(0.0035f, 0.0025f, 0.001f),
                    Eigen::Quaternionf::Identity());
    const CollisionWorld hw = world_of(hs, 0.5f);
    const Eigen::Vector3d high(0, 0, 0.0002 + r + 0.0012);
    EXPECT_GT(angle_deg(shaded_normal(hw, high, r, 0.5), up), 3.0);
    EXPECT_LT(angle_deg(shaded_normal(hw, high, r, 0.5, free), up), 0.5);
  }

  // Pressed 2 mm down from above, through the servo-free render call: the force is along +z.
  ProxyRenderer single(w, test::ellipsoid_params());
  CompoundTool ball = CompoundTool::single(Eigen::Vector3d::Constant(r));
  ball.parts[0].offset = Eigen::Vector3d(0, 0, r);  // TCP at the ball's bottom: the compound proxy
  ProxyRenderer compound(w, test::ellipsoid_params());
  compound.set_tool(ball);
  std::array<ToolEllipsoid, kMaxToolParts> parts;
  for (int k = 0; k <= 400; ++k) {
    const double z = 0.02 - 0.02 * std::min(1.0, k / 300.0) + (0.0002 + r - 0.002) * std::min(1.0, k / 300.0);
    const RenderOutput a = single.render(ToolEllipsoid::sphere({0, 0, z}, r), Eigen::Vector3d::Zero(), 1e-3);
    const Eigen::Vector3d tcp(0, 0, z - r);
    const int n = ball.posed(tcp, Eigen::Quaterniond::Identity(), parts);
    const RenderOutput b = compound.render_compound({parts.data(), std::size_t(n)}, tcp, Eigen::Vector3d::Zero(),
                                                    Eigen::Vector3d::Zero(), 1e-3);
    if (k == 400) {
      ASSERT_GT(a.force.norm(), 1.0);
      ASSERT_GT(b.force.norm(), 1.0);
      EXPECT_LT(angle_deg(a.force, up), 0.5);
      EXPECT_LT(angle_deg(b.force, up), 0.5);
    }
  }
}

// A 60-degree groove of 8 mm discs, the tool resting on one face 33 mm from the crease with the
// kernel widened to 13 mm (the width of the large discs the fidelity scenes draw there): the far
// face, 23 mm from the reading point, tilts the sum toward the groove's bisector. Its discs lie
// farther from the reading point than the surface under the tool (FreeBall::surface), so they
// fade; on a flat layer, where every disc's plane is at the surface's distance, the reading is
// bit-identical with or without it.
TEST(ShadedNormal, TheFarFaceOfAConcaveCreaseDoesNotTiltAWideKernel) {
  const float h = 0.008f;
  std::vector<GaussianSpec> gs;
  const Eigen::Vector3f y = Eigen::Vector3f::UnitY();
  Eigen::Vector3f dir[2] = {{-0.5f, 0, 0.8660254f}, {0.5f, 0, 0.8660254f}};
  Eigen::Vector3f nrm[2] = {{0.8660254f, 0, 0.5f}, {-0.8660254f, 0, 0.5f}};
  for (int f = 0; f < 2; ++f)
    for (float along = 0.5f * h; along < 0.08f; along += h)
      for (float v = -0.04f; v <= 0.04f; v += h)
        gs.emplace_back(dir[f] * along + y * v, Eigen::Vector3f(h, h, 0.05f * h),
                        Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), nrm[f]));
  const CollisionWorld w = world_of(gs, 0.5f);
  const double r = 0.010, wide = 0.013;
  const Eigen::Vector3d n0 = nrm[0].cast<double>(), c = dir[0].cast<double>() * 0.033 + n0 * (r + 0.05 * h);
  const double plain = angle_deg(shaded_normal(w, c, wide, 0.5, FreeBall{r, n0}, wide), n0);
  const double faded = angle_deg(shaded_normal(w, c, wide, 0.5, FreeBall{r, n0, r + 0.05 * h}, wide), n0);
  EXPECT_GT(plain, 3.0) << "the set-up: the far face tilts the plain reading";
  EXPECT_LT(faded, 1.0) << plain;
  ShadingScratch scratch(256);
  EXPECT_EQ(shaded_normal(w, c, wide, 0.5, scratch, FreeBall{r, n0, r + 0.05 * h}, wide),
            shaded_normal(w, c, wide, 0.5, FreeBall{r, n0, r + 0.05 * h}, wide));

  std::vector<GaussianSpec> layer;
  add_layer(layer, 0.0f, h, 0.05f);
  const CollisionWorld flat = world_of(layer, 0.5f);
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  for (const Eigen::Vector3d& at : {Eigen::Vector3d(0.001, 0.002, r + 0.05 * h), Eigen::Vector3d(0.003, -0.001, r + 0.05 * h)})
    EXPECT_EQ(shaded_normal(flat, at, wide, 0.5, FreeBall{r, up, r + 0.05 * h}, wide),
              shaded_normal(flat, at, wide, 0.5, FreeBall{r, up}, wide));
}

// On a sparse curved surface (a 5 cm cylinder drawn with 8 mm discs, 9 degrees of arc each) a
// kernel of half a 10 mm tool reads little more than the disc under the tool: its facet. A
// kernel at least as wide as the Gaussian spacing (shading_spacing: the disc under the tool's
// middle semi-axis) averages the neighbours and follows the curvature.
TEST(ShadedNormal, AKernelAsWideAsTheSpacingFollowsASparseCurvedSurface) {
  AnalyticShape shape(ShapeKind::kCylinder);
  SynthParams sp;
  sp.spacing = 0.008;
  sp.floater_share = 0;
  const SyntheticScene s = make_synthetic_scene(shape, sp);
  const CollisionWorld w = CollisionWorld::build(s.scene, WorldConfig{});
  const double r = 0.01;
  std::vector<double> plain, wide;
  for (const SurfaceSample& q : shape.sample_surface(0.006)) {
    const Eigen::Vector3d p = q.position + q.normal * (r + 0.0005);
    // The blocker: the Gaussian nearest to the tool's contact point (a stand-in for the sweep's).
    Contact b;
    double best = INFINITY;
    for (std::uint32_t k = 0; k < w.gaussians().size(); ++k) {
      const auto& g = w.gaussians()[k];
      const double d = (Eigen::Vector3d(g.center[0], g.center[1], g.center[2]) - q.position).norm();
      if (d < best) best = d, b.slot = k;
    }
    const double scale = shading_scale(w, {&b, 1}, r);
    plain.push_back(angle_deg(shaded_normal(w, p, scale, 0.5), q.normal));
    wide.push_back(angle_deg(shaded_normal(w, p, scale, 0.5, {}, shading_spacing(w, {&b, 1})), q.normal));
  }
  ASSERT_GT(plain.size(), 100u);
  const auto p95 = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[std::size_t(0.95 * double(v.size() - 1))];
  };
  EXPECT_LT(p95(wide), 3.0);   // 3.0 before the linear fit
  EXPECT_LT(p95(plain), 3.0);  // 4.1 before the linear fit (the facets: the wider kernel and the fit each mend them)
}

// Where the Gaussians near the reading point lie to one side of it, the plain weighted sum reads
// the surface at their centroid; on a curved surface that is a tilt of offset / radius. The
// second pass fits the directions linearly over the centres and reads the fit at the point
// (shaded_normal.cpp, LocalLinearSum). Exact discs (no jitter, no tilt) on the fidelity
// cylinder (radius 5 cm) at 8 mm spacing, read 10 mm off the surface at 6 mm steps with the
// half-tool kernel: the error is the sampling's alone. With the fit p95 1.6 deg; with the plain
// sum 2.9 (checked with the fit turned off).
TEST(ShadedNormal, ALinearFitReadsASparseCurvedSurfaceAtThePointNotAtTheCentroid) {
  AnalyticShape shape(ShapeKind::kCylinder);
  SynthParams sp;
  sp.spacing = 0.008;
  sp.floater_share = 0;
  sp.normal_jitter = 0;
  sp.tilt_deg = 0;
  sp.low_opacity_share = 0;
  const CollisionWorld w = CollisionWorld::build(make_synthetic_scene(shape, sp).scene, WorldConfig{});
  const double r = 0.01;
  std::vector<double> err;
  for (const SurfaceSample& q : shape.sample_surface(0.006)) {
    if (std::abs(q.position.z()) > 0.1) continue;  // away from the cylinder's rims
    const Eigen::Vector3d p = q.position + q.normal * r;
    err.push_back(angle_deg(shaded_normal(w, p, r, 0.5), q.normal));
  }
  ASSERT_GT(err.size(), 100u);
  std::sort(err.begin(), err.end());
  EXPECT_LT(err[std::size_t(0.95 * double(err.size() - 1))], 2.0);
}

// The same through the renderer: ProxyRenderer reads the field with the blockers' spacing. The
// fidelity cylinder at 8 mm spacing, 20 presses of a 10 mm tool to 5 mm, render() alone: the
// force's direction p95 against the true normal: 2.6 degrees; 4.6 with the half-tool kernel, seed 1.
TEST(ProxyRenderer, PressesOnASparseCylinderFollowItsCurvature) {
  AnalyticShape shape(ShapeKind::kCylinder);
  SynthParams sp;
  sp.spacing = 0.008;
  const CollisionWorld w = CollisionWorld::build(make_synthetic_scene(shape, sp).scene, WorldConfig{});
  const double r = 0.01;
  std::vector<double> err;
  for (const ContactSite& site : shape.press_sites(20, 1, 0.03)) {
    ProxyRenderer proxy(w, test::ellipsoid_params());
    const Script script = press_script(shape, site, r, 0.005, 1000);
    for (const ScriptTick& t : script.ticks) {
      const RenderOutput o = proxy.render(ToolEllipsoid::sphere(t.position, r), t.velocity, 1e-3);
      if (o.force.norm() >= 0.5) err.push_back(angle_deg(o.force, distance_gradient(shape, t.position)));
    }
  }
  ASSERT_GT(err.size(), 10000u);
  std::sort(err.begin(), err.end());
  EXPECT_LT(err[std::size_t(0.95 * double(err.size() - 1))], 3.5);
}

TEST(ShadedNormal, FollowsASphereOfGaussiansWithinAFewDegrees) {
  AnalyticShape shape(ShapeKind::kSphere);
  const SyntheticScene s = make_synthetic_scene(shape, SynthParams{});
  const CollisionWorld w = CollisionWorld::build(s.scene, WorldConfig{});
  double worst = 0;
  int n = 0;
  for (const SurfaceSample& q : shape.sample_surface(0.02)) {
    const Eigen::Vector3d p = q.position + q.normal * 0.005;  // a 5 mm tool resting on it
    worst = std::max(worst, angle_deg(shaded_normal(w, p, 0.005, 0.5), q.normal));
    ++n;
  }
  EXPECT_GT(n, 20);
  EXPECT_LT(worst, 5.0);
}

// The lanes (16 Gaussians a vectorised loop, sums by lanes) against a slow scalar reading written
// from the formulas with matrices (support/shading_reference.h), on the same support: resting
// tools at random sites of the fidelity cube, sphere and concave corner with floaters, with and
// without the tool's free ball, and on the Truck. Summation order and FMA aside they are the same
// function: within 1e-6 degrees.
TEST(ShadedNormal, TheLanesMatchASlowScalarReading) {
  double worst = 0;
  int n = 0;
  const auto check = [&](const CollisionWorld& w, const Eigen::Vector3d& p, double r, const FreeBall& ball,
                         double min_width) {
    const Eigen::Vector3d lanes = shaded_normal(w, p, r, 0.5, ball, min_width);
    const Eigen::Vector3d ref = test::reference_shaded_normal(w, p, r, 0.5, ball, min_width);
    ASSERT_FALSE(ref.isZero(0));
    const double e = angle_deg(lanes, ref);
    worst = std::max(worst, e);
    ++n;
    EXPECT_LT(e, 1e-6) << p.transpose();
  };
  for (ShapeKind kind : {ShapeKind::kCube, ShapeKind::kSphere, ShapeKind::kCorner90})
    for (double spacing : {0.002, 0.008}) {
      const AnalyticShape shape(kind);
      const CollisionWorld w = synthetic_world(shape, spacing, 4);
      for (const double r : {0.005, 0.010}) {
        const std::vector<ContactSite> sites = shape.press_sites(5, 4, 0.03);
        const std::vector<Eigen::Vector3d> centres = resting_centres(w, shape, r, 5, 4);
        for (std::size_t i = 0; i < centres.size(); ++i) {
          check(w, centres[i], r, {}, spacing);
          check(w, centres[i], r, FreeBall{r, sites[i].normal, r}, spacing);
          // The overhang falloff (FreeBall::face) along one face's axis at edges and corners.
          int k = 0;
          sites[i].normal.cwiseAbs().maxCoeff(&k);
          Eigen::Vector3d axis = Eigen::Vector3d::Zero();
          axis[k] = sites[i].normal[k] > 0 ? 1.0 : -1.0;
          check(w, centres[i], r, FreeBall{r, sites[i].normal, r, axis, 0.8 * r, 0.7}, spacing);
        }
      }
    }
  WorldConfig config;
  config.registration = load_registration_file(test::data_path("truck.registration.json"));
  const CollisionWorld truck = CollisionWorld::build(load_scene(test::data_path("truck.splat")).scene, config);
  ContactQuery query(truck);
  const double r = 0.03;
  for (std::size_t k = 0; k < truck.size(); k += 9973) {
    const CollisionGaussian& g = truck.gaussians()[k];
    Eigen::Vector3d p(g.center[0], g.center[1], g.center[2]);
    while (query.any_contact(ToolEllipsoid::sphere(p, r))) p += 2e-3 * truck.up();
    check(truck, p, r, FreeBall{r, truck.up(), r}, 0);
  }
  EXPECT_GT(n, 100);
  RecordProperty("worst_deg", std::to_string(worst));
}

// Where a kernel's leaves hold more than kMaxKernelVisits Gaussians (a large tool on a dense
// surface: 4 and 6 cm tools on 2 mm spacing), the reading takes an even sample of them. The
// plain call, the call with working memory and the slow reference's own sample read the same
// normal; and the sample's normal lies within 3 degrees of the sum over every Gaussian of the
// support on faces, the sphere, edges and corners (the most at the cube's edges and corners,
// where the field turns), well under a degree on average.
TEST(ShadedNormal, ADenseKernelIsReadFromAnEvenSampleNearTheWholeSum) {
  double worst = 0, sum = 0;
  int n = 0, sampled = 0;
  for (ShapeKind kind : {ShapeKind::kPlane, ShapeKind::kSphere, ShapeKind::kCube})
    for (double r : {0.04, 0.06}) {
      const AnalyticShape shape(kind);
      const double spacing = 0.002;
      const CollisionWorld w = synthetic_world(shape, spacing, 7);
      ShadingScratch scratch;
      for (const Eigen::Vector3d& p : resting_centres(w, shape, r, 6, 7)) {
        const Eigen::Vector3d plain = shaded_normal(w, p, r, 0.5, {}, spacing);
        ASSERT_FALSE(plain.isZero(0));
        ASSERT_EQ(plain, shaded_normal(w, p, r, 0.5, scratch, {}, spacing));
        EXPECT_LT(angle_deg(plain, test::reference_shaded_normal(w, p, r, 0.5, {}, spacing)), 1e-6) << p.transpose();
        const Eigen::Vector3d every = test::reference_shaded_normal(w, p, r, 0.5, {}, spacing, kShadingTail, false);
        if (scratch.last_steps() <= 2 * kMaxKernelVisits && every != plain) ++sampled;
        const double gap = angle_deg(plain, every);
        worst = std::max(worst, gap);
        sum += gap;
        ++n;
      }
    }
  EXPECT_EQ(sampled, n);  // (every reading here is a sample)
  EXPECT_LT(worst, 3.0);
  EXPECT_LT(sum / n, 0.6);
  RecordProperty("worst_deg", std::to_string(worst));
  RecordProperty("mean_deg", std::to_string(sum / n));
}

// The shaded normal's support stops at q <= (1 + radius / s)^2 + kShadingTail: against the sum
// over every Gaussian of the scene (the slow reference, unsampled on both sides) (a tail so long that the support holds them all), resting
// tools at random sites (faces, edges and corners) of the fidelity cube, sphere, cylinder and
// concave corner, floaters included, read the same normal within 0.5 deg, and within 0.02 deg
// on average. A support cut at a short tail (6) does not: the check can tell.
TEST(ShadedNormal, TheSupportsTailChangesTheNormalByAFewHundredthsOfADegree) {
  double worst = 0, sum = 0, worst_short = 0;
  int n = 0;
  for (ShapeKind kind : {ShapeKind::kCube, ShapeKind::kSphere, ShapeKind::kCylinder, ShapeKind::kCorner90})
    for (double spacing : {0.002, 0.004, 0.008})
      for (double r : {0.005, 0.010}) {
        const AnalyticShape shape(kind);
        const CollisionWorld w = synthetic_world(shape, spacing, 11);
        for (const Eigen::Vector3d& p : resting_centres(w, shape, r, 6, 11)) {
          // (Every Gaussian of the support, none left out by the sampling of dense kernels.)
          const auto every = [&](double tail) {
            return test::reference_shaded_normal(w, p, r, 0.5, {}, spacing, tail, /*sampled=*/false);
          };
          const Eigen::Vector3d all = every(1e5);
          ASSERT_FALSE(all.isZero(0));
          const double gap = angle_deg(all, every(kShadingTail));
          worst = std::max(worst, gap);
          sum += gap;
          ++n;
          worst_short = std::max(worst_short, angle_deg(all, every(6.0)));
        }
      }
  EXPECT_LT(worst, 0.5);
  EXPECT_LT(sum / n, 0.02);
  EXPECT_GT(worst_short, 1.0);
  RecordProperty("worst_deg", std::to_string(worst));
}

// A 5 mm tool resting on a cube of Gaussians next to a convex edge, on either face and around the
// edge: the shaded normal stays in the edge's normal cone (between the two faces' normals), as
// the fidelity matrix scores it. Discs of one face seen from beside the other have the tool
// behind their plane; taken along their own normal they push the tool into the cube (the plain
// field leaves the cone by up to 60 deg here). At 8 mm spacing the discs overhang the cube's edge
// by several millimetres, more than half the tool, so the shell's edge is not the cube's.
TEST(ShadedNormal, StaysInTheNormalConeAroundAConvexEdge) {
  const AnalyticShape shape(ShapeKind::kCube);
  for (double spacing : {0.002, 0.004}) {
    const CollisionWorld w = shell_without_floaters(shape, spacing);
    ContactQuery query(w);
    const double r = 0.005, h = 0.1;  // tool radius; the cube's half side
    double worst = 0;
    for (double y : {-0.05, -0.013, 0.0, 0.021, 0.06}) {
      const NormalCone cone = shape.normal_cone({h, y, h});
      std::vector<Eigen::Vector3d> points;
      for (double u = 0; u <= 0.006; u += 0.001) {
        points.emplace_back(h - u, y, h + r);  // on the top face, u from the edge
        points.emplace_back(h + r, y, h - u);  // on the side face
      }
      for (double a = 15; a < 90; a += 15)
        points.push_back(Eigen::Vector3d(h, y, h) + r * Eigen::Vector3d(std::sin(a * M_PI / 180), 0, std::cos(a * M_PI / 180)));
      for (Eigen::Vector3d p : points) {
        // Where a proxy can be: moved out until the tool overlaps no Gaussian (at 8 mm spacing the
        // discs overhang the cube's edges by millimetres).
        const Eigen::Vector3d out = distance_gradient(shape, p);
        while (query.any_contact(ToolEllipsoid::sphere(p, r))) p += 1e-4 * out;
        const Eigen::Vector3d n = shaded_normal(w, p, shading_scale(w, {}, r), 0.5);
        const double e = cone.angle_deg(n);
        worst = std::max(worst, e);
        EXPECT_LT(e, 5.0) << "spacing " << spacing << " at " << p.transpose() << ": n " << n.transpose();
      }
    }
    RecordProperty(spacing < 0.003 ? "worst_deg_2mm" : "worst_deg_4mm", std::to_string(worst));
  }
}

// The slot of the Gaussian of `w` centred nearest `c` (the BVH reorders the records).
std::uint32_t slot_near(const CollisionWorld& w, const Eigen::Vector3d& c) {
  std::uint32_t best = 0;
  double best_d = 1e300;
  for (std::uint32_t k = 0; k < w.size(); ++k) {
    const CollisionGaussian& g = w.gaussians()[k];
    const double d = (Eigen::Vector3d(g.center[0], g.center[1], g.center[2]) - c).norm();
    if (d < best_d) best_d = d, best = k;
  }
  return best;
}

// A convex edge along y (solid x < 0, z < 0) drawn with 8 mm discs that end at the edge, but one
// of the side face's discs is 26 mm tall and stands 8.8 mm above the top face: an overhang, as
// the fidelity scenes' discs near an edge are. A 5 mm tool resting on the top face beside it
// touches its flat side.
struct OverhangEdge {
  static constexpr float h = 0.008f;
  static constexpr double r = 0.005;
  CollisionWorld world;
  Eigen::Vector3d at;  // the tool's centre, resting on the top face against the overhang
  OverhangEdge() : world(build()), at(-(0.05 * h + r + 1e-5), 0.0, 0.05 * h + r + 1e-5) {}
  static CollisionWorld build() {
    std::vector<GaussianSpec> gs;
    const Eigen::Quaternionf side = Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitX());
    for (int i = 0; i < 6; ++i)
      for (int j = -5; j <= 5; ++j) {
        const float u = (float(i) + 0.5f) * h, y = float(j) * h;
        gs.emplace_back(Eigen::Vector3f(-u, y, 0), Eigen::Vector3f(0.55f * h, 0.55f * h, 0.05f * h),
                        Eigen::Quaternionf::Identity());
        const bool fin = i == 0 && j == 0;  // (semi-axes in the disc's frame: its z is the world's x)
        gs.emplace_back(Eigen::Vector3f(0, y, -u),
                        fin ? Eigen::Vector3f(1.6f * h, 0.55f * h, 0.05f * h) : Eigen::Vector3f(0.55f * h, 0.55f * h, 0.05f * h),
                        side);
      }
    return world_of(gs, 0.8f);
  }
};

// front_face tells an overhang from the two faces of a clean edge, a concave crease and two
// discs of one face: the overhang lies across the face disc and behind its plane, and the face
// disc does not lie behind the overhang's.
TEST(ShadedNormal, FrontFaceFindsTheFaceUnderAnOverhangAndNothingElse) {
  const OverhangEdge e;
  const float h = OverhangEdge::h;
  const double r = OverhangEdge::r, margin = kOverhangMargin * r;
  const CollisionWorld& w = e.world;
  const Contact top = blocker_contact(w, slot_near(w, {-0.5 * h, 0, 0}));
  const Contact fin = blocker_contact(w, slot_near(w, {0, 0, -0.5 * h}));
  const Contact side = blocker_contact(w, slot_near(w, {0, 2 * h, -0.5 * h}));
  const Contact top_by_side = blocker_contact(w, slot_near(w, {-0.5 * h, 2 * h, 0}));
  const std::vector<Contact> against_fin{top, fin};
  const FrontFace f = front_face(w, against_fin, e.at, margin);
  EXPECT_LT(angle_deg(f.normal, Eigen::Vector3d::UnitZ()), 0.1);
  EXPECT_NEAR(f.height, e.at.z(), 1e-6);  // (the top disc's plane is z = 0)
  EXPECT_NEAR(f.strength, 1.0, 1e-9);
  const std::vector<Contact> reversed{fin, top};
  EXPECT_LT(angle_deg(front_face(w, reversed, e.at, margin).normal, Eigen::Vector3d::UnitZ()), 0.1);
  // A clean edge: each face's disc lies behind the other's plane.
  const std::vector<Contact> edge{top_by_side, side};
  EXPECT_TRUE(front_face(w, edge, Eigen::Vector3d(0.7 * r, 2 * h, 0.7 * r), margin).normal.isZero(0));
  // A concave crease (a floor and a wall of discs in front of each other).
  std::vector<GaussianSpec> crease{
      {Eigen::Vector3f(0.004f, 0, 0), Eigen::Vector3f(h, h, 0.05f * h), Eigen::Quaternionf::Identity()},
      {Eigen::Vector3f(0, 0, 0.004f), Eigen::Vector3f(h, h, 0.05f * h),
       Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitX())}};
  const CollisionWorld cw = world_of(crease);
  const std::vector<Contact> both{blocker_contact(cw, 0), blocker_contact(cw, 1)};
  EXPECT_TRUE(front_face(cw, both, Eigen::Vector3d(r, 0, r), margin).normal.isZero(0));
  // Two discs of one face 16 mm apart, one 0.8 mm proud and tilted 4 degrees: the flat one lies
  // 1.9 mm behind the tilted one's plane, more than the margin, but the two are not across.
  const float tilt = float(4 * M_PI / 180);
  std::vector<GaussianSpec> one_face{
      {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(h, h, 0.05f * h), Eigen::Quaternionf::Identity()},
      {Eigen::Vector3f(0.016f, 0, 0.0008f), Eigen::Vector3f(h, h, 0.05f * h),
       Eigen::Quaternionf(Eigen::AngleAxisf(tilt, Eigen::Vector3f::UnitY()))}};
  const CollisionWorld fw = world_of(one_face);
  const std::vector<Contact> pair{blocker_contact(fw, 0), blocker_contact(fw, 1)};
  EXPECT_TRUE(front_face(fw, pair, Eigen::Vector3d(0.008, 0, r + 0.001), margin).normal.isZero(0));
}

// On the overhang edge the plain shaded normal is pulled toward the overhang's flat side (19
// degrees); with the face under the tool (FreeBall::face) it is the top face's within 2 (the
// overhang, 4 mm behind the top face's plane, keeps a tenth of its weight: 1.6 degrees).
TEST(ShadedNormal, AnOverhangOfTheOtherFaceIsLeftOutBehindTheFaceUnderTheTool) {
  const OverhangEdge e;
  const float h = OverhangEdge::h;
  const double r = OverhangEdge::r, scale = std::max(r, 0.55 * h);
  const CollisionWorld& w = e.world;
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  const double plain = angle_deg(shaded_normal(w, e.at, scale, 0.5, FreeBall{r, up, r}, 0.55 * h), up);
  const std::vector<Contact> blockers{blocker_contact(w, slot_near(w, {-0.5 * h, 0, 0})),
                                      blocker_contact(w, slot_near(w, {0, 0, -0.5 * h}))};
  const FrontFace f = front_face(w, blockers, e.at, kOverhangMargin * r);
  const FreeBall ball{r, up, r, f.normal, f.height, f.strength};
  const double faced = angle_deg(shaded_normal(w, e.at, scale, 0.5, ball, 0.55 * h), up);
  EXPECT_GT(plain, 10.0) << "the set-up: the overhang turns the plain reading";
  EXPECT_LT(faced, 2.0) << plain;
  // The lanes and the scalar reference agree with the falloff on.
  EXPECT_LT(angle_deg(shaded_normal(w, e.at, scale, 0.5, ball, 0.55 * h),
                      test::reference_shaded_normal(w, e.at, scale, 0.5, ball, 0.55 * h)),
            1e-6);
  RecordProperty("plain_deg", std::to_string(plain));
  RecordProperty("faced_deg", std::to_string(faced));
}

// A 10 mm tool sliding over a cube's top face and around its edge on 2 mm spacing (about a
// thousand Gaussians a reading): reading ahead, every normal the cache gives is bit-identical to
// the plain reading at the point where it was read, that point is within `reuse` of the tool,
// and at a slide's pace nearly no call reads the field whole; a jump reads at once.
TEST(ShadedNormalCache, ReadingAheadGivesThePlainReadingWithinReuseAndSpreadsItsCost) {
  const AnalyticShape shape(ShapeKind::kCube);
  SynthParams sp;
  sp.spacing = 0.002;
  const CollisionWorld w = CollisionWorld::build(make_synthetic_scene(shape, sp).scene, WorldConfig{});
  const double r = 0.01, h = 0.1, reuse = 0.05 * r;
  const std::size_t budget = test::ellipsoid_params().shading_budget;
  ShadedNormalCache ahead, whole;
  ShadingScratch scratch, plain_scratch;
  int calls = 0, readings = 0;
  const FreeBall ball{r, Eigen::Vector3d::UnitZ()};
  const auto path = [&](double u) {  // 0.05 mm a call (5 cm/s at 1 kHz)
    return u < 0.03 ? Eigen::Vector3d(h - 0.03 + u, 0.001, h + r)
                    : Eigen::Vector3d(h, 0.001, h) + r * Eigen::Vector3d(std::sin((u - 0.03) / r), 0, std::cos((u - 0.03) / r));
  };
  for (double u = 0; u < 0.045; u += 5e-5, ++calls) {
    const Eigen::Vector3d p = path(u);
    const std::uint64_t before = ahead.reads();
    const Eigen::Vector3d n = ahead.read_ahead(w, p, r, 0.5, reuse, scratch, budget, ball, 0.002);
    readings += int(ahead.reads() - before);
    ASSERT_LE((p - ahead.read_point()).norm(), reuse + 1e-15) << u;
    ASSERT_EQ(n, shaded_normal(w, ahead.read_point(), r, 0.5, plain_scratch, ball, 0.002)) << u;
    (void)whole.read(w, p, r, 0.5, reuse, plain_scratch, ball, 0.002);
  }
  const std::uint64_t whole_before_jump = ahead.whole_reads();
  EXPECT_LE(10 * whole_before_jump, ahead.reads());  // (the first, and where the slide turns the edge)
  {
    // With a turn tolerance (the renderer's default) the field's turn round the edge asks for
    // readings closer than a slide at this pace can prepare; a reading costlier than the budget
    // is then kept as far as one ahead needs, so the slide still reads ahead.
    ShadedNormalCache turn;
    turn.set_turn_tolerance(M_PI / 180);
    ShadingScratch turn_scratch;
    for (double u = 0; u < 0.045; u += 5e-5) {
      const Eigen::Vector3d p = path(u);
      const Eigen::Vector3d n = turn.read_ahead(w, p, r, 0.5, reuse, turn_scratch, budget, ball, 0.002);
      ASSERT_LE((p - turn.read_point()).norm(), reuse + 1e-15) << u;
      ASSERT_EQ(n, shaded_normal(w, turn.read_point(), r, 0.5, plain_scratch, ball, 0.002)) << u;
    }
    EXPECT_LE(8 * turn.whole_reads(), turn.reads()) << turn.whole_reads() << " of " << turn.reads();
  }
  EXPECT_NEAR(readings, int(whole.reads()), int(whole.reads()) / 10);  // (read where the tool will be)
  EXPECT_LT(4 * readings, calls);  // yet each reading serves several calls
  EXPECT_GT(scratch.last_terms(), 0u);
  // A jump past reuse with no reading prepared there: read at once, at the new point.
  const Eigen::Vector3d far(0, 0.001, h + r);
  const Eigen::Vector3d n = ahead.read_ahead(w, far, r, 0.5, reuse, scratch, budget, ball, 0.002);
  EXPECT_EQ(ahead.whole_reads(), whole_before_jump + 1);
  EXPECT_EQ(ahead.read_point(), far);
  EXPECT_EQ(n, shaded_normal(w, far, r, 0.5, ball, 0.002));
  // Budget 0: read() exactly.
  ShadedNormalCache zero;
  for (double u = 0; u < 0.01; u += 5e-5) {
    const Eigen::Vector3d p = path(u);
    const Eigen::Vector3d nz = zero.read_ahead(w, p, r, 0.5, reuse, scratch, 0, ball, 0.002);
    EXPECT_EQ(nz, shaded_normal(w, zero.read_point(), r, 0.5, ball, 0.002));
  }
  EXPECT_EQ(zero.whole_reads(), zero.reads());
  // A reading cheaper than the budget (here every one) is made whole when due, not ahead: the
  // same readings at the same points as read().
  ShadedNormalCache cheap, due;
  for (double u = 0; u < 0.01; u += 5e-5) {
    const Eigen::Vector3d p = path(u);
    const Eigen::Vector3d nc = cheap.read_ahead(w, p, r, 0.5, reuse, scratch, 1000000, ball, 0.002);
    EXPECT_EQ(nc, due.read(w, p, r, 0.5, reuse, plain_scratch, ball, 0.002));
  }
  EXPECT_EQ(cheap.whole_reads(), cheap.reads());
  EXPECT_EQ(cheap.reads(), due.reads());
  // A proxy that wanders (a zigzag of 0.1 mm across a 0.05 mm a call drift: the path is far
  // longer than the displacement) is not read ahead: the readings read() makes, whole.
  ShadedNormalCache wander, plain;
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector3d p = path(5e-5 * i) + Eigen::Vector3d(0, (i % 2 ? 1e-4 : -1e-4), 0);
    const Eigen::Vector3d nw = wander.read_ahead(w, p, r, 0.5, reuse, scratch, budget, ball, 0.002);
    EXPECT_EQ(nw, plain.read(w, p, r, 0.5, reuse, plain_scratch, ball, 0.002));
  }
  EXPECT_EQ(wander.whole_reads(), plain.reads());
  EXPECT_GT(plain.reads(), 3u);
}

// A part whose probe cycles among three Gaussians moves its reading point among three places
// more than `reuse` apart, tick by tick: read() keeps the earlier readings, so the field is read
// once a place, and every normal it gives is bit-identical to the plain reading at a point within
// `reuse` of the call's. A cycle of more places than it keeps reads every time.
TEST(ShadedNormalCache, ReadKeepsEarlierReadingsForAReadingPointThatCycles) {
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.002f, 0.04f);
  const CollisionWorld w = world_of(gs);
  const double r = 0.005, reuse = 0.05 * r;
  const FreeBall ball{r, Eigen::Vector3d::UnitZ()};
  ShadingScratch scratch, plain_scratch;
  const auto place = [&](int k) { return Eigen::Vector3d(0.0014 * k, 0.0003 * k, r + 0.002); };
  for (const int places : {3, int(ShadedNormalCache::kEarlierReadings) + 2}) {
    SCOPED_TRACE(places);
    ShadedNormalCache cache;
    for (int tick = 0; tick < 60; ++tick) {
      // (with a jitter under reuse)
      const Eigen::Vector3d at = place(tick % places) + Eigen::Vector3d(0, 0, 1e-6 * (tick % 7));
      const Eigen::Vector3d n = cache.read(w, at, r, 0.5, reuse, scratch, ball, 0.002);
      ASSERT_LE((at - cache.read_point()).norm(), reuse) << tick;
      ASSERT_EQ(n, shaded_normal(w, cache.read_point(), r, 0.5, plain_scratch, ball, 0.002)) << tick;
    }
    if (places <= int(ShadedNormalCache::kEarlierReadings) + 1)
      EXPECT_EQ(cache.reads(), std::uint64_t(places));
    else
      EXPECT_EQ(cache.reads(), 60u);  // (each place was evicted before it came round again)
  }
}

// Round a convex edge the shaded field turns tens of degrees per millimetre; on a face, tenths.
// A tool rolled slowly (10 um a call) from a cube's top face round its edge and down its side, at
// 4 and 8 mm spacing with 5 and 10 mm tools: with a turn tolerance of 1 degree the normal the
// cache gives stays within about that of the plain reading at the call's point (p95), where the
// cache without it lags by 3-6 degrees p95 (up to 19 at the worst call); on the face it reads no
// more often than without.
TEST(ShadedNormalCache, ATurnToleranceKeepsAReadingOnlyWhileTheFieldTurnsLessThanIt) {
  const AnalyticShape shape(ShapeKind::kCube);
  for (double spacing : {0.004, 0.008}) {
    const CollisionWorld w = shell_without_floaters(shape, spacing, 5);
    ContactQuery query(w);
    for (double r : {0.005, 0.01}) {
      SCOPED_TRACE(testing::Message() << "spacing " << spacing << ", tool " << r);
      const double h = 0.1, reuse = 0.05 * r;
      const auto along = [&](double a) {  // a: radians of the roll round the edge (< 0: on the top face)
        Eigen::Vector3d p = a < 0            ? Eigen::Vector3d(h + a * r, 0.013, h + r)
                            : a > M_PI / 2 ? Eigen::Vector3d(h + r, 0.013, h - (a - M_PI / 2) * r)
                                           : Eigen::Vector3d(h + r * std::sin(a), 0.013, h + r * std::cos(a));
        const Eigen::Vector3d out = distance_gradient(shape, p);
        while (query.any_contact(ToolEllipsoid::sphere(p, r))) p += 1e-5 * out;  // where a proxy can be
        return p;
      };
      double p95[2] = {0, 0};
      std::uint64_t face_reads[2] = {0, 0};
      for (int with = 0; with < 2; ++with) {
        ShadedNormalCache cache;
        cache.set_turn_tolerance(with ? M_PI / 180 : 0.0);
        // (Before two readings the field's turn is unknown: the smallest radius.)
        EXPECT_EQ(cache.reuse_within(reuse), with ? ShadedNormalCache::kMinReuseShare * reuse : reuse);
        ShadingScratch scratch, plain;
        std::vector<double> lag;
        for (double a = -0.6; a <= 2.2; a += 1e-5 / r) {
          const Eigen::Vector3d p = along(a);
          const Eigen::Vector3d n = cache.read(w, p, r, 0.5, reuse, scratch);
          ASSERT_LE((p - cache.read_point()).norm(), reuse + 1e-15);
          lag.push_back(angle_deg(n, shaded_normal(w, p, r, 0.5, plain)));
          if (a < -0.3) face_reads[with] = cache.reads();
        }
        std::sort(lag.begin(), lag.end());
        p95[with] = lag[lag.size() * 95 / 100];
      }
      EXPECT_GT(p95[0], 2.5);  // (the case is one a held normal gets wrong)
      EXPECT_LT(p95[1], 1.2);
      EXPECT_LE(face_reads[1], face_reads[0] + 1);  // (the first reading is kept over the smallest radius)
    }
  }
}

// The force acts along the shaded normal, with the coupling's component along it: a normal held
// over a steep field makes the force depend on the path, and a press read on the way in and again
// on the way out pushed harder out than in. Presses into every edge and corner site of the cube
// (8 and 4 mm spacing, 5 and 10 mm tools, six seeds; through the runtime's servo step): with
// neither the turn tolerance nor the energy bound they gave back up to 3.2 mJ; with the defaults
// none gives energy back. (The tolerance alone held them to -0.5 mJ until the step-up rule of
// WedgedState changed seed 1's 4 mm corner path: -1.45 mJ there without the bound, +0.89 with.)
// The crest hold keeps the proxy still under these presses, so "without" leaves it off too: it
// is the sliding proxy whose turns the bound must take care of (with the hold and without the
// two, no press gave energy back either).
TEST(ProxyRenderer, PressesIntoCubeEdgesAndCornersGiveBackNoEnergy) {
  const AnalyticShape shape(ShapeKind::kCube);
  double worst[2] = {0, 0};
  for (std::uint64_t seed = 1; seed <= 6; ++seed)
    for (double spacing : {0.004, 0.008}) {
      const CollisionWorld w = synthetic_world(shape, spacing, seed);
      for (int with = 0; with < 2; ++with) {
        ProxyParams pp = test::ellipsoid_params();  // with: the defaults
        if (!with) {
          pp.energy_bound = false;
          pp.shading_turn = 0;
          pp.crest_hold = false;
        }
        ProxyRenderer proxy(w, pp);
        for (const ContactSite& site : shape.press_sites(20, seed, 0.03)) {
          if (site.feature == "face") continue;
          for (double r : {0.005, 0.01}) {
            const Script s = press_script(shape, site, r, 0.010, 1000);
            const PressMetrics m = press_metrics(shape, s, play_script(proxy, s, 1000));
            worst[with] = std::min(worst[with], m.energy_j);
          }
        }
      }
    }
  EXPECT_LT(worst[0], -1e-3);  // (without them these presses do give energy back)
  EXPECT_GE(worst[1], 0.0);    // J: with them, none (the press stores ~60 mJ)
  RecordProperty("worst_mJ", std::to_string(worst[1] * 1e3));
}

// The 60-degree groove's crease: under load the proxy creeps along the crease between the
// jittered discs and the shaded normal turns by tens of degrees at a fixed device position
// (bench/RESULTS.md, twenty-sixth session); on the way out the proxy does not creep back the
// same way, and the plain coupling pushed the hand out with up to 12 mJ more than it took.
// Concave presses at 2 mm spacing, 5 and 10 mm tools, six seeds, through the servo step: with
// the energy bound no cycle gives energy back.
TEST(ProxyRenderer, PressesIntoAGrooveCreaseGiveBackNoEnergyWithTheEnergyBound) {
  const AnalyticShape shape(ShapeKind::kVGroove60);
  double worst[2] = {0, 0};
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const CollisionWorld w = synthetic_world(shape, 0.002, seed);
    for (int with = 0; with < 2; ++with) {
      ProxyParams pp = test::ellipsoid_params();
      pp.energy_bound = with == 1;
      ProxyRenderer proxy(w, pp);
      for (const ContactSite& site : shape.press_sites(20, seed, 0.03)) {
        if (site.feature != "concave") continue;
        for (double r : {0.005, 0.01}) {
          const Script s = press_script(shape, site, r, 0.010, 1000);
          const PressMetrics m = press_metrics(shape, s, play_script(proxy, s, 1000));
          worst[with] = std::min(worst[with], m.energy_j);
        }
      }
    }
  }
  EXPECT_LT(worst[0], -1e-3);  // (without the bound these presses do give energy back)
  EXPECT_GE(worst[1], 0.0);    // with it, none
  RecordProperty("worst_mJ", std::to_string(worst[1] * 1e3));
}

// On a curved face of Gaussians the frictionless proxy slides off the discs' rims into the hollows
// between them, up to half the spacing from where the device presses, and the field read where
// it comes to rest points that much round the face: seed 4's cylinder (5 cm radius) at 8 mm
// spacing with the 10 mm tool read 3.8 degrees p95 over its 20 presses (issue 36 asks 3). Read
// where the device would rest too (ProxyParams::device_shading), it is within 3 degrees, and the
// presses give back no energy; without it, over 3. Through the runtime's servo step.
TEST(ProxyRenderer, TheFieldReadWhereTheDeviceWouldRestKeepsACurvedFacesDirection) {
  const AnalyticShape shape(ShapeKind::kCylinder);
  const std::uint64_t seed = 4;
  const CollisionWorld w = synthetic_world(shape, 0.008, seed);
  double p95[2] = {0, 0}, worst_energy = 0;
  for (int with = 0; with < 2; ++with) {
    ProxyParams pp = test::ellipsoid_params();  // with: the defaults
    if (!with) pp.device_shading = 0;
    ProxyRenderer proxy(w, pp);
    std::vector<double> directions;
    for (const ContactSite& site : shape.press_sites(20, seed, 0.03)) {
      const Script s = press_script(shape, site, 0.01, 0.010, 1000);
      const PressMetrics m = press_metrics(shape, s, play_script(proxy, s, 1000));
      directions.insert(directions.end(), m.direction_deg.begin(), m.direction_deg.end());
      if (with) worst_energy = std::min(worst_energy, m.energy_j);
    }
    ASSERT_GT(directions.size(), 1000u);
    p95[with] = percentile(directions, 95);
  }
  EXPECT_GT(p95[0], 3.0);  // (the proxy's own reading alone)
  EXPECT_LE(p95[1], 3.0);
  EXPECT_GE(worst_energy, 0.0);
  RecordProperty("p95_deg_without", std::to_string(p95[0]));
  RecordProperty("p95_deg_with", std::to_string(p95[1]));
}

// The force direction error p95 (degrees) of the fidelity presses at the `feature` sites of
// `kind`'s Gaussians (spacing and tool radius in m, 20 sites drawn with `seed`), through the
// servo step with `params`; the worst press energy is kept in `worst_energy` (J).
double press_direction_p95(ShapeKind kind, double spacing, double radius, std::uint64_t seed, const char* feature,
                           const ProxyParams& params, double& worst_energy) {
  const AnalyticShape shape(kind);
  const CollisionWorld w = synthetic_world(shape, spacing, seed);
  ProxyRenderer proxy(w, params);
  std::vector<double> directions;
  for (const ContactSite& site : shape.press_sites(20, seed, 0.03)) {
    if (site.feature != feature) continue;
    const Script s = press_script(shape, site, radius, 0.010, 1000);
    const PressMetrics m = press_metrics(shape, s, play_script(proxy, s, 1000));
    directions.insert(directions.end(), m.direction_deg.begin(), m.direction_deg.end());
    worst_energy = std::min(worst_energy, m.energy_j);
  }
  EXPECT_GT(directions.size(), 500u);
  return percentile(directions, 95);
}

// Pressed into a cube's corner, the proxy comes to rest on one face a few mm from the corner, as
// a god-object on the analytic cube would, and the shaded field of that face tilts out of the
// corner's normal cone by its discs' jitter: seed 16's 8 mm cube with the 5 mm tool read 5.7
// degrees p95 over its corner presses (issue 36 asks 5). At a clean convex corner the patch's
// support normal stays in the cone (ProxyParams::corner_normal); the presses give back no
// energy. In the 60-degree groove's crease (seed 2, 2 mm, 10 mm tool) the rule must not fire:
// there the walls' discs face away from the tool once turned away from their centroid (it read
// 20.8 degrees before the corner test checked that).
TEST(ProxyRenderer, TheCornerNormalKeepsACubeCornersForceInItsConeAndLeavesCreasesAlone) {
  const auto corner_p95 = [](ShapeKind kind, double spacing, double radius, std::uint64_t seed, const char* feature,
                             bool with, double& worst_energy) {
    ProxyParams pp = test::ellipsoid_params();
    pp.corner_normal = with;
    // (The overhang falloff alone also keeps this corner in its cone, 2.0 degrees p95, and so
    // does the crest hold, which keeps the proxy off the face: both off, so that the corner
    // normal is what is measured.)
    pp.overhang_falloff = false;
    pp.crest_hold = false;
    return press_direction_p95(kind, spacing, radius, seed, feature, pp, worst_energy);
  };
  double energy = 0, ignored = 0;
  const double without = corner_p95(ShapeKind::kCube, 0.008, 0.005, 16, "corner", false, ignored);
  const double with = corner_p95(ShapeKind::kCube, 0.008, 0.005, 16, "corner", true, energy);
  EXPECT_GT(without, 5.0);
  EXPECT_LE(with, 5.0);
  EXPECT_GE(energy, 0.0);
  const double crease = corner_p95(ShapeKind::kVGroove60, 0.002, 0.01, 2, "concave", true, energy);
  EXPECT_LT(crease, 2.0);
  RecordProperty("corner_p95_deg_without", std::to_string(without));
  RecordProperty("corner_p95_deg_with", std::to_string(with));
  RecordProperty("crease_p95_deg", std::to_string(crease));
}

// The fidelity cube (seed 1) pressed 10 mm into its edges and corners along their bisectors
// through the servo step, at 2 and 8 mm spacing with the 5 mm tool. Without the crest hold the
// frictionless proxy rolls off the discs' rims toward a face once the device passes under the
// crest, at a depth the discs decide: the 2 mm edges read 0.75 N/mm and the 8 mm corners 0.83
// where every face reads 1.00 (stiffness across densities 1.12-1.31 on seed 1). Held, every edge
// and corner reads the coupling's 1.00 N/mm, its force inside the feature's normal cone, and no
// press gives energy back. A slide over the edge (the device moving across the spring) is the
// same with and without.
TEST(ProxyRenderer, PressedIntoACubesEdgeOrCornerTheProxyHoldsOnTheCrest) {
  const AnalyticShape shape(ShapeKind::kCube);
  const double radius = 0.005;
  double lowest_without = 10, worst_energy = 1;
  for (const double spacing : {0.002, 0.008}) {
    const CollisionWorld w = synthetic_world(shape, spacing, 1);
    for (const bool hold : {false, true}) {
      ProxyParams pp = test::ellipsoid_params();
      pp.crest_hold = hold;
      ProxyRenderer proxy(w, pp);
      for (const char* feature : {"edge", "corner"}) {
        std::vector<double> stiffness, directions;
        for (const ContactSite& site : shape.press_sites(20, 1, 0.03)) {
          if (site.feature != feature) continue;
          const Script s = press_script(shape, site, radius, 0.010, 1000);
          const PressMetrics m = press_metrics(shape, s, play_script(proxy, s, 1000));
          stiffness.push_back(m.stiffness_n_per_mm);
          directions.insert(directions.end(), m.direction_deg.begin(), m.direction_deg.end());
          if (hold) worst_energy = std::min(worst_energy, m.energy_j);
        }
        ASSERT_GE(stiffness.size(), 4u);
        const double median = percentile(stiffness, 50);
        if (!hold) {
          lowest_without = std::min(lowest_without, median);
          continue;
        }
        EXPECT_NEAR(median, 1.0, 0.01) << feature << " at " << spacing;
        EXPECT_LE(percentile(directions, 95), 5.0) << feature << " at " << spacing;
      }
    }
    // The slide over the cube's edge, 2 mm deep at 5 cm/s.
    double p95[2];
    for (const bool hold : {false, true}) {
      ProxyParams pp = test::ellipsoid_params();
      pp.crest_hold = hold;
      ProxyRenderer proxy(w, pp);
      const Script s = slide_script(shape, radius, 1000);
      p95[hold] = percentile(slide_metrics(shape, s, play_script(proxy, s, 1000)).direction_deg, 95);
    }
    EXPECT_NEAR(p95[1], p95[0], 0.1) << spacing;
  }
  EXPECT_LT(lowest_without, 0.9);  // (what the hold is for: not vacuous on this cube)
  EXPECT_GE(worst_energy, 0.0);
  RecordProperty("lowest_median_stiffness_without", std::to_string(lowest_without));
}

// The fidelity cube at 8 mm spacing with the 5 mm tool, through the servo step: on seed 25 a -y
// face disc 16 mm across reaches 12 mm below the -z face, and the tool pressed into that edge
// rests on the -z face against its flat side; on seed 19 a corner's tool rests in the same way
// beside a fin. The plain shaded normal takes the overhang's side (edge p95 23 degrees, corner
// 22); leaving out the other face's discs behind the face under the tool keeps both within 5,
// and no press gives energy back.
TEST(ProxyRenderer, AnOverhangingDiscOfTheOtherFaceDoesNotTurnTheFaceItBlocks) {
  const auto p95 = [](std::uint64_t seed, const char* feature, bool with, double& worst_energy) {
    ProxyParams pp = test::ellipsoid_params();
    pp.overhang_falloff = with;
    pp.crest_hold = false;  // (held on the crest, the tool does not come to rest against the fin)
    return press_direction_p95(ShapeKind::kCube, 0.008, 0.005, seed, feature, pp, worst_energy);
  };
  double energy = 0, ignored = 0;
  const double edge_without = p95(25, "edge", false, ignored), edge_with = p95(25, "edge", true, energy);
  const double corner_without = p95(19, "corner", false, ignored), corner_with = p95(19, "corner", true, energy);
  EXPECT_GT(edge_without, 10.0);
  EXPECT_LE(edge_with, 5.0);
  EXPECT_GT(corner_without, 10.0);
  EXPECT_LE(corner_with, 5.0);
  EXPECT_GE(energy, 0.0);
  RecordProperty("edge_p95_deg_without", std::to_string(edge_without));
  RecordProperty("edge_p95_deg_with", std::to_string(edge_with));
  RecordProperty("corner_p95_deg_without", std::to_string(corner_without));
  RecordProperty("corner_p95_deg_with", std::to_string(corner_with));
}

// Seed 32's 8 mm cube, 5 mm tool, pressed 10 mm into its corners, through the servo step: at
// one corner the proxy slides off onto the top face against a fin (a disc of the +y face
// standing above the top), with three blockers. The patch's hull holds the fin's rim, so its
// support normal leaned 9 degrees off the fin, out of the corner's normal cone (p95 9.1 over
// the corners; checked by building without the fade). The shaded normal already leaves the fin
// out (the overhang falloff), and where front_face finds the overhang the corner's answer fades
// out by its strength.
TEST(ProxyRenderer, TheCornerNormalGivesWayWhereAFinBlocksTheTool) {
  double energy = 0;
  const double p95 = press_direction_p95(ShapeKind::kCube, 0.008, 0.005, 32, "corner", test::ellipsoid_params(), energy);
  EXPECT_LE(p95, 5.0);
  EXPECT_GE(energy, 0.0);
  RecordProperty("corner_p95_deg", std::to_string(p95));
}

// A god-object moves toward its goal and never away from it: under a loaded coupling a move away
// from the device is energy the proxy makes. Sweeps toward the constrained goal cannot move away;
// the step-up out of a pocket does, and it is kept only when the tick's sweeps after it end
// nearer the goal than where the proxy was wedged (WedgedState). Concave presses into the
// 60-degree groove's crease at 4 and 8 mm spacing, 5 and 10 mm tools, six seeds, driving the
// solver tick by tick with the press script's device positions: without the rule the proxy
// stepped up 0.4 mm under 21 N at the turn of a press (seed 9, 8 mm, site 14: -4.8 mJ).
TEST(ProxySolver, AStepUpNeverLeavesTheProxyFartherFromItsGoal) {
  const AnalyticShape shape(ShapeKind::kVGroove60);
  double worst = 0;  // largest growth of |proxy - goal| over one tick, m
  int wedged_ticks = 0;
  for (std::uint64_t seed : {4, 5, 6, 9}) {
    for (double spacing : {0.004, 0.008}) {
      const CollisionWorld w = synthetic_world(shape, spacing, seed);
      for (const ContactSite& site : shape.press_sites(20, seed, 0.03)) {
        if (site.feature != "concave") continue;
        for (double r : {0.005, 0.01}) {
          ProxySolver solver(w, test::ellipsoid_params());
          const Script s = press_script(shape, site, r, 0.010, 1000);
          solver.place(ToolEllipsoid::sphere(s.ticks.front().position, r));
          for (const ScriptTick& t : s.ticks) {
            const double before = (solver.position() - t.position).norm();
            const ProxyMove m = solver.move_toward(ToolEllipsoid::sphere(t.position, r), t.position, false);
            worst = std::max(worst, (m.position - t.position).norm() - before);
            wedged_ticks += m.constraints >= 2;
          }
        }
      }
    }
  }
  EXPECT_GT(wedged_ticks, 1000);  // (the proxy does rest in the crease on two planes)
  EXPECT_LE(worst, 1e-12);
  RecordProperty("worst_um", std::to_string(worst * 1e6));
}

// A step-up WedgedState undid is not tried again from the same place until the goal has moved a
// lift away: held still in the crease, the proxy pays its substeps a tick, not a step-up and
// its sweeps every tick only to undo them (halo's probe run: proxy p99 17.6 -> 8.4 us).
TEST(ProxySolver, AnUndoneStepUpIsNotRetriedWhileTheGoalStaysWithinALift) {
  const AnalyticShape shape(ShapeKind::kVGroove60);
  const std::uint64_t seed = 9;
  const CollisionWorld w = synthetic_world(shape, 0.008, seed);
  int held = 0, costly = 0;
  for (const ContactSite& site : shape.press_sites(20, seed, 0.03)) {
    if (site.feature != "concave") continue;
    for (double r : {0.005, 0.01}) {
      ProxySolver solver(w, test::ellipsoid_params());
      const Script s = press_script(shape, site, r, 0.010, 1000);
      solver.place(ToolEllipsoid::sphere(s.ticks.front().position, r));
      Eigen::Vector3d last = solver.position();
      for (std::size_t k = 0; k < s.ticks.size(); ++k) {
        const ScriptTick& t = s.ticks[k];
        const ProxyMove m = solver.move_toward(ToolEllipsoid::sphere(t.position, r), t.position, false);
        // The hold: the device still at the deepest point, after the first ticks of it.
        if (k > 0 && t.velocity.norm() == 0 && t.delta > 0 && s.ticks[k - 1].velocity.norm() == 0) {
          ++held;
          costly += m.sweeps > 4;  // (4 substeps; a step-up adds its own sweep)
          EXPECT_EQ(m.position, last);  // (and it stays put)
        }
        last = m.position;
      }
    }
  }
  EXPECT_GT(held, 2000);
  EXPECT_EQ(costly, 0);
}

// The stylus `stylus:0.06,0.005` pressed tip-first into the 60-degree groove's crease at its
// concave press sites, tick by tick: the tip (the TCP) leads, the stylus along the site normal.
// `on_press(proxy, q, script)` runs each press on a fresh proxy.
template <typename OnPress>
void stylus_groove_presses(std::initializer_list<std::uint64_t> seeds, std::initializer_list<double> spacings,
                           OnPress&& on_press) {
  const AnalyticShape shape(ShapeKind::kVGroove60);
  const CompoundTool stylus = parse_tool_spec("stylus:0.06,0.005");
  for (std::uint64_t seed : seeds)
    for (double spacing : spacings) {
      const CollisionWorld w = synthetic_world(shape, spacing, seed);
      for (const ContactSite& site : shape.press_sites(20, seed, 0.03)) {
        if (site.feature != "concave") continue;
        CompoundProxy proxy(w, stylus);
        const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), site.normal);
        on_press(proxy, q, press_script(shape, site, 0.005, 0.010, 1000));
      }
    }
}

// The compound proxy's god-object follows the same rule (WedgedState): a stylus pressed tip-first
// into the 60-degree groove's crease, tick by tick, never ends a tick farther from the device's
// TCP than it began it (its orientation held at the device's, so only the translation moves it).
TEST(CompoundProxy, AStepUpNeverLeavesTheStylusFartherFromTheDevice) {
  double worst = 0;
  int wedged = 0;
  stylus_groove_presses({4, 5, 6, 9}, {0.002, 0.004, 0.008},
                        [&](CompoundProxy& proxy, const Eigen::Quaterniond& q, const Script& s) {
                          Eigen::Vector3d last = s.ticks.front().position;
                          for (const ScriptTick& t : s.ticks) {
                            const RenderOutput out =
                                proxy.render(t.position, q, t.velocity, Eigen::Vector3d::Zero(), 1e-3);
                            worst = std::max(worst, (out.proxy - t.position).norm() - (last - t.position).norm());
                            wedged += out.constraints >= 2;
                            last = out.proxy;
                          }
                        });
  EXPECT_GT(wedged, 1000);  // (the stylus does rest in the crease on two planes)
  EXPECT_LE(worst, 1e-12);
  RecordProperty("worst_um", std::to_string(worst * 1e6));
}

TEST(ShadedNormal, TheKernelScaleFollowsTheLargestBlocker) {
  const CollisionWorld w = world_of({{Eigen::Vector3f::Zero(), Eigen::Vector3f(0.03f, 0.02f, 0.001f), Eigen::Quaternionf::Identity()},
                                     {Eigen::Vector3f(0.1f, 0, 0), Eigen::Vector3f::Constant(0.001f), Eigen::Quaternionf::Identity()}});
  Contact big, small;
  big.slot = 0;
  small.slot = 1;
  for (std::uint32_t s = 0; s < 2; ++s) (w.gaussians()[s].center[0] > 0.05f ? small : big).slot = s;
  EXPECT_EQ(shading_scale(w, {}, 0.005), 0.005);
  EXPECT_EQ(shading_scale(w, {&small, 1}, 0.005), 0.005);
  EXPECT_NEAR(shading_scale(w, {&big, 1}, 0.005), 0.02, 1e-9);  // the middle semi-axis
}

TEST(FrictionCone, SticksInsideTheConeAndSlidesOutsideIt) {
  FrictionCone cone(0.5, 0.3);
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ(), proxy(0, 0, 0.005);
  const double r = 0.005;
  // No contact: the goal is the device.
  FrictionStep f = cone.update(false, n, {0.001, 0, 0.003}, proxy, Eigen::Vector3d::Zero(), r);
  EXPECT_FALSE(f.sticking || f.sliding);
  EXPECT_EQ(f.goal, Eigen::Vector3d(0.001, 0, 0.003));
  // Depth 2 mm, offset 0.9 mm < 0.5 x 2 mm: sticks.
  f = cone.update(true, n, {0.0009, 0, 0.003}, proxy, {0.0001, 0, 0}, r);
  EXPECT_TRUE(f.sticking);
  EXPECT_EQ(f.goal, proxy);
  // Offset 1.1 mm > 1 mm: slides, kept mu_k x depth behind the device along its motion.
  f = cone.update(true, n, {0.0011, 0, 0.003}, proxy, {0.0002, 0, 0}, r);
  ASSERT_TRUE(f.sliding);
  EXPECT_TRUE(cone.sliding());
  EXPECT_NEAR((f.slip_dir - Eigen::Vector3d::UnitX()).norm(), 0, 1e-12);
  EXPECT_NEAR((f.goal - Eigen::Vector3d(0.0011 - 0.3 * 0.002, 0, 0.003)).norm(), 0, 1e-12);
  // While sliding the kinetic limit applies: 0.7 mm > 0.3 x 2 mm keeps it sliding even though
  // it is inside the static cone; moving on keeps it sliding at any offset.
  f = cone.update(true, n, {0.0007, 0, 0.003}, proxy, {-0.0001, 0, 0}, r);
  EXPECT_TRUE(f.sliding);
  f = cone.update(true, n, {0.0001, 0, 0.003}, proxy, {0.0001, 0, 0}, r);
  EXPECT_TRUE(f.sliding);
  // Stopped inside the kinetic cone: sticks again.
  f = cone.update(true, n, {0.0005, 0, 0.003}, proxy, {-0.0001, 0, 0}, r);
  EXPECT_TRUE(f.sticking);
  // Off the surface (no depth): no friction.
  f = cone.update(true, n, {0.0005, 0, 0.006}, proxy, Eigen::Vector3d::Zero(), r);
  EXPECT_FALSE(f.sticking || f.sliding);
  // mu_s = 0: friction off.
  FrictionCone off(0, 0);
  EXPECT_FALSE(off.update(true, n, {0.0001, 0, 0.003}, proxy, Eigen::Vector3d::Zero(), r).sticking);
}

TEST(VirtualCoupling, SpringDamperAlongTheNormalNeverPullsAndIsClamped) {
  ProxyParams params = test::ellipsoid_params();
  params.stiffness = 1000.0;
  params.damping = 2.0;
  params.energy_bound = false;
  VirtualCoupling c(params, 10.0);
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  const FrictionStep none;
  // 3 mm deep, moving in at 0.1 m/s: 3 N + 0.2 N along n; the tangential offset is not rendered.
  Eigen::Vector3d f = c.force({0.001, 0, 0.003}, n, {0, 0, -0.1}, 1e-3, {}, none, 0);
  EXPECT_NEAR((f - Eigen::Vector3d(0, 0, 3.2)).norm(), 0, 1e-12);
  // Moving out fast: the damping would pull; the force stops at zero.
  f = c.force({0, 0, 0.001}, n, {0, 0, 1.0}, 1e-3, {}, none, 0);
  EXPECT_EQ(f, Eigen::Vector3d::Zero());
  // Clamped to f_max along its own direction.
  f = c.force({0, 0, 0.05}, n, Eigen::Vector3d::Zero(), 1e-3, {}, none, 0);
  EXPECT_NEAR(f.norm(), 10.0, 1e-12);
  // Sticking adds the spring's tangential part; sliding subtracts mu_k |F_n| along slip.
  FrictionStep stick;
  stick.sticking = true;
  f = c.force({0.001, 0, 0.003}, n, Eigen::Vector3d::Zero(), 1e-3, {}, stick, 0.3);
  EXPECT_NEAR((f - Eigen::Vector3d(1.0, 0, 3.0)).norm(), 0, 1e-12);
  FrictionStep slide;
  slide.sliding = true;
  slide.slip_dir = Eigen::Vector3d::UnitX();
  f = c.force({-0.001, 0, 0.003}, n, Eigen::Vector3d::Zero(), 1e-3, {}, slide, 0.3);
  EXPECT_NEAR((f - Eigen::Vector3d(-0.9, 0, 3.0)).norm(), 0, 1e-12);
}

// The spring k/2 (e.n)^2 with e = proxy - device. A press along -z into a wall at z = 0: the
// device goes 4 mm in, the shaded normal turns at a fixed device position (a re-reading), the
// device comes back out. The hand's work over the cycle, -sum F . dx (F = k depth n), is what the
// spring keeps; the plain spring gives energy back when the turn raised its depth.
TEST(SpringEnergyBound, TurnsThatRaiseTheSpringsDepthAreNotRenderedAndACycleIsPassive) {
  const double k = 1000.0;
  const Eigen::Vector3d proxy(0, 0, 0);
  const Eigen::Vector3d n_in = Eigen::Vector3d(std::sin(0.6), 0, std::cos(0.6)), n_out = Eigen::Vector3d::UnitZ();
  const auto cycle = [&](bool bounded, double* jump_before, double* jump_after) {
    SpringEnergyBound bound;
    double work = 0;
    Eigen::Vector3d device = proxy, last = proxy;
    Eigen::Vector3d last_force = Eigen::Vector3d::Zero();
    const auto tick = [&](const Eigen::Vector3d& n) {
      const Eigen::Vector3d e = proxy - device;
      const double d = bounded ? bound.depth(e, n, k) : e.dot(n);
      const Eigen::Vector3d f = k * std::max(0.0, d) * n;
      work -= 0.5 * (f + last_force).dot(device - last);
      last = device;
      last_force = f;
      return d;
    };
    for (int i = 1; i <= 400; ++i) {  // in, 10 um a tick, with the first normal
      device.z() = -1e-5 * i;
      tick(n_in);
    }
    *jump_before = tick(n_in);
    *jump_after = tick(n_out);  // the re-reading at a fixed device position: the normal turns
    for (int i = 399; i >= -10; --i) {  // out with the second one
      device.z() = -1e-5 * std::max(i, 0);
      tick(n_out);
    }
    return work;
  };
  double before = 0, after = 0;
  const double plain = cycle(false, &before, &after);
  EXPECT_NEAR(after / before, 1.0 / std::cos(0.6), 1e-9);  // the plain spring's depth jumps with the normal
  EXPECT_LT(plain, -1e-3);  // ... and the cycle gives back 0.5 k d^2 (1 - cos^2 0.6), about 2.5 mJ
  EXPECT_NEAR(plain, -0.5 * k * 0.004 * 0.004 * (1 - std::cos(0.6) * std::cos(0.6)), 1e-5);
  const double bounded = cycle(true, &before, &after);
  EXPECT_NEAR(after, before, 1e-15);  // bounded: the depth does not jump
  // The cycle gives nothing back (the force now ends 4 (1 - cos 0.6) mm before the wall, and
  // the work out, k/2 (4 mm - that)^2, is the work in, k/2 (4 mm cos 0.6)^2; 1e-8 J: the
  // trapezoid at the kink).
  EXPECT_NEAR(bounded, 0.0, 1e-8);

  // Without turns the bound is the plain spring, bit for bit. The offset e = (0, 0, 4 mm) held,
  // the normal n(a) = (sin a, 0, cos a) turning: a rise with an empty bank is withheld; a fall
  // pays the withheld depth back first, and what is left of it is rendered and banked; a later
  // rise up to the bank is rendered as it comes; the proxy's own moves are rendered as they are;
  // release() forgets the contact.
  SpringEnergyBound b;
  const auto n = [](double a) { return Eigen::Vector3d(std::sin(a), 0, std::cos(a)); };
  const auto energy = [k](double x) { return 0.5 * k * x * x; };
  const Eigen::Vector3d e(0, 0, 0.004);
  EXPECT_EQ(b.depth({0, 0, 0.003}, n(0.6), k), 0.003 * std::cos(0.6));
  EXPECT_EQ(b.depth(e, n(0.6), k), 0.004 * std::cos(0.6));                 // the device moved 1 mm in
  EXPECT_NEAR(b.depth(e, n(0.0), k), 0.004 * std::cos(0.6), 1e-15);        // turned up: withheld
  EXPECT_NEAR(b.withheld(), 0.004 * (1 - std::cos(0.6)), 1e-15);
  EXPECT_NEAR(b.depth(e, n(0.3), k), 0.004 * std::cos(0.6), 1e-15);        // turned back a little: paid back
  EXPECT_EQ(b.bank(), 0.0);
  EXPECT_NEAR(b.depth(e, n(1.0), k), 0.004 * std::cos(1.0), 1e-15);        // further: the rest, then rendered
  EXPECT_EQ(b.withheld(), 0.0);
  EXPECT_NEAR(b.bank(), energy(0.004 * std::cos(0.6)) - energy(0.004 * std::cos(1.0)), 1e-12);  // ... and banked
  EXPECT_NEAR(b.depth(e, n(0.6), k), 0.004 * std::cos(0.6), 1e-15);        // up again: paid from the bank
  EXPECT_NEAR(b.bank(), 0.0, 1e-12);
  EXPECT_NEAR(b.depth(e, n(0.0), k), 0.004 * std::cos(0.6), 1e-12);        // and more: the bank is empty
  const double held = b.withheld();
  EXPECT_GT(held, 0.0);
  EXPECT_NEAR(b.depth({0, 0, 0.005}, n(0.0), k), 0.005 - held, 1e-15);     // the proxy's move: as it is
  EXPECT_EQ(b.withheld(), held);
  b.release();
  EXPECT_EQ(b.withheld(), 0.0);
  EXPECT_EQ(b.depth(e, n(0.0), k), 0.004);  // a new contact starts with nothing withheld
}

// Turns back and forth among a few normals under a slowly moving offset (a stylus's normal
// jumping between a ridge's faces, as on the 1 mm grating): the depth stays finite, the
// withheld depth and the bank never go negative. (A fall the withheld depth absorbed whole could
// leave the bank at -1e-20 by rounding, and the next rise read its square root as a NaN depth:
// the force vanished for that tick. 1 NaN and 2,746 negative banks in this replay before.)
TEST(SpringEnergyBound, RoundingNeverMakesANaNDepthOrANegativeBank) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  const std::array<Eigen::Vector3d, 3> normals = {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.719, 0, 0.695).normalized(),
                                                  Eigen::Vector3d(-0.5, 0.1, 0.86).normalized()};
  for (int run = 0; run < 200; ++run) {
    SpringEnergyBound b;
    Eigen::Vector3d e(0.0003 * u(rng), 0.0003 * u(rng), 0.002);
    for (int i = 0; i < 2000; ++i) {
      if (i % 7 == 0) e += Eigen::Vector3d(0.0001 * u(rng), 0.0001 * u(rng), 0.0001 * u(rng));
      const double d = b.depth(e, normals[std::size_t(i * 7919 % 3)], 1000);
      ASSERT_TRUE(std::isfinite(d)) << run << " " << i;
      ASSERT_GE(b.bank(), 0.0) << run << " " << i;
      ASSERT_GE(b.withheld(), 0.0) << run << " " << i;
      ASSERT_LE(d, e.dot(normals[std::size_t(i * 7919 % 3)]) + 1e-15);  // never more than the spring's depth
    }
  }
}

TEST(VirtualCoupling, OpacityStiffnessApproachesTheBlockersMeanOpacityWithItsTimeConstant) {
  ProxyParams params = test::ellipsoid_params();
  params.stiffness = 1000.0;
  params.damping = 0.0;
  params.opacity_stiffness = true;
  params.tau_opacity = 0.02;
  VirtualCoupling c(params, INFINITY);
  Contact a, b;
  a.opacity = 0.4f;
  b.opacity = 0.6f;
  const Contact both[2] = {a, b};
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ(), e(0, 0, 0.002);
  // After 20 ms (one time constant) the factor has covered 1 - 1/e of the way from 1 to 0.5.
  Eigen::Vector3d f;
  for (int k = 0; k < 20; ++k) f = c.force(e, n, Eigen::Vector3d::Zero(), 1e-3, both, FrictionStep{}, 0);
  const double expected = 0.5 + 0.5 * std::exp(-1.0);
  EXPECT_NEAR(c.opacity_factor(), expected, 1e-7);  // (float opacities)
  EXPECT_NEAR(f.z(), 2.0 * expected, 2e-7);
  c.release();
  EXPECT_EQ(c.opacity_factor(), 1.0);
}


// The compound proxy keeps ProxySolver's rule too: a step-up WedgedState undid is not tried again
// from the same pose while the goal stays within a lift of its goal then. A stylus held tip-first
// in the 60-degree groove's crease pays its substeps and its contact probe a tick, not a step-up
// and the sweeps after it every tick only to undo them (the fidelity side-on stylus at seed 12,
// wedged between three discs: tick p99 81 -> 40 us).
TEST(CompoundProxy, AnUndoneStepUpIsNotRetriedWhileTheGoalStaysWithinALift) {
  const int per_tick = test::ellipsoid_params().substeps + 1;  // (the substeps and the contact probe)
  int held = 0, costly = 0;
  stylus_groove_presses({4, 9}, {0.004, 0.008}, [&](CompoundProxy& proxy, const Eigen::Quaterniond& q, const Script& s) {
    for (std::size_t k = 0; k < s.ticks.size(); ++k) {
      const ScriptTick& t = s.ticks[k];
      const std::uint64_t before = proxy.sweep_work().sweeps;
      const RenderOutput out = proxy.render(t.position, q, t.velocity, Eigen::Vector3d::Zero(), 1e-3);
      if (k > 1 && t.velocity.norm() == 0 && t.delta > 0 && s.ticks[k - 1].velocity.norm() == 0 &&
          s.ticks[k - 2].velocity.norm() == 0 && out.constraints >= 2) {
        ++held;
        costly += proxy.sweep_work().sweeps - before > std::uint64_t(per_tick);
      }
    }
  });
  EXPECT_GT(held, 10000);
  EXPECT_EQ(costly, 0);  // (without the rule: 5489 of 11976 held ticks take 6 sweeps)
}

}  // namespace
}  // namespace gshaptics
