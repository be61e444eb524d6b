// The 6-DoF fidelity cases (issue 36, item 4): the analytic contact of an ellipsoid on a plane
// and on an edge against answers worked out by hand here, and the wrench the proxy renders on a
// synthetic Gaussian plane and cube (played through the servo step) against those answers:
// torque direction within 5 degrees and magnitude within 10 %.

#include "gshaptics/fidelity/wrench_fidelity.h"

#include <gtest/gtest.h>

#include <cmath>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/fidelity/fidelity_run.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/force/renderer_spec.h"

namespace gshaptics {
namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Quaterniond about(const Eigen::Vector3d& axis, double deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * kPi / 180, axis));
}

WrenchCase on_plane(const CompoundTool& tool, const Eigen::Quaterniond& q) {
  WrenchCase c;
  c.name = "hand-made";
  c.tool = tool;
  c.orientation = q;
  c.feature = {ContactFeature::Kind::kPlane, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ()};
  c.touch = {0.01, -0.02, 0.5};
  c.touch.z() += analytic_contact(c, c.touch).lift;
  return c;
}

TEST(WrenchFidelity, ADiscTiltedOnAPlaneTouchesAtItsSupportPoint) {
  // An oblate disc (radius R, half-thickness c) tilted by theta about y rests at height
  // S = sqrt(R^2 sin^2 + c^2 cos^2) and touches sin cos (R^2 - c^2) / S beside its centre, toward +x.
  const double R = 0.02, c = 0.002, th = 30 * kPi / 180;
  const WrenchCase k = on_plane(parse_tool_spec("disc:0.02,0.004"), about(Eigen::Vector3d::UnitY(), 30));
  const double S = std::sqrt(R * R * std::sin(th) * std::sin(th) + c * c * std::cos(th) * std::cos(th));
  const double x = std::sin(th) * std::cos(th) * (R * R - c * c) / S;
  EXPECT_NEAR(k.touch.z(), S, 1e-12);
  const AnalyticContact a = analytic_contact(k, k.touch);
  EXPECT_NEAR(a.lift, 0, 1e-12);
  EXPECT_EQ(a.parts, 1);
  EXPECT_NEAR((a.point - k.touch - Eigen::Vector3d(x, 0, -S)).norm(), 0, 1e-12);
  EXPECT_NEAR((a.normal - Eigen::Vector3d::UnitZ()).norm(), 0, 1e-12);
  // 3 mm deeper: the lift says so, the contact point moves with the tool.
  const AnalyticContact d = analytic_contact(k, k.touch - Eigen::Vector3d(0, 0, 0.003));
  EXPECT_NEAR(d.lift, 0.003, 1e-12);
  EXPECT_NEAR((d.point - a.point).norm(), 0, 1e-12);
}

TEST(WrenchFidelity, AStylusLyingOnAPlaneRestsOnAllPartsAtTheMiddleOfItsLength) {
  const double L = 0.12, r = 0.005;
  const WrenchCase k = on_plane(parse_tool_spec("stylus:0.12,0.005"), about(Eigen::Vector3d::UnitY(), 90));
  EXPECT_NEAR(k.touch.z(), r, 1e-12);  // lying flat: its axis at the radius's height
  const AnalyticContact a = analytic_contact(k, k.touch);
  EXPECT_EQ(a.parts, 4);
  EXPECT_NEAR((a.point - (k.touch + Eigen::Vector3d(L / 2, 0, -r))).norm(), 0, 1e-12);
}

TEST(WrenchFidelity, AnEllipsoidOnAnEdgeTouchesWhereItsShortAxisMeetsTheEdge) {
  // A prolate part (R, R, C) at 30 degrees to the horizontal over the edge x = 0.1, z = 0.1 (along
  // y), placed so that the end of a short axis is on the edge: it touches there, with the
  // normal along that short axis, and lowering it by h makes the lift h.
  const double R = 0.005, C = 0.02, th = 30 * kPi / 180;
  WrenchCase k;
  k.tool = CompoundTool::single(Eigen::Vector3d(R, R, C));
  const Eigen::Vector3d axis(-std::cos(th), 0, std::sin(th)), side(std::sin(th), 0, std::cos(th));
  k.orientation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), axis);
  k.feature = {ContactFeature::Kind::kLine, Eigen::Vector3d(0.1, 0.03, 0.1), Eigen::Vector3d::UnitY()};
  const Eigen::Vector3d edge(0.1, 0.03, 0.1);
  k.touch = edge + side * R;
  const AnalyticContact a = analytic_contact(k, k.touch);
  EXPECT_NEAR(a.lift, 0, 1e-12);
  EXPECT_NEAR((a.point - edge).norm(), 0, 1e-12);
  EXPECT_NEAR((a.normal - side).norm(), 0, 1e-9);
  EXPECT_NEAR(analytic_contact(k, k.touch - Eigen::Vector3d(0, 0, 0.002)).lift, 0.002, 1e-12);
  // Brute force: lowered by the lift, the part's Mahalanobis distance to the line is 1.
  const Eigen::Vector3d at = k.touch - Eigen::Vector3d(0, 0, 0.002);
  const AnalyticContact b = analytic_contact(k, at);
  const Eigen::Vector3d centre = at + Eigen::Vector3d::UnitZ() * b.lift;
  const Eigen::Matrix3d rot = k.orientation.toRotationMatrix();
  const Eigen::Matrix3d A = rot * Eigen::Vector3d(1 / (R * R), 1 / (R * R), 1 / (C * C)).asDiagonal() * rot.transpose();
  double best = INFINITY;
  for (int i = -20000; i <= 20000; ++i) {
    const Eigen::Vector3d w = edge + Eigen::Vector3d::UnitY() * (i * 1e-6) - centre;
    best = std::min(best, w.dot(A * w));
  }
  EXPECT_NEAR(best, 1.0, 1e-6);
}

TEST(WrenchFidelity, CasesAreDrawnWithTheirToolsAndTouchTheirFeature) {
  const WrenchTools tools;
  const std::vector<WrenchCase> plane = wrench_cases(ShapeKind::kPlane, tools, 2, 7);
  ASSERT_EQ(plane.size(), 12u);
  const std::vector<WrenchCase> cube = wrench_cases(ShapeKind::kCube, tools, 3, 7);
  ASSERT_EQ(cube.size(), 3u);
  EXPECT_TRUE(wrench_cases(ShapeKind::kSphere, tools, 2, 7).empty());
  const AnalyticShape box(ShapeKind::kCube);
  for (const WrenchCase& c : cube) {
    const AnalyticContact a = analytic_contact(c, c.touch);
    EXPECT_NEAR(a.lift, 0, 1e-12);
    EXPECT_NEAR(box.signed_distance(a.point), 0, 1e-9);      // on the edge
    EXPECT_LT(box.normal_cone(a.point).angle_deg(a.normal), 1e-6);  // inside its normal cone
    // No part dips into the cube at the touch pose: its surface points along many directions are outside.
    std::array<ToolEllipsoid, kMaxToolParts> parts{};
    const int n = c.tool.posed(c.touch, c.orientation, parts);
    for (int j = 0; j < n; ++j)
      for (int s = 0; s < 400; ++s) {
        const double z = -1 + 2 * (s + 0.5) / 400, phi = s * 2.399963;
        const Eigen::Vector3d d(std::sqrt(1 - z * z) * std::cos(phi), std::sqrt(1 - z * z) * std::sin(phi), z);
        EXPECT_GT(box.signed_distance(parts[std::size_t(j)].surface_point(d)), -1e-9);
      }
  }
}

// One case played through the servo step with the proxy on a synthetic scene (4 mm spacing by
// default): the `site`-th of `sites` drawn with `seed`, on the scene `gshaptics fidelity --seed
// scene_seed` makes.
WrenchMetrics play(ShapeKind shape, const std::string& name, double spacing = 0.004, std::uint64_t seed = 3,
                   int sites = 1, int site = 0, std::uint64_t scene_seed = 1,
                   ProxySurface surface = ProxySurface::kEllipsoids, double edge_sigmas = 0) {
  SynthParams p;
  p.spacing = spacing;
  p.seed = scene_seed;
  p.edge_sigmas = edge_sigmas;
  const SyntheticScene sc = make_synthetic_scene(AnalyticShape(shape), p);
  ProxyParams params;
  params.surface = surface;
  const RendererSpec spec = renderer_spec_for(renderer_spec(RendererKind::kProxy, params), ProxyTool::kCompound);
  WorldConfig config;
  config.min_opacity = default_min_opacity(spec);
  const CollisionWorld world = CollisionWorld::build(sc.scene, config);
  int k = 0;
  for (const WrenchCase& c : wrench_cases(shape, WrenchTools{}, sites, seed)) {
    if (c.name != name || k++ != site) continue;
    const auto renderer = make_force_renderer(spec, world);
    const Script s = wrench_script(c, 0.005, 1000);
    const PlayOptions play = default_play_options();
    return wrench_metrics(c, s, play_script(*renderer, s, 1000, play), true, play.safety.tau_max);
  }
  ADD_FAILURE() << "no case " << name;
  return {};
}

double worst(const std::vector<double>& v) { return v.empty() ? NAN : *std::max_element(v.begin(), v.end()); }
double least(const std::vector<double>& v) { return v.empty() ? NAN : *std::min_element(v.begin(), v.end()); }

TEST(WrenchFidelity, TheProxyRendersTheAnalyticTorqueOfAStylusLyingOnAPlaneAndATiltedDisc) {
  for (const char* name : {"stylus side-on", "disc tilted 30 deg", "stylus tip-first 60 deg"}) {
    SCOPED_TRACE(name);
    const WrenchMetrics m = play(ShapeKind::kPlane, name);
    ASSERT_GT(m.torque_ratio.size(), 100u);
    EXPECT_LT(worst(m.torque_dir_deg), 5.0);
    EXPECT_GT(least(m.torque_ratio), 0.9);
    EXPECT_LT(worst(m.torque_ratio), 1.1);
    EXPECT_LT(worst(m.force_dir_deg), 5.0);
    EXPECT_TRUE(m.press.never_lost);
    EXPECT_LT(m.deepest_part_mm, 0.5);  // no part ends inside the surface (Gaussian-scale)
  }
  // Tip-first at 0 degrees: no lever, no torque.
  const WrenchMetrics tip = play(ShapeKind::kPlane, "stylus tip-first 0 deg");
  ASSERT_FALSE(tip.zero_lever_mm.empty());
  EXPECT_LT(worst(tip.zero_lever_mm), 1.0);
}

TEST(WrenchFidelity, AStylusAcrossACubeEdgeGetsTheTorqueOfItsLever) {
  const WrenchMetrics m = play(ShapeKind::kCube, "stylus across an edge");
  ASSERT_GT(m.torque_dir_deg.size(), 100u);
  EXPECT_NEAR(m.analytic_lever_mm, 11 * 120.0 / 18, 1.0);  // the third part's centre, 11 L / 18 from the tip
  std::vector<double> d = m.torque_dir_deg;
  std::nth_element(d.begin(), d.begin() + std::ptrdiff_t(d.size() * 95 / 100), d.end());
  EXPECT_LT(d[d.size() * 95 / 100], 5.0);  // the torque turns the right way (p95)
  // The force acts along the stylus's own normal where it rests on the edge (the support normal
  // of the edge's patch), not along a blend of the two faces' normals (the shaded field alone
  // was 20-50 degrees off here).
  std::vector<double> f = m.force_dir_deg;
  ASSERT_GT(f.size(), 100u);
  std::nth_element(f.begin(), f.begin() + std::ptrdiff_t(f.size() * 95 / 100), f.end());
  EXPECT_LT(f[f.size() * 95 / 100], 5.0);
  std::vector<double> r = m.torque_ratio;
  std::sort(r.begin(), r.end());
  EXPECT_GT(r[r.size() * 5 / 100], 0.9);
  EXPECT_LT(r[r.size() * 95 / 100], 1.1);
  EXPECT_TRUE(m.press.never_lost);
}

// On the seen solid, the stylus across the 8 mm cube's edge (fidelity --surface seen, the first
// of three sites): lifted off after the press, the force stays along the edge's normal. A contact
// that began as the tool left the top face and failed at once forgot which way the face lay; the
// next tick counted the shell the tool lifts off from and pulled it back (p95 159 degrees).
TEST(WrenchFidelity, OnTheSeenSolidAStylusLiftedOffACoarseCubeEdgeIsNotPulledBack) {
  const WrenchMetrics m = play(ShapeKind::kCube, "stylus across an edge", 0.008, 1, 3, 0, 1, ProxySurface::kSeen);
  std::vector<double> f = m.force_dir_deg;
  ASSERT_GT(f.size(), 100u);
  std::nth_element(f.begin(), f.begin() + std::ptrdiff_t(f.size() * 95 / 100), f.end());
  EXPECT_LT(f[f.size() * 95 / 100], 15.0);
}

// The stylus across the cube's edge on the seen solid at fidelity seeds 3 (2 mm) and 4 (4 mm),
// every site: where the edge search's source line itself rests on the edge, no line between
// meets the surface; that search found no edge point, the part was held on the line's own normal
// and the force leaned along the edge, 30 degrees off (p95) on one site of each. The line is the
// edge point; the direction the two searches give still errs (up to 13 degrees at p95 over these
// sites against the 5-degree target: bench/RESULTS.md, ninety-sixth session).
TEST(WrenchFidelity, OnTheSeenSolidAStylusRestingWithAFootprintLineOnTheEdgeIsHeldByTheEdge) {
  for (const auto& [spacing, seed] : {std::pair{0.002, std::uint64_t{3}}, std::pair{0.004, std::uint64_t{4}}})
    for (int site = 0; site < 3; ++site) {
      SCOPED_TRACE(testing::Message() << "spacing " << spacing << ", seed " << seed << ", site " << site);
      const WrenchMetrics m = play(ShapeKind::kCube, "stylus across an edge", spacing, seed, 3, site, seed, ProxySurface::kSeen);
      std::vector<double> f = m.force_dir_deg;
      ASSERT_GT(f.size(), 100u);
      std::nth_element(f.begin(), f.begin() + std::ptrdiff_t(f.size() * 95 / 100), f.end());
      EXPECT_LT(f[f.size() * 95 / 100], 15.0);  // (7.2 at 4 mm, site 2; 12.7 before the edge held its points)
      EXPECT_TRUE(m.press.never_lost);
    }
}

// The stylus across the cube's edge on the seen solid where the edge is ragged at the Gaussians'
// scale (fidelity --surface seen, these spacings, seeds and sites). A footprint line on a disc
// standing a fraction of a millimetre proud of the edge held the part on its own normal, a few
// millimetres beside the tangent point: 30 degrees along the edge for the whole press (2 mm, seed
// 6); and where the second edge search found no line to start from, the edge was dropped and the
// part fell back on a line's normal for the first 50 ms (2 mm, seed 7; seed 4 also lost the
// contact). The line on the edge now rests the part at its tangent point, and the edge keeps its
// point while the part lies over it.
TEST(WrenchFidelity, OnTheSeenSolidAStylusOnARaggedEdgeIsHeldAtItsTangentPoint) {
  struct Site {
    double spacing;
    std::uint64_t seed;
    int site;
  };
  for (const Site& s : {Site{0.002, 6, 1}, Site{0.002, 7, 2}, Site{0.002, 4, 1}, Site{0.002, 13, 0}, Site{0.004, 14, 2}}) {
    SCOPED_TRACE(testing::Message() << "spacing " << s.spacing << ", seed " << s.seed << ", site " << s.site);
    const WrenchMetrics m = play(ShapeKind::kCube, "stylus across an edge", s.spacing, s.seed, 3, s.site, s.seed, ProxySurface::kSeen);
    std::vector<double> f = m.force_dir_deg;
    ASSERT_GT(f.size(), 100u);
    std::nth_element(f.begin(), f.begin() + std::ptrdiff_t(f.size() * 95 / 100), f.end());
    EXPECT_LT(f[f.size() * 95 / 100], 10.0);  // (24.6-30.3 before)
    EXPECT_TRUE(m.press.never_lost);
  }
}

// The stylus across the crisp-edged 2 mm cube (fidelity --shape cube --edge-sigmas 1.17 --defect
// none --seed S): where a proud rim patch lies under a part's middle, two roaming inner lines met
// it a fraction of a millimetre apart, and the part was held by whichever slot came first within
// the band of the nearest. The hold jumped to the other line 1.2 mm off the stylus's plane
// mid-press: the proxy sank 0.16 mm, the force leaned 14 degrees along the edge (p95, seed 1) and
// the unload gave back more than the press took (W -0.013 mJ). The part stays on the nearest
// inner line, and on the line that holds it while that one is as near within kInnerKeep (the
// nearest alone, re-read lines traded places: 5.8 degrees at seed 6).
TEST(WrenchFidelity, OnTheSeenSolidAStylusOnACrispEdgesProudPatchKeepsOneInnerLine) {
  for (const std::uint64_t seed : {std::uint64_t{1}, std::uint64_t{2}, std::uint64_t{6}, std::uint64_t{12}})
    for (int site = 0; site < 3; ++site) {
      SCOPED_TRACE(testing::Message() << "seed " << seed << ", site " << site);
      const WrenchMetrics m = play(ShapeKind::kCube, "stylus across an edge", 0.002, seed, 3, site, seed,
                                   ProxySurface::kSeen, SynthParams::kCrispEdgeSigmas);
      std::vector<double> f = m.force_dir_deg;
      ASSERT_GT(f.size(), 100u);
      std::nth_element(f.begin(), f.begin() + std::ptrdiff_t(f.size() * 95 / 100), f.end());
      EXPECT_LT(f[f.size() * 95 / 100], 5.0);
      EXPECT_TRUE(m.press.never_lost);
      EXPECT_GE(m.press.energy_j, 0.0);  // (W, the closed cycle)
    }
}

// The stylus across the crisp-edged 8 mm cube at seeds 7 and 11 (fidelity --shape cube
// --edge-sigmas 1.17 --defect none --seed S): a ring line on the rim's top held the third part
// from the first tick to the last, 2.5 mm along the edge from the part's plane of symmetry, and
// the force leaned asin(2.5 / 5) = 30 degrees (p95 30.3). The edge searches ended down the rim's
// shoulder, so the edge's fit lay 0.125 smallest semi-axes under the line: past kEdgeSnap, the
// part was not moved onto its tangent point. A line up to kRimTop above the fit is the rim's top.
TEST(WrenchFidelity, OnTheSeenSolidAStylusOnACrispRimsTopIsHeldAtItsTangentPoint) {
  for (const std::uint64_t seed : {std::uint64_t{7}, std::uint64_t{11}}) {
    SCOPED_TRACE(testing::Message() << "seed " << seed);
    std::vector<double> f;
    for (int site = 0; site < 3; ++site) {
      const WrenchMetrics m = play(ShapeKind::kCube, "stylus across an edge", 0.008, seed, 3, site, seed,
                                   ProxySurface::kSeen, SynthParams::kCrispEdgeSigmas);
      EXPECT_TRUE(m.press.never_lost);
      EXPECT_GE(m.press.energy_j, 0.0);
      f.insert(f.end(), m.force_dir_deg.begin(), m.force_dir_deg.end());
    }
    ASSERT_GT(f.size(), 300u);
    std::nth_element(f.begin(), f.begin() + std::ptrdiff_t(f.size() * 95 / 100), f.end());
    EXPECT_LT(f[f.size() * 95 / 100], 5.0);  // (30.3 before)
  }
}

// Seed 27's third stylus across the 8 mm cube's edge (fidelity --seed 27): the stylus first
// rests on a side-face disc standing proud of the top face, and the part beside the one resting
// there comes within the contact band of the same disc, at a point inside its neighbour. It
// carries no load (CompoundProxy: a hidden contact); with its share the torque read 0.69 of
// the lever's until the press pushed it out of the band.
TEST(WrenchFidelity, AStylusPartBesideTheLipItsNeighbourRestsOnDoesNotShortenTheLever) {
  const WrenchMetrics m = play(ShapeKind::kCube, "stylus across an edge", 0.008, 27, 3, 2, 27);
  ASSERT_GT(m.torque_ratio.size(), 100u);
  std::vector<double> r = m.torque_ratio;
  std::sort(r.begin(), r.end());
  EXPECT_GT(r[r.size() * 5 / 100], 0.9);
  EXPECT_LT(r[r.size() * 95 / 100], 1.1);
  EXPECT_TRUE(m.press.never_lost);
}

// The hand gets at most the safety layer's torque limit: a trace whose torque is the analytic one
// clipped to 0.5 N m scores a magnitude ratio of 1 against the clipped answer, and the plain
// answer would call it low (8 N across the cube's edge at a 73 mm lever asks 0.59 N m).
TEST(WrenchFidelity, TheTorqueMagnitudeIsJudgedAgainstTheAnalyticTorqueClippedToTheLimit) {
  const std::vector<WrenchCase> cases = wrench_cases(ShapeKind::kCube, WrenchTools{}, 1, 3);
  const auto it = std::find_if(cases.begin(), cases.end(), [](const WrenchCase& c) { return c.name == "stylus across an edge"; });
  ASSERT_NE(it, cases.end());
  const WrenchCase& c = *it;
  const Script s = wrench_script(c, 0.005, 1000);
  const double limit = 0.5, force = 8.0;
  ScriptTrace tr;
  for (const ScriptTick& t : s.ticks) {
    const AnalyticContact a = analytic_contact(c, t.position);
    const Eigen::Vector3d resting = t.position + c.up * a.lift;
    const Eigen::Vector3d expected = (a.point - resting).cross(force * a.normal);
    tr.force.push_back(force * a.normal);
    tr.torque.push_back(expected.norm() > limit ? Eigen::Vector3d(expected.normalized() * limit) : expected);
    tr.proxy.push_back(t.position);
    tr.render_us.push_back(0);
    tr.contacts.push_back(1);
  }
  const WrenchMetrics clipped = wrench_metrics(c, s, tr, false, limit);
  ASSERT_GT(clipped.torque_ratio.size(), 100u);
  EXPECT_NEAR(least(clipped.torque_ratio), 1.0, 1e-9);
  EXPECT_NEAR(worst(clipped.torque_ratio), 1.0, 1e-9);
  EXPECT_LT(worst(clipped.torque_dir_deg), 1e-6);
  const WrenchMetrics plain = wrench_metrics(c, s, tr, false);
  EXPECT_LT(least(plain.torque_ratio), 0.9);  // (the case does ask more than the limit)
}

}  // namespace
}  // namespace gshaptics
