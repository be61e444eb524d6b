// The compound proxy (issue 36, item 2, first version): no part of the proxy ever ends inside the
// Gaussians, a turn that would swing a stylus through a thin plate stops at the contact, the
// wrench of a symmetric press has no torque and mirrored presses mirror it, the lever arm of an
// off-centre contact, the rotational coupling, a stylus across an edge pushed along its own
// normal there, friction (sticking inside the cone, mu_k times the normal force sliding, its
// moment in the torque), a resting part settled by the probe's hint, and ticks that allocate nothing.

#include "gshaptics/force/compound_proxy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gshaptics/error.h"
#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/force/shaded_normal.h"
#include "support/allocation_counter.h"
#include "support/ellipsoid_params.h"
#include "support/gaussian_worlds.h"

namespace gshaptics {
namespace {

using test::add_layer;
using test::GaussianSpec;
using test::world_of;

// A plate of flat discs at z = 0 (spacing 4 mm, 0.2 mm thick) over [-0.2, 0.2]^2.
const CollisionWorld& plate() {
  static const CollisionWorld w = [] {
    std::vector<GaussianSpec> gs;
    add_layer(gs, 0.0f, 0.004f, 0.2f);
    return world_of(gs);
  }();
  return w;
}

CompoundTool dumbbell() {  // two 1 cm spheres 3 cm either side of the TCP on the tool's x axis
  CompoundTool t;
  t.count = 2;
  t.parts[0].offset = {-0.03, 0, 0};
  t.parts[1].offset = {0.03, 0, 0};
  t.parts[0].semi_axes = t.parts[1].semi_axes = Eigen::Vector3d::Constant(0.01);
  return t;
}

Eigen::Quaterniond about_y(double deg) { return Eigen::Quaterniond(Eigen::AngleAxisd(deg * M_PI / 180, Eigen::Vector3d::UnitY())); }

TEST(CompoundProxy, PressedIntoAPlateNoPartEndsInsideAndTheWrenchIsRight) {
  CompoundProxy proxy(plate(), dumbbell());
  const Eigen::Vector3d v(0, 0, -0.02);
  // Level, lowered from 3 cm above to 1 cm below the plate: the proxy stays on it.
  RenderOutput out;
  for (int k = 0; k <= 40; ++k) {
    const Eigen::Vector3d x(0.001, 0.0007, 0.03 - 0.001 * k);
    out = proxy.render(x, Eigen::Quaterniond::Identity(), v, Eigen::Vector3d::Zero(), 1e-3);
    ASSERT_FALSE(proxy.blocked(proxy.position(), proxy.orientation())) << "tick " << k;
  }
  // The spheres rest on the discs (0.2 mm thick, so their tops at 0.1 mm): the TCP about 1 cm up.
  EXPECT_NEAR(proxy.position().z(), 0.0101, 0.0003);
  EXPECT_GT(out.force.z(), 0.0);
  EXPECT_NEAR(out.force.norm(), 1000.0 * (proxy.position().z() + 0.010) + 1.0 * 0.02, 0.4);
  // Symmetric: both spheres hold it, the contact moments cancel.
  EXPECT_LT(out.torque.norm(), 0.02 * out.force.norm() * 0.03) << out.torque.transpose();

  // Tilted +-20 deg about y and pressed: one sphere holds; the torques mirror, and the lever
  // arm is the contact point's horizontal distance from the TCP (0.03 cos 20 deg).
  RenderOutput tilt[2];
  for (int side = 0; side < 2; ++side) {
    CompoundProxy p(plate(), dumbbell());
    const Eigen::Quaterniond q = about_y(side == 0 ? 20 : -20);
    for (int k = 0; k <= 40; ++k)
      tilt[side] = p.render({0.001, 0.0007, 0.04 - 0.001 * k}, q, v, Eigen::Vector3d::Zero(), 1e-3);
    ASSERT_FALSE(p.blocked(p.position(), p.orientation()));
    ASSERT_GT(tilt[side].force.z(), 0.0);
  }
  EXPECT_NEAR(tilt[0].torque.y(), -tilt[1].torque.y(), 0.05 * std::abs(tilt[0].torque.y()));
  EXPECT_LT(tilt[0].torque.y(), 0.0);  // +20 deg lowers the +x sphere: (+x) x (+z) = -y
  const double lever = std::abs(tilt[0].torque.y()) / tilt[0].force.norm();
  EXPECT_NEAR(lever, 0.03 * std::cos(20 * M_PI / 180), 0.1 * 0.03);
}

// Two plates of flat discs side by side, x < -5 mm at z = 0 and x > 5 mm at z = `step`.
CollisionWorld stepped_plates(float step) {
  std::vector<GaussianSpec> gs;
  const float h = 0.004f;
  for (float x = -0.06f; x <= 0.06f; x += h)
    for (float y = -0.04f; y <= 0.04f; y += h)
      if (std::abs(x) > 0.005f)
        gs.emplace_back(Eigen::Vector3f(x, y, x > 0 ? step : 0.0f), Eigen::Vector3f(h, h, 0.05f * h),
                        Eigen::Quaternionf::Identity());
  return world_of(gs);
}

TEST(CompoundProxy, APartAJitterAboveTheSurfaceStillCarriesItsShare) {
  // The dumbbell pressed level onto two plates whose heights differ: the proxy rests on the
  // higher (+x) one and the other sphere hangs `step` above its plate. Its weight is
  // 1 - (gap / band)^2, band half the spheres' 1 cm radius, so the resultant acts at
  // x_c = 0.03 (1 - w) / (1 + w) and the lever is |tau_y| / |F| = x_c. A 1 mm step (a fifth of the
  // band, the Gaussians' jitter) moves it 0.6 mm (the linear 1 - gap / band: 3.3 mm); a step past
  // the band leaves the +x sphere alone (30 mm).
  const auto lever_on = [](float step) {
    const CollisionWorld w = stepped_plates(step);
    CompoundProxy proxy(w, dumbbell());
    RenderOutput out;
    for (int k = 0; k <= 45; ++k)
      out = proxy.render({0.0, 0.0007, 0.035 - 0.001 * k}, Eigen::Quaterniond::Identity(), {0, 0, -0.02},
                         Eigen::Vector3d::Zero(), 1e-3);
    EXPECT_FALSE(proxy.blocked(proxy.position(), proxy.orientation()));
    EXPECT_GT(out.force.z(), 5.0);
    EXPECT_LT(out.torque.y(), 0.0) << "the +x sphere carries more: (+x) x (+z) = -y";
    return std::abs(out.torque.y()) / out.force.norm();
  };
  const double t = 0.001 / 0.005, w = 1 - t * t;  // (the gap to within a stand-off, 10 um)
  EXPECT_NEAR(lever_on(0.001f), 0.03 * (1 - w) / (1 + w), 2e-4);
  EXPECT_LT(lever_on(0.001f), 0.001);
  EXPECT_NEAR(lever_on(0.007f), 0.03, 5e-4);
}

TEST(CompoundProxy, APartSmallerThanTheSpacingReReadsTheFieldAtTheSpacingsScale) {
  // Two 2 mm spheres 3 cm apart slid 4 mm along a plate of 8 mm discs, pressed 1 mm: each part's
  // shaded normal is read at the spacing's scale (its kernel is 0.5 x that), so it is kept over
  // shading_reuse x the spacing, not x the part's 2 mm (which read 4x as often).
  std::vector<GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.008f, 0.1f);
  const CollisionWorld w = world_of(gs);
  CompoundTool tool;
  tool.count = 2;
  tool.parts[0].offset = {-0.015, 0, 0};
  tool.parts[1].offset = {0.015, 0, 0};
  tool.parts[0].semi_axes = tool.parts[1].semi_axes = Eigen::Vector3d::Constant(0.002);
  CompoundProxy proxy(w, tool);
  const Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  for (int k = 0; k <= 40; ++k)
    proxy.render({0.001, 0.0013, 0.01 - 0.0003 * k}, q, {0, 0, -0.3}, Eigen::Vector3d::Zero(), 1e-3);
  const double z = proxy.position().z() - 0.001;
  ASSERT_GT(proxy.blockers().size(), 0u);
  const double spacing = shading_spacing(w, proxy.blockers());
  ASSERT_GT(spacing, 0.004);
  const std::uint64_t before = proxy.shading_reads();
  const double slide = 0.004;
  RenderOutput out;
  for (int k = 1; k <= 400; ++k)
    out = proxy.render({0.001 + slide * k / 400, 0.0013, z}, q, {0.01, 0, 0}, Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_GT(out.force.z(), 0.5);
  const double reads = double(proxy.shading_reads() - before);
  const ProxyParams params = test::ellipsoid_params();
  const double at_spacing = 2 * slide / (params.shading_reuse * spacing);  // both parts
  EXPECT_GE(reads, 0.5 * at_spacing);
  EXPECT_LE(reads, 1.5 * at_spacing + 4);
  EXPECT_LT(reads, 0.5 * 2 * slide / (params.shading_reuse * 0.002));
}

TEST(CompoundProxy, OnAFlatFaceThePartsNormalIsAveragedWithTheDiscsMeanAxis) {
  // Discs 2 mm apart on z = 0, each tilted by a random 3 degrees (the fidelity scenes' jitter).
  // The shaded field averages the tilts of the few discs its kernel weighs near the reading
  // point; the face's mean thin axis (EdgeNormal's patch: every disc within a band of the part)
  // averages tens of them. A stylus pressed tip-first at 60 degrees at 16 sites, with the face
  // average and without it: the force tilts off z less with it, on the whole and nearly
  // everywhere.
  std::vector<GaussianSpec> gs;
  std::mt19937 rng(11);
  std::normal_distribution<float> tilt(0.0f, 3.0f * float(M_PI) / 180);
  for (float x = -0.07f; x <= 0.07f; x += 0.002f)
    for (float y = -0.07f; y <= 0.07f; y += 0.002f) {
      const Eigen::Vector3f axis = Eigen::Vector3f(tilt(rng), tilt(rng), 1.0f).normalized();
      gs.emplace_back(Eigen::Vector3f(x, y, 0), Eigen::Vector3f(0.0012f, 0.0012f, 0.00005f),
                      Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), axis));
    }
  const CollisionWorld w = world_of(gs);
  const CompoundTool stylus = parse_tool_spec("stylus:0.12,0.005");
  const Eigen::Quaterniond q(Eigen::AngleAxisd(60 * M_PI / 180, Eigen::Vector3d::UnitY()));
  const auto tilt_off_z = [&](const Eigen::Vector3d& at, bool average) {
    ProxyParams params = test::ellipsoid_params();
    params.face_average = average;
    CompoundProxy proxy(w, stylus, params);
    RenderOutput out;
    for (int k = 0; k <= 30; ++k)
      out = proxy.render(at + Eigen::Vector3d(0, 0, 0.012 - 0.0005 * k), q, {0, 0, -0.5}, Eigen::Vector3d::Zero(),
                         1e-3);
    EXPECT_GT(out.force.z(), 1.0);
    return std::atan2(out.force.head<2>().norm(), out.force.z()) * 180 / M_PI;
  };
  double sum_on = 0, sum_off = 0;
  int better = 0;
  for (int site = 0; site < 16; ++site) {
    const Eigen::Vector3d at(-0.03 + 0.0041 * site, 0.0027 * site - 0.02, 0);
    const double on = tilt_off_z(at, true), off = tilt_off_z(at, false);
    sum_on += on;
    sum_off += off;
    better += on <= off + 0.1 ? 1 : 0;
  }
  EXPECT_LT(sum_on, 0.8 * sum_off);
  EXPECT_GE(better, 13);
}

TEST(CompoundProxy, ASlideUnderHalfTheStandOffIsNotSwept) {
  // The dumbbell resting level on the plate, each sphere over a disc's centre, then the device
  // moved aside: by 0.3 stand-offs (1e-3 of the smallest semi-axis) the slide along the contact
  // plane is left out and the proxy holds; by 3 it slides with the device.
  const double eps = ProxySolver::kStandOff * 0.01;
  for (const double aside : {0.3 * eps, 3.0 * eps}) {
    CompoundProxy proxy(plate(), dumbbell());
    const Eigen::Vector3d v(0, 0, -0.02);
    for (int k = 0; k <= 40; ++k)
      (void)proxy.render({0.002, 0.0, 0.03 - 0.001 * k}, Eigen::Quaterniond::Identity(), v, Eigen::Vector3d::Zero(), 1e-3);
    const Eigen::Vector3d rest = proxy.position();
    ASSERT_NEAR(rest.z(), 0.0101, 0.0003);
    ASSERT_NEAR(rest.x(), 0.002, 1e-9) << "the discs under the spheres are level";
    (void)proxy.render({0.002 + aside, 0.0, -0.01}, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(),
                       Eigen::Vector3d::Zero(), 1e-3);
    SCOPED_TRACE(aside / eps);
    if (aside < 0.5 * eps) {
      EXPECT_LT((proxy.position() - rest).norm(), 1e-3 * eps);
    } else {
      EXPECT_NEAR(proxy.position().x(), rest.x() + aside, 0.1 * eps);
      EXPECT_NEAR(proxy.position().z(), rest.z(), 0.1 * eps);
    }
  }
}

TEST(CompoundProxy, TheProbeTakesAPartRestingAStandOffFromItsBlockerAsSettled) {
  // The dumbbell pressed level onto the plate and held there with friction: the proxy sticks,
  // so the tick's only sweep is the contact probe. Each sphere rests a stand-off from the disc
  // that stopped it; the probe knows a part's gap to two stand-offs (kProbeTolerance), so that
  // disc, tested first as a hint, settles the part and no other candidate is read. (To half a
  // stand-off, as the translation's sweeps search, both parts read their near lists.)
  ProxyParams params = test::ellipsoid_params();
  params.mu_s = 0.5;
  params.mu_k = 0.4;
  CompoundProxy proxy(plate(), dumbbell(), params);
  const Eigen::Vector3d v(0, 0, -0.02);
  RenderOutput out;
  for (int k = 0; k <= 40; ++k)
    out = proxy.render({0.001, 0.0007, 0.03 - 0.001 * k}, Eigen::Quaterniond::Identity(), v, Eigen::Vector3d::Zero(),
                       1e-3);
  ASSERT_NEAR(proxy.position().z(), 0.0101, 0.0003);
  const Eigen::Vector3d held = proxy.position();
  const CompoundProxy::SweepWork before = proxy.sweep_work();
  out = proxy.render({0.001, 0.0007, -0.01}, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(),
                     Eigen::Vector3d::Zero(), 1e-3);
  const CompoundProxy::SweepWork& after = proxy.sweep_work();
  EXPECT_EQ((proxy.position() - held).norm(), 0.0) << "friction holds it";
  EXPECT_EQ(after.sweeps - before.sweeps, 1u) << "the probe alone";
  EXPECT_EQ(after.candidates - before.candidates, 0u);
  // Both spheres still hold it with their full weight: no torque, the whole spring along z.
  EXPECT_LT(out.torque.norm(), 0.02 * out.force.norm() * 0.03) << out.torque.transpose();
  EXPECT_NEAR(out.force.z(), 1000.0 * (held.z() + 0.010), 0.05);
}

TEST(CompoundProxy, ATurnThatWouldSwingAStylusThroughAThinPlateStopsAtTheContact) {
  // A 10 cm stylus upright, its tip (the TCP) 2 cm above the plate, turned 120 deg about y in
  // one tick: its far end would sweep through the plate (it crosses z = 0 at about 100 deg).
  const CompoundTool stylus = parse_tool_spec("stylus:0.1,0.006");
  CompoundProxy proxy(plate(), stylus);
  const Eigen::Vector3d x(0.0, 0.0, 0.02);
  proxy.render(x, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
  const RenderOutput out = proxy.render(x, about_y(120), Eigen::Vector3d::Zero(), {0, 2094.0, 0}, 1e-3);
  EXPECT_FALSE(proxy.blocked(proxy.position(), proxy.orientation()));
  // It stopped short of the plate: every part above it, the turn between 60 and 100 deg.
  std::array<ToolEllipsoid, kMaxToolParts> parts;
  const int n = stylus.posed(proxy.position(), proxy.orientation(), parts);
  for (int j = 0; j < n; ++j) EXPECT_GT(parts[std::size_t(j)].center.z(), 0.0) << "part " << j;
  const double turned = Eigen::AngleAxisd(proxy.orientation()).angle() * 180 / M_PI;
  EXPECT_GT(turned, 60.0);
  EXPECT_LT(turned, 100.0);
  // The rotational coupling pulls the device back toward the proxy: about -y, k_r x the gap
  // minus b_r x omega.
  const double gap = (120 - turned) * M_PI / 180;
  EXPECT_NEAR(out.torque.y(), -(1.0 * gap) - 0.001 * 2094.0, 0.05);
  // Without the plate the same turn goes all the way.
  const CollisionWorld empty = world_of({{Eigen::Vector3f(5, 5, 5), Eigen::Vector3f::Constant(0.001f), Eigen::Quaternionf::Identity()}});
  CompoundProxy free_proxy(empty, stylus, [] { ProxyParams p = test::ellipsoid_params(); p.pass_isolated = false; return p; }());
  free_proxy.render(x, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
  const RenderOutput free_out = free_proxy.render(x, about_y(120), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_NEAR(Eigen::AngleAxisd(free_proxy.orientation()).angle() * 180 / M_PI, 120.0, 1e-6);
  EXPECT_EQ(free_out.torque, Eigen::Vector3d::Zero());
  EXPECT_EQ(free_out.force, Eigen::Vector3d::Zero());
  // A turn larger than a tick's sub-rotations catches up over ticks, with no torque in free space.
  ProxyParams few = test::ellipsoid_params();
  few.pass_isolated = false;
  few.max_rotation_steps = 2;
  CompoundProxy slow(empty, stylus, few);
  slow.render(x, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
  const RenderOutput partial = slow.render(x, about_y(120), Eigen::Vector3d::Zero(), {0, 5, 0}, 1e-3);
  EXPECT_GT(Eigen::AngleAxisd(slow.orientation()).angle(), 0.0);
  EXPECT_LT(Eigen::AngleAxisd(slow.orientation()).angle() * 180 / M_PI, 120.0 - 1.0);
  EXPECT_EQ(partial.torque, Eigen::Vector3d::Zero());
}

// A block's edge along y: discs on the top face (z = 0, x < 0) and on the side face (x = 0, z < 0),
// 4 mm apart, 2.4 mm wide, 0.2 mm thick.
const CollisionWorld& block_edge() {
  static const CollisionWorld w = [] {
    std::vector<GaussianSpec> gs;
    const Eigen::Quaternionf side(Eigen::AngleAxisf(float(M_PI / 2), Eigen::Vector3f::UnitY()));
    for (float y = -0.06f; y <= 0.06f; y += 0.004f)
      for (float d = 0.002f; d <= 0.1f; d += 0.004f) {
        gs.emplace_back(Eigen::Vector3f(-d, y, 0), Eigen::Vector3f(0.0024f, 0.0024f, 0.0001f), Eigen::Quaternionf::Identity());
        gs.emplace_back(Eigen::Vector3f(0, y, -d), Eigen::Vector3f(0.0024f, 0.0024f, 0.0001f), side);
      }
    return world_of(gs);
  }();
  return w;
}

TEST(CompoundProxy, AStylusPressedAcrossAnEdgeIsPushedAlongItsOwnNormalThereWithoutAllocating) {
  // The stylus (tip at the TCP, along the tool's +z) descends across the edge at 30 deg; its
  // third part's centre (11 L / 18 from the tip) rests on the edge. A cylinder on a line is
  // pushed perpendicular to both: n = (sin 30, 0, cos 30), not a blend of the faces' normals.
  const CompoundTool stylus = parse_tool_spec("stylus:0.12,0.005");
  const double tilt = 30 * M_PI / 180, s = 11 * 0.12 / 18;
  const Eigen::Vector3d axis(-std::cos(tilt), 0, std::sin(tilt)), n(std::sin(tilt), 0, std::cos(tilt));
  const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), axis);
  const Eigen::Vector3d touch = n * 0.005 - s * axis + Eigen::Vector3d(0, 0.0013, 0);
  CompoundProxy proxy(block_edge(), stylus);
  const auto tick = [&](double depth) { return proxy.render(touch - depth * n, q, -0.02 * n, Eigen::Vector3d::Zero(), 1e-3); };
  for (int k = 0; k < 100; ++k) (void)tick(-0.003 + 0.00005 * k);  // from 3 mm off to 2 mm in
  const std::size_t before = test::allocation_count();
  RenderOutput out;
  double worst = 0;
  for (int k = 100; k < 160; ++k) {
    out = tick(-0.003 + 0.00005 * k);  // on to 5 mm in
    ASSERT_GT(out.force.norm(), 0.5) << k;
    worst = std::max(worst, std::atan2(out.force.cross(n).norm(), out.force.dot(n)) * 180 / M_PI);
  }
  EXPECT_EQ(test::allocation_count() - before, 0u);
  EXPECT_LT(worst, 5.0);
  // Its moment about the TCP turns the way the lever says: (s axis) x n, within 5 deg.
  const Eigen::Vector3d lever = (s * axis).cross(n);
  EXPECT_LT(std::atan2(out.torque.cross(lever).norm(), out.torque.dot(lever)) * 180 / M_PI, 5.0);
}

// Two overlapping rods lowered level onto a plate of discs that ends under their overlap: rod A
// (x in [-10, 30] mm) lies on it, and rod B (x in [-40, 0] mm) hangs past its edge (x = -4
// mm), within the contact band of the last discs (2 mm above them, where A's underside is 3.6
// mm below the axis and B's 3.0): its first contact there lies inside A, whose surface is the
// union's there. B carries no load, so the resultant acts under A's middle, as for A alone on
// the plate; B's share (its support point along the plate's normal: its own middle, x = -20 mm)
// pulled it 6 mm toward B (the stylus across the 8 mm fidelity cube's edge: torque 0.69 of the
// lever's).
TEST(CompoundProxy, APartWhoseContactLiesInsideAnotherPartCarriesNoLoad) {
  CompoundTool rods;
  rods.count = 2;
  rods.parts[0].offset = {0.010, 0, 0};
  rods.parts[1].offset = {-0.020, 0, 0};
  rods.parts[0].semi_axes = rods.parts[1].semi_axes = {0.020, 0.005, 0.005};
  std::vector<GaussianSpec> gs;
  for (int i = 0; i <= 8; ++i)
    for (int k = -3; k <= 3; ++k)
      gs.emplace_back(Eigen::Vector3f(0.004f * float(i), 0.004f * float(k), 0.0f), Eigen::Vector3f(0.004f, 0.004f, 0.0002f),
                      Eigen::Quaternionf::Identity());
  const CollisionWorld world = world_of(gs);
  CompoundProxy proxy(world, rods);
  RenderOutput out;
  const Eigen::Quaterniond level = Eigen::Quaterniond::Identity();
  for (int k = 0; k <= 60; ++k)  // from 3 mm above the touch to 3 mm below it, 10 cm/s
    out = proxy.render({0, 0, 0.0052 - 0.0001 * k}, level, {0, 0, -0.1}, Eigen::Vector3d::Zero(), 1e-3);
  ASSERT_GT(out.force.norm(), 1.0);
  ASSERT_FALSE(proxy.blocked(proxy.position(), proxy.orientation()));
  // The line of action's offset from the TCP, F x tau / |F|^2, is A's middle's: 10 mm along x.
  const Eigen::Vector3d lever = out.force.cross(out.torque) / out.force.squaredNorm();
  EXPECT_NEAR(lever.x(), 0.010, 0.001) << lever.transpose();
}

// Pressed 2 mm into the plate, then drawn sideways: with friction the proxy sticks while the
// device stays inside the cone (the spring's tangential part k x offset), then slides with mu_k
// times the normal force against the motion; the friction acts at the contacts, 1 cm below the
// TCP, so its moment is in the torque. Without friction the sideways force is only the shell's
// noise.
struct Drag {
  double stuck_proxy_shift = 0, stuck_force_y = 0, stuck_force_z = 0;
  double slid_proxy_shift = 0, slid_force_y = 0, slid_force_z = 0, slid_torque_x = 0;
  bool ever_inside = false;
};
Drag drag(double mu_s, double mu_k) {
  ProxyParams p = test::ellipsoid_params();
  p.mu_s = mu_s;
  p.mu_k = mu_k;
  CompoundProxy proxy(plate(), dumbbell(), p);
  const double z_press = 0.0101 - 0.002;
  Drag d;
  RenderOutput out;
  const Eigen::Quaterniond level = Eigen::Quaterniond::Identity();
  for (int k = 0; k <= 30; ++k) {  // down from 3 cm, then held
    const double z = std::max(z_press, 0.03 - 0.001 * k);
    out = proxy.render({0.001, 0.0, z}, level, {0, 0, z > z_press ? -1.0 : 0.0}, Eigen::Vector3d::Zero(), 1e-3);
  }
  for (int k = 0; k < 20; ++k) out = proxy.render({0.001, 0.0, z_press}, level, {}, Eigen::Vector3d::Zero(), 1e-3);
  const double y0 = proxy.position().y();
  double y = 0;
  const Eigen::Vector3d v(0, 0.01, 0);  // 10 mm/s sideways
  const auto slide = [&](int ticks) {   // 10 um a tick
    for (int k = 0; k < ticks; ++k) {
      y += 1e-5;
      out = proxy.render({0.001, y, z_press}, level, v, Eigen::Vector3d::Zero(), 1e-3);
      d.ever_inside = d.ever_inside || proxy.blocked(proxy.position(), proxy.orientation());
    }
  };
  slide(50);  // 0.5 mm: inside the cone of mu_s = 0.5 at 2 mm depth
  d.stuck_proxy_shift = proxy.position().y() - y0;
  d.stuck_force_y = out.force.y();
  d.stuck_force_z = out.force.z();
  slide(450);  // on to 5 mm: out of the cone, sliding
  d.slid_proxy_shift = proxy.position().y() - y0;
  d.slid_force_y = out.force.y();
  d.slid_force_z = out.force.z();
  d.slid_torque_x = out.torque.x();
  return d;
}

TEST(CompoundProxy, FrictionSticksInsideTheConeSlidesWithMuKAndItsMomentIsInTheTorque) {
  const Drag f = drag(0.5, 0.3);
  EXPECT_FALSE(f.ever_inside);
  // Sticking: the proxy has not moved; the force's sideways part is the spring's, k x 0.5 mm.
  EXPECT_NEAR(f.stuck_proxy_shift, 0.0, 1e-9);
  EXPECT_NEAR(f.stuck_force_z, 2.0, 0.3);
  EXPECT_NEAR(f.stuck_force_y, -1000.0 * 0.0005, 0.05);
  // Sliding: the proxy followed (held mu_k x depth behind), the sideways force is -mu_k F_n.
  EXPECT_GT(f.slid_proxy_shift, 0.003);
  EXPECT_NEAR(f.slid_force_y, -0.3 * f.slid_force_z, 0.05 * f.slid_force_z);
  // At the contacts, 1.01 cm below the TCP: tau_x = 0.0101 F_y (plus nothing from F_z, symmetric).
  EXPECT_NEAR(f.slid_torque_x, 0.0101 * f.slid_force_y, 0.1 * std::fabs(0.0101 * f.slid_force_y));

  const Drag none = drag(0.0, 0.0);
  EXPECT_FALSE(none.ever_inside);
  EXPECT_GT(none.stuck_proxy_shift, 0.0004);  // it followed the device at once
  EXPECT_LT(std::fabs(none.slid_force_y), 0.05 * none.slid_force_z);
}

TEST(CompoundProxy, TheProxyRendererTakesCompoundToolsAndItsTickAllocatesNothing) {
  ProxyRenderer r(plate(), test::ellipsoid_params());
  ASSERT_FALSE(r.renders_compound());
  const CompoundTool bell = dumbbell();
  r.set_tool(bell);
  ASSERT_TRUE(r.renders_compound());
  std::array<ToolEllipsoid, kMaxToolParts> parts;
  const auto tick = [&](double z, double deg) {
    const Eigen::Vector3d x(0.002, 0.001, z);
    const int n = bell.posed(x, about_y(deg), parts);
    return r.render_compound({parts.data(), std::size_t(n)}, x, {0, 0, -0.02}, Eigen::Vector3d::Zero(), 1e-3);
  };
  for (int k = 0; k < 10; ++k) (void)tick(0.03 - 0.001 * k, 0);  // warm up
  const std::size_t before = test::allocation_count();
  RenderOutput out;
  for (int k = 10; k < 60; ++k) out = tick(0.03 - 0.001 * k, 0.2 * (k - 10));
  EXPECT_EQ(test::allocation_count() - before, 0u);
  EXPECT_GT(out.force.z(), 0.0);
  ASSERT_FALSE(r.contacts().empty());
  for (const Contact& c : r.contacts()) EXPECT_LE(c.part, 1);
  // The renderer counts the compound proxy's placements (its first, free one) and no lost one.
  EXPECT_EQ(r.placements(), 1u);
  EXPECT_EQ(r.lost(), 0u);
}

TEST(CompoundProxy, PressedAndPulledBackItsForceNeverPointsIntoThePlate) {
  // A tilted stylus pressed tip-first onto the plate, then pulled straight back up: the force
  // pushes out while pressed, never points into the plate (the proxy never pulls the hand in),
  // and is zero once the device is free above the surface.
  ProxyRenderer r(plate(), test::ellipsoid_params());
  const CompoundTool stylus = parse_tool_spec("stylus:0.06,0.005");
  r.set_tool(stylus);
  std::array<ToolEllipsoid, kMaxToolParts> parts;
  const Eigen::Quaterniond q = about_y(40);
  double fz_min = INFINITY;
  for (int k = 0; k <= 120; ++k) {
    const double z = k <= 60 ? 0.01 - 0.0002 * k : -0.002 + 0.0004 * (k - 60);
    const Eigen::Vector3d x(0.001, 0.002, z);
    const int n = stylus.posed(x, q, parts);
    const RenderOutput o = r.render_compound({parts.data(), std::size_t(n)}, x, {0, 0, k <= 60 ? -0.2 : 0.4},
                                             Eigen::Vector3d::Zero(), 1e-3);
    fz_min = std::min(fz_min, o.force.z());
    if (k == 60) {
      EXPECT_GT(o.force.z(), 1.0);  // pressed in: pushed out
    }
    if (k == 120) {
      EXPECT_EQ(o.force.norm(), 0.0);  // free above the plate: nothing
    }
  }
  EXPECT_GE(fz_min, 0.0);
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

// The compound proxy reads the one ProxyParams of the renderer: the opacity-scaled stiffness and
// the force limit reach it (the coupling is the one-ellipsoid proxy's VirtualCoupling), and a
// field that serves only the other kind of tool is refused, not ignored.
TEST(CompoundProxy, ReadsTheProxysOwnParametersAndRefusesTheOnesForAOnePartTool) {
  static const CollisionWorld faint = [] {
    std::vector<GaussianSpec> gs;
    add_layer(gs, 0.0f, 0.004f, 0.2f);
    return world_of(gs, 0.5f);
  }();
  const auto press = [](const ProxyParams& params, double f_max) {
    CompoundProxy proxy(faint, dumbbell(), params, f_max);
    RenderOutput out;
    for (int k = 0; k <= 300; ++k)  // down to 5 mm into the plate, then held 0.26 s (tau_opacity 0.02 s)
      out = proxy.render({0.001, 0.0007, 0.03 - 0.001 * std::min(k, 35)}, Eigen::Quaterniond::Identity(),
                         Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
    return out.force;
  };
  const Eigen::Vector3d plain = press({}, INFINITY);
  ProxyParams scaled = test::ellipsoid_params();
  scaled.opacity_stiffness = true;
  const Eigen::Vector3d faint_force = press(scaled, INFINITY);
  ASSERT_GT(plain.z(), 4.0);
  EXPECT_NEAR(faint_force.z() / plain.z(), 0.5, 0.01);
  EXPECT_NEAR(press({}, 2.0).norm(), 2.0, 1e-9);

  ProxyParams corner_off = test::ellipsoid_params();
  corner_off.corner_normal = false;
  ProxyRenderer renderer(faint, corner_off);
  CompoundTool stylus = parse_tool_spec("stylus:0.06,0.005");
  try {
    renderer.set_tool(stylus);
    FAIL() << "a compound tool took a one-part tool's option";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("corner_normal (--corner-normal) serves one-part tools only"), std::string::npos)
        << e.what();
  }
  ProxyParams lists_off = test::ellipsoid_params();
  lists_off.near_lists = false;
  ProxyRenderer sphere_renderer(faint, lists_off);
  EXPECT_THROW(sphere_renderer.set_tool(parse_tool_spec("sphere:0.005")), InputError);
  // The same fields at their defaults for the tool they do not serve: accepted.
  EXPECT_NO_THROW(ProxyRenderer(faint, proxy_params_for(corner_off, ProxyTool::kCompound)).set_tool(stylus));
  EXPECT_FALSE(proxy_params_for(lists_off, ProxyTool::kOnePart).near_lists == false);
  EXPECT_FALSE(proxy_params_for(corner_off, ProxyTool::kOnePart).corner_normal);  // it serves that tool: kept
}

}  // namespace
}  // namespace gshaptics
