// The proxy (god-object) renderer as a whole: analytic stop
// distances and normals, no tunnelling through a 1 mm plate, friction stick and slip, placement
// after a start inside geometry, and an allocation-free tick.

#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/force/renderer_spec.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include <fmt/format.h>

#include "gshaptics/error.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/fidelity/wrench_fidelity.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/sim/probe_run.h"
#include "gshaptics/sim/probe_trajectory.h"
#include "support/allocation_counter.h"
#include "support/ellipsoid_params.h"
#include "support/gaussian_worlds.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

using test::add_layer;
using test::world_of;

double overlap(const CollisionWorld& w, const ToolEllipsoid& t) { return test::overlaps(w, t) ? 1.0 : 0.0; }

TEST(ProxyRenderer, StopsOnASphereAtTheAnalyticDistanceWithItsNormal) {
  const float R = 0.02f;
  const CollisionWorld w = world_of({{Eigen::Vector3f::Zero(), Eigen::Vector3f::Constant(R), Eigen::Quaternionf::Identity()}});
  ProxyParams p = test::ellipsoid_params();
  p.pass_isolated = false;  // a lone Gaussian is the whole object here
  ProxyRenderer proxy(w, p);
  const double r = 0.005;
  const Eigen::Vector3d from(0.003, -0.002, 0.05), dir = Eigen::Vector3d(-0.003, 0.002, -0.05).normalized();
  RenderOutput out;
  for (int k = 0; k <= 35; ++k)  // 1 mm per tick, ending 10 mm past the surface
    out = proxy.render(ToolEllipsoid::sphere(from + dir * 0.001 * k, r), Eigen::Vector3d::Zero(), 1e-3);
  const Eigen::Vector3d device = from + dir * 0.035;
  // The proxy rests on the sphere of radius R + r (god-object: the point of the free space
  // closest to the device), along the line from the centre to the device, its stand-off short
  // of it (at least half of it: the sweeps' tolerance).
  const double stand_off = ProxySolver::kStandOff * r;
  EXPECT_GE(proxy.proxy_position().norm(), R + r + 0.5 * stand_off - 1e-7);
  EXPECT_LE(proxy.proxy_position().norm(), R + r + stand_off + 1e-7);
  EXPECT_LT(std::acos(proxy.proxy_position().normalized().dot(device.normalized())) * 180 / M_PI, 0.05);
  EXPECT_LT(std::acos(proxy.contact_normal().dot(device.normalized())) * 180 / M_PI, 0.05);
  EXPECT_NEAR(out.force.norm(), p.stiffness * (R + r - device.norm()), 1e-2);
  EXPECT_GE(out.constraints, 1);
  EXPECT_EQ(proxy.contacts().size(), std::size_t(out.constraints) == 0 ? 0 : proxy.contacts().size());
}

TEST(ProxyRenderer, PlaneOfGaussiansStopDistanceNormalAndSlideDirection) {
  std::vector<test::GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.08f);
  const CollisionWorld w = world_of(gs);
  ProxyParams p = test::ellipsoid_params();
  ProxyRenderer proxy(w, p);
  const double r = 0.005;
  Eigen::Vector3d x(0.001, 0.002, 0.02);
  for (int k = 0; k < 22; ++k, x.z() -= 0.001) (void)proxy.render(ToolEllipsoid::sphere(x, r), Eigen::Vector3d::Zero(), 1e-3);
  // Device 2 mm below the discs: the proxy stops r above the highest disc surface under it
  // (disc semi-axes 4, 4, 0.2 mm: at an in-plane offset rho from a centre the surface is at
  // 0.2 mm * sqrt(1 - rho^2 / 16 mm^2)).
  const RenderOutput pressed = proxy.render(ToolEllipsoid::sphere(x, r), Eigen::Vector3d::Zero(), 1e-3);
  const auto top_at = [&](double px, double py) {
    double top = 0;
    for (const auto& [c, a, q] : gs) {
      const double rho2 = (std::pow(px - c.x(), 2) + std::pow(py - c.y(), 2)) / (double(a.x()) * a.x());
      if (rho2 < 1) top = std::max(top, double(a.z()) * std::sqrt(1 - rho2));
    }
    return top;
  };
  // Exactly where a sphere lowered there comes to rest: max over the surface under it of
  // top(q) + sqrt(r^2 - |q - centre|^2) (sampled every 0.05 mm).
  const auto rest_height = [&](double px, double py) {
    double z = 0;
    for (double qx = -r; qx <= r; qx += 5e-5)
      for (double qy = -r; qy <= r; qy += 5e-5) {
        const double l2 = qx * qx + qy * qy;
        if (l2 < r * r) z = std::max(z, top_at(px + qx, py + qy) + std::sqrt(r * r - l2));
      }
    return z;
  };
  EXPECT_NEAR(proxy.proxy_position().z(), rest_height(proxy.proxy_position().x(), proxy.proxy_position().y()), 1e-6);
  EXPECT_LT(std::acos(pressed.force.normalized().z()) * 180 / M_PI, 0.5);
  EXPECT_NEAR(pressed.force.z(), p.stiffness * (proxy.proxy_position().z() - x.z()), 1e-4);
  // Slide along +x: the proxy follows on the surface; no tangential force without friction.
  const Eigen::Vector3d v(0.05, 0, 0);
  for (int k = 0; k < 400; ++k) {
    x += v * 1e-3;
    const RenderOutput out = proxy.render(ToolEllipsoid::sphere(x, r), v, 1e-3);
    // Resting on the discs: never below the surface under its centre, never above their tops.
    ASSERT_GE(proxy.proxy_position().z(), r + top_at(proxy.proxy_position().x(), proxy.proxy_position().y()) - 1e-6) << k;
    ASSERT_LE(proxy.proxy_position().z(), r + 0.0002 + 1e-6) << k;
    ASSERT_NEAR(proxy.proxy_position().x(), x.x(), 1e-3) << k;
    ASSERT_LT(std::hypot(out.force.x(), out.force.y()), 0.02 * out.force.z()) << k;
  }
}

TEST(ProxyRenderer, DoesNotTunnelThroughAOneMillimetrePlateInOneTick) {
  // Two layers of discs 1 mm apart: a 1 mm plate, hollow in between.
  std::vector<test::GaussianSpec> gs;
  add_layer(gs, 0.0005f, 0.003f, 0.05f);
  add_layer(gs, -0.0005f, 0.003f, 0.05f);
  const CollisionWorld w = world_of(gs);
  const double r = 0.004;
  // 1 m/s at 1 kHz: 1 mm per tick, straight through.
  ProxyRenderer proxy(w, test::ellipsoid_params());
  for (int k = 0; k <= 40; ++k) {
    const Eigen::Vector3d x(0.0, 0.0, 0.02 - 0.001 * k);
    const RenderOutput out = proxy.render(ToolEllipsoid::sphere(x, r), Eigen::Vector3d(0, 0, -1), 1e-3);
    ASSERT_GT(proxy.proxy_position().z(), 0.0005 + r - 1e-5) << k;
    if (x.z() < r) {
      ASSERT_GT(out.force.z(), 0) << k;
    }
  }
  // The whole plate and more in a single tick (9 mm): still held on the entry side.
  ProxyRenderer jump(w, test::ellipsoid_params());
  (void)jump.render(ToolEllipsoid::sphere({0, 0, 0.0046}, r), Eigen::Vector3d::Zero(), 1e-3);
  const RenderOutput out = jump.render(ToolEllipsoid::sphere({0, 0, -0.0044}, r), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_GT(jump.proxy_position().z(), 0.0005 + r - 1e-5);
  EXPECT_GT(out.force.z(), 5.0);
}

TEST(ProxyRenderer, FloatersDoNotCatchTheTool) {
  std::vector<test::GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.05f);
  gs.emplace_back(Eigen::Vector3f(0, 0, 0.012f), Eigen::Vector3f::Constant(0.002f), Eigen::Quaternionf::Identity());
  const CollisionWorld w = world_of(gs);
  const double r = 0.005;
  for (bool pass : {true, false}) {
    ProxyParams p = test::ellipsoid_params();
    p.pass_isolated = pass;
    ProxyRenderer proxy(w, p);
    for (double z = 0.03; z > 0.002; z -= 0.0005)
      (void)proxy.render(ToolEllipsoid::sphere({0, 0, z}, r), Eigen::Vector3d::Zero(), 1e-3);
    if (pass) {  // through the floater, onto the discs (tops at most 0.2 mm high)
      EXPECT_GT(proxy.proxy_position().z(), r);
      EXPECT_LT(proxy.proxy_position().z(), r + 0.0002 + 1e-6);
    }
    if (!pass) {  // held on top of the floater
      EXPECT_GT(proxy.proxy_position().z(), 0.012 + 0.002 + r - 1e-4);
    }
  }
}

// Floaters come in clumps: a pair and a triple of overlapping round Gaussians hanging 12 mm over
// a layer do not catch a 5 mm tool pressed down through them (floater_cluster 3, the default);
// with single floaters only (1) the pair holds it like a solid. A clump of four, and a pair
// hanging within its own size of the layer (a bump of the surface), hold it either way.
TEST(ProxyRenderer, FloaterClumpsDoNotCatchTheToolButSurfaceClumpsHold) {
  std::vector<test::GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.05f);
  const float a = 0.0025f;  // the clumps' radius; members 4 mm apart overlap
  const auto ball = [&](float x, float y, float z) {
    gs.emplace_back(Eigen::Vector3f(x, y, z), Eigen::Vector3f::Constant(a), Eigen::Quaternionf::Identity());
  };
  ball(-0.002f, 0, 0.012f), ball(0.002f, 0, 0.012f);                               // pair at (0, 0)
  ball(0.018f, 0, 0.012f), ball(0.022f, 0, 0.012f), ball(0.020f, 0.0035f, 0.012f);  // triple at (0.02, 0)
  for (float x : {-0.026f, -0.022f, -0.018f, -0.014f}) ball(x, 0, 0.012f);          // four in a row at (-0.02, 0)
  ball(-0.002f, 0.02f, 0.0042f), ball(0.002f, 0.02f, 0.0042f);                    // pair 1.5 mm over the layer at (0, 0.02)
  const CollisionWorld w = world_of(gs);
  const double r = 0.005, on_layer = r + 0.0002, on_clump = 0.012 + a + r;
  const auto press = [&](std::size_t cluster, double x, double y) {
    ProxyParams p = test::ellipsoid_params();
    p.floater_cluster = cluster;
    ProxyRenderer proxy(w, p);
    for (double z = 0.03; z > 0.003; z -= 0.0005)
      (void)proxy.render(ToolEllipsoid::sphere({x, y, z}, r), Eigen::Vector3d::Zero(), 1e-3);
    return proxy.proxy_position().z();
  };
  EXPECT_NEAR(press(3, 0, 0), on_layer, 1e-4) << "caught on a floater pair";
  EXPECT_NEAR(press(3, 0.02, 0), on_layer, 1e-4) << "caught on a floater triple";
  EXPECT_GT(press(1, 0, 0), on_clump - 1e-3) << "single floaters only: the pair holds";
  EXPECT_GT(press(3, -0.02, 0), on_clump - 1e-3) << "a clump of four holds";
  EXPECT_GT(press(3, 0, 0.02), 0.0042 + a + r - 1e-3) << "a pair within its size of the surface holds";
  EXPECT_THROW(ProxyRenderer(w, [] { ProxyParams p = test::ellipsoid_params(); p.floater_cluster = 0; return p; }()), InputError);
}

// A sparse surface, as small trained objects have (fruitdrops: in-plane scales about half the
// spacing, so neighbouring 1-sigma ellipsoids leave gaps): no Gaussian overlaps another, yet
// every one has neighbours within a tool radius. With isolation_gap 1 it holds the tool; with
// the default overlap-only floater rule (0) every Gaussian counts as a floater and the tool falls through.
TEST(ProxyRenderer, SparseSurfacesHoldWhereFloatersPass) {
  std::vector<test::GaussianSpec> gs;
  const float h = 0.004f;
  for (float x = -0.03f; x <= 0.03f; x += h)
    for (float y = -0.03f; y <= 0.03f; y += h)
      gs.emplace_back(Eigen::Vector3f(x, y, 0), Eigen::Vector3f(0.4f * h, 0.25f * h, 0.05f * h), Eigen::Quaternionf::Identity());
  gs.emplace_back(Eigen::Vector3f(0.02f, 0.02f, 0.02f), Eigen::Vector3f::Constant(0.002f), Eigen::Quaternionf::Identity());
  const CollisionWorld w = world_of(gs);
  const double r = 0.005;
  for (const double gap : {0.0, 1.0}) {
    ProxyParams p = test::ellipsoid_params();
    p.isolation_gap = gap;
    ProxyRenderer proxy(w, p);
    for (double z = 0.03; z > -0.004; z -= 0.0005)
      (void)proxy.render(ToolEllipsoid::sphere({0.002, 0.001, z}, r), Eigen::Vector3d::Zero(), 1e-3);
    if (gap == 0) EXPECT_LT(proxy.proxy_position().z(), 0.0) << "the sparse layer held with the overlap-only rule";
    else EXPECT_NEAR(proxy.proxy_position().z(), r, 0.0015) << "the tool fell through a sparse surface";
    // The floater, 2 cm above the layer, is alone within a tool radius: it never catches the tool.
    ProxyRenderer down(w, p);
    for (double z = 0.05; z > 0.004; z -= 0.0005)
      (void)down.render(ToolEllipsoid::sphere({0.02, 0.02, z}, r), Eigen::Vector3d::Zero(), 1e-3);
    if (gap > 0) {
      EXPECT_NEAR(down.proxy_position().z(), r, 0.0015) << "caught on the floater";
    }
  }
}

TEST(ProxyRenderer, FrictionSticksBelowMuSAndSlidesAtMuK) {
  std::vector<test::GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.1f);
  const CollisionWorld w = world_of(gs);
  ProxyParams p = test::ellipsoid_params();
  p.mu_s = 0.6;
  p.mu_k = 0.4;
  ProxyRenderer proxy(w, p);
  const double r = 0.005;
  Eigen::Vector3d x(0, 0, 0.01);
  for (; x.z() > r - 0.002; x.z() -= 0.0005) (void)proxy.render(ToolEllipsoid::sphere(x, r), Eigen::Vector3d::Zero(), 1e-3);
  const double depth = proxy.proxy_position().z() - x.z();  // ~2 mm
  const double x0 = proxy.proxy_position().x();
  // Tangential offset below mu_s * depth: the proxy sticks where it is.
  const Eigen::Vector3d v(0.01, 0, 0);
  int ticks = 0;
  while (x.x() - x0 < 0.9 * p.mu_s * depth) {
    x += v * 1e-3;
    const RenderOutput out = proxy.render(ToolEllipsoid::sphere(x, r), v, 1e-3);
    ASSERT_TRUE(proxy.sticking()) << ticks;
    ASSERT_NEAR(proxy.proxy_position().x(), x0, 1e-6) << ticks;
    ASSERT_NEAR(-out.force.x() / out.force.z(), (x.x() - x0) / depth, 0.02) << ticks;
    ++ticks;
  }
  EXPECT_GT(ticks, 50);
  // Past mu_s it slips, and while sliding F_t / F_n = mu_k.
  for (int k = 0; k < 300; ++k) {
    x += v * 1e-3;
    const RenderOutput out = proxy.render(ToolEllipsoid::sphere(x, r), v, 1e-3);
    if (k < 100) continue;
    ASSERT_FALSE(proxy.sticking()) << k << " offset " << (x.x() - proxy.proxy_position().x()) << " depth " << (proxy.proxy_position().z() - x.z());
    ASSERT_NEAR(-out.force.x() / out.force.z(), p.mu_k, 0.1 * p.mu_k) << k << " n " << proxy.contact_normal().transpose();
  }
}

TEST(ProxyRenderer, StartInsideGeometryPlacesTheProxyOutside) {
  std::vector<test::GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.05f);
  const CollisionWorld w = world_of(gs);
  ProxyRenderer proxy(w, test::ellipsoid_params());
  const double r = 0.005;
  const ToolEllipsoid start = ToolEllipsoid::sphere({0.001, 0.0, 0.001}, r);  // overlapping the layer
  const RenderOutput out = proxy.render(start, Eigen::Vector3d::Zero(), 1e-3);
  ToolEllipsoid at = start;
  at.center = proxy.proxy_position();
  EXPECT_EQ(overlap(w, at), 0.0);
  EXPECT_GT(proxy.proxy_position().z(), start.center.z());  // out along the normal, the nearest way
  EXPECT_LT((proxy.proxy_position() - start.center).norm(), 2 * r);
  EXPECT_EQ(proxy.placements(), 1u);
  EXPECT_TRUE(out.force.allFinite());
  EXPECT_LE(out.force.norm(), ForceParams{}.f_max + 1e-9);
}

TEST(ProxyRenderer, ATeleportStartsTheContactAfreshAsANewRendererDoes) {
  // Two layers of discs a metre apart: a faint one (opacity 0.3) and an opaque one. With the
  // opacity-scaled stiffness (paper eq. 9) the coupling smooths the blockers' opacity; a device
  // jump of more than `teleport` tool radii re-places the proxy, and the contact it lands in
  // must not inherit the faint layer's smoothed opacity (or any other contact state).
  GaussianScene s;
  std::uint32_t id = 0;
  for (const auto& [x0, opacity] : {std::pair{0.0f, 0.3f}, std::pair{1.0f, 1.0f}})
    for (float x = -0.03f; x <= 0.03f; x += 0.004f)
      for (float y = -0.03f; y <= 0.03f; y += 0.004f)
        s.push_back(Eigen::Vector3f(x0 + x, y, 0.0f), Eigen::Vector3f(0.004f, 0.004f, 0.0002f), Eigen::Vector4f(1, 0, 0, 0),
                    opacity, id++);
  const CollisionWorld w = CollisionWorld::build(s, WorldConfig{});
  ProxyParams p = test::ellipsoid_params();
  p.opacity_stiffness = true;
  const double r = 0.005;
  const Eigen::Vector3d pressed_b(1.0, 0.001, r - 0.003);  // 3 mm into the opaque layer
  ProxyRenderer fresh(w, p);
  const RenderOutput want = fresh.render(ToolEllipsoid::sphere(pressed_b, r), Eigen::Vector3d::Zero(), 1e-3);
  ASSERT_GT(want.force.z(), 2.0);  // (k_c 1000 N/m on 3 mm, full opacity)

  ProxyRenderer proxy(w, p);
  Eigen::Vector3d x(0.001, 0.0, 0.02);
  RenderOutput held;
  for (int k = 0; k < 400; ++k) {  // down into the faint layer, then held 3 mm in
    if (x.z() > r - 0.003) x.z() -= 0.0001;
    held = proxy.render(ToolEllipsoid::sphere(x, r), Eigen::Vector3d::Zero(), 1e-3);
  }
  ASSERT_LT(held.force.z(), 0.35 * want.force.z());  // it did take on the faint layer's opacity
  const std::uint64_t placed = proxy.placements();
  const RenderOutput got = proxy.render(ToolEllipsoid::sphere(pressed_b, r), Eigen::Vector3d::Zero(), 1e-3);
  EXPECT_EQ(proxy.placements(), placed + 1);  // the jump re-placed the proxy
  EXPECT_LT((proxy.proxy_position() - fresh.proxy_position()).norm(), 1e-12);
  EXPECT_LT((got.force - want.force).norm(), 1e-9) << got.force.transpose() << " vs " << want.force.transpose();
}

TEST(ProxyRenderer, TickIsAllocationFreeAndNoexcept) {
  AnalyticShape shape(ShapeKind::kSphere);
  SynthParams sp;
  const SyntheticScene s = make_synthetic_scene(shape, sp);
  const CollisionWorld w = CollisionWorld::build(s.scene, WorldConfig{});
  ProxyRenderer proxy(w, test::ellipsoid_params());
  const ToolEllipsoid t0{};
  const Eigen::Vector3d v0 = Eigen::Vector3d::Zero();
  static_assert(noexcept(proxy.render(t0, v0, 1e-3)));
  Eigen::Vector3d x(0, 0, 0.13);
  (void)proxy.render(ToolEllipsoid::sphere(x, 0.005), Eigen::Vector3d::Zero(), 1e-3);  // placement
  const std::size_t before = test::allocation_count();
  for (int k = 0; k < 600; ++k) {
    x += Eigen::Vector3d(0.00002, 0.00001, -0.0001);
    (void)proxy.render(ToolEllipsoid::sphere(x, 0.005), Eigen::Vector3d(0.02, 0.01, -0.1), 1e-3);
  }
  EXPECT_EQ(test::allocation_count() - before, 0u);
  EXPECT_GT(proxy.contact_normal().z(), 0.9);  // it did touch the sphere's top
}

// The bundled Truck registered as `gshaptics simulate` does, the default tool radius, and its
// probe run (seed 7, run_probe with its defaults): built once for the replays below.
struct TruckProbeRun {
  CollisionWorld world;
  double tool_radius;
  ProbeRunResult run;
};
const TruckProbeRun& truck_probe_run() {
  static const TruckProbeRun t = [] {
    WorldConfig config;
    config.registration = load_registration_file(test::data_path("truck.registration.json"));
    CollisionWorld w = CollisionWorld::build(load_scene(test::data_path("truck.splat")).scene, config);
    const double r = default_tool_radius(w);
    const ProbeTrajectory traj = generate_probe_trajectory(w, default_probe_params(w, r, 7, 1, 0.02));
    ProbeRunResult run = run_probe(w, traj, {});
    return TruckProbeRun{std::move(w), r, std::move(run)};
  }();
  return t;
}

// The shaded normal's support bound (ProxyParams::shading_tail, default kShadingTail) against a
// support that holds every Gaussian that matters (tail 200: exp(-100) of the touching ones), on
// the Truck's probe run replayed through the renderer: the same proxy path tick for tick (the
// god-object does not read the normal), and the force within 0.25 deg and 1 % wherever it is
// over 0.5 N (0.019 deg and 0.02 % here, over 9,444 ticks). A short tail (2) moves it by 1.7 deg:
// the check can tell.
TEST(ProxyRenderer, TheShadedNormalsSupportBoundKeepsTheTrucksProbeRunsPathAndForce) {
  const TruckProbeRun& truck = truck_probe_run();
  const CollisionWorld& w = truck.world;
  const double r = truck.tool_radius;
  const ProbeRunResult& run = truck.run;
  std::size_t pressed = 0;
  const auto replay = [&](double tail, double& worst_deg, double& worst_rel, std::size_t& path_differs) {
    pressed = 0;
    ProxyParams bounded = test::ellipsoid_params(), wide = test::ellipsoid_params();
    bounded.shading_tail = kShadingTail;
    wide.shading_tail = tail;
    bounded.shading_visits = wide.shading_visits = 0;  // (every Gaussian: the tail alone differs)
    // (Each reading made whole where it falls due: one prepared ahead is made for where the proxy
    // is predicted to be, and when one starts depends on what the last reading cost, which the
    // tail changes.)
    bounded.shading_budget = wide.shading_budget = 0;
    ProxyRenderer a(w, bounded), b(w, wide);
    worst_deg = worst_rel = 0;
    path_differs = 0;
    for (const TickRecord& t : run.ticks) {
      const ToolEllipsoid tool = ToolEllipsoid::sphere(t.position, r);
      const RenderOutput oa = a.render(tool, t.velocity, 1e-3), ob = b.render(tool, t.velocity, 1e-3);
      path_differs += oa.proxy != ob.proxy;
      if (ob.force.norm() > 0.5) {
        ++pressed;
        worst_deg = std::max(worst_deg, std::acos(std::clamp(oa.force.normalized().dot(ob.force.normalized()), -1.0, 1.0)) * 180 / M_PI);
        worst_rel = std::max(worst_rel, std::fabs(oa.force.norm() - ob.force.norm()) / ob.force.norm());
      }
    }
  };
  double deg = 0, rel = 0;
  std::size_t differs = 0;
  replay(200, deg, rel, differs);
  EXPECT_GT(pressed, 1000u);  // (ticks pressing with over 0.5 N)
  EXPECT_EQ(differs, 0u);
  EXPECT_LT(deg, 0.25);
  EXPECT_LT(rel, 0.01);
  RecordProperty("worst_deg", std::to_string(deg));
  RecordProperty("worst_rel", std::to_string(rel));
  double short_deg = 0, short_rel = 0;
  replay(2, short_deg, short_rel, differs);
  EXPECT_GT(short_deg, 0.25);
  RecordProperty("short_tail_deg", std::to_string(short_deg));
}

// The compound proxy's near lists (ProxyParams::near_lists) keep its path and wrench: the same
// proxy pose and the same force and torque on every tick as the proxy that takes the BVH every
// sweep, for a stylus lying on the fidelity plane at 2 mm (the press the lists are for), a
// stylus pressed 3 mm onto the fidelity cube's top and slid across its edge and back, and a
// tilted stylus (as gshaptics_proxy_bench --stylus) on the Truck's probe run, its device
// jumping three tool radii every 400 ticks (out of its lists' boxes). The lists must serve
// most of the sweeps.
TEST(ProxyRenderer, NearListsKeepTheCompoundProxysPathAndWrench) {
  struct Tick {
    Eigen::Vector3d position, velocity;
    Eigen::Quaterniond orientation;
  };
  const auto replay = [](const CollisionWorld& w, const CompoundTool& tool, const std::vector<Tick>& ticks,
                         const std::string& name) {
    ProxyParams on = test::ellipsoid_params(), off = test::ellipsoid_params();
    off.near_lists = false;
    ProxyRenderer a(w, on), b(w, off);
    a.set_tool(tool);
    b.set_tool(tool);
    std::array<ToolEllipsoid, kMaxToolParts> parts;
    std::size_t differ = 0, pressed = 0;
    double worst_x = 0, worst_f = 0;
    for (const Tick& t : ticks) {
      const int n = tool.posed(t.position, t.orientation, parts);
      const std::span<const ToolEllipsoid> ps(parts.data(), std::size_t(n));
      const RenderOutput oa = a.render_compound(ps, t.position, t.velocity, Eigen::Vector3d::Zero(), 1e-3);
      const RenderOutput ob = b.render_compound(ps, t.position, t.velocity, Eigen::Vector3d::Zero(), 1e-3);
      differ += oa.proxy != ob.proxy || oa.force != ob.force || oa.torque != ob.torque;
      pressed += ob.force.norm() > 0.5;
      worst_x = std::max(worst_x, (oa.proxy - ob.proxy).norm());
      worst_f = std::max(worst_f, (oa.force - ob.force).norm() + (oa.torque - ob.torque).norm());
    }
    ASSERT_NE(a.compound(), nullptr);
    const CompoundProxy::SweepWork& work = a.compound()->sweep_work();
    EXPECT_EQ(b.compound()->sweep_work().reused, 0u) << name;
    EXPECT_GT(work.reused, work.sweeps) << name << ": the lists served few sweeps";
    EXPECT_GT(pressed, ticks.size() / 10) << name;
    // (The lists leave out Gaussians that cannot touch, whose exact searches would otherwise
    // warm-start others: the same contacts to the search's tolerance, 1e-12 of a motion.)
    EXPECT_LT(worst_x, 1e-12) << name;
    EXPECT_LT(worst_f, 1e-8) << name;
    RecordProperty(name + "_ticks_not_bit_identical", std::to_string(differ));
    RecordProperty(name + "_reused_parts", std::to_string(work.reused));
    RecordProperty(name + "_rebuilt", std::to_string(work.rebuilt));
  };
  const WrenchTools tools;
  {
    SynthParams sp;
    sp.spacing = 0.002;
    const CollisionWorld w = CollisionWorld::build(make_synthetic_scene(AnalyticShape(ShapeKind::kPlane), sp).scene, WorldConfig{});
    for (const WrenchCase& c : wrench_cases(ShapeKind::kPlane, tools, 1, 1)) {
      if (c.name != "stylus side-on") continue;
      std::vector<Tick> ticks;
      for (const ScriptTick& t : wrench_script(c, 0.005, 1000).ticks) ticks.push_back({t.position, t.velocity, t.orientation});
      replay(w, c.tool, ticks, "plane");
    }
  }
  {
    SynthParams sp;
    sp.spacing = 0.004;
    const CollisionWorld w = CollisionWorld::build(make_synthetic_scene(AnalyticShape(ShapeKind::kCube), sp).scene, WorldConfig{});
    // The cube's top at z = 0.1, its edge at x = 0.1: the stylus lies along y, tilted 20 deg.
    const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX())) *
                                 Eigen::Quaterniond(Eigen::AngleAxisd(20 * M_PI / 180, Eigen::Vector3d::UnitY()));
    std::vector<Tick> ticks;
    const Eigen::Vector3d start(0.06, 0, 0.1 + 0.02), pressed(0.06, 0, 0.1 - 0.003), across(0.13, 0, 0.1 - 0.003);
    const auto line = [&](const Eigen::Vector3d& from, const Eigen::Vector3d& to, int n) {
      for (int i = 0; i < n; ++i)
        ticks.push_back({from + (to - from) * (double(i) / n), (to - from) / (n * 1e-3), q});
    };
    line(start, pressed, 800);
    line(pressed, across, 2000);
    line(across, pressed, 2000);
    line(pressed, start, 800);
    replay(w, tools.stylus, ticks, "cube_edge");
  }
  {
    const TruckProbeRun& truck = truck_probe_run();
    const CollisionWorld& w = truck.world;
    const double r = truck.tool_radius;
    const ProbeRunResult& run = truck.run;
    const CompoundTool stylus = parse_tool_spec(fmt::format("stylus:{},{}", 6 * r, r));
    const Eigen::Quaterniond tilt(Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitY()));
    std::mt19937_64 rng(12);
    std::normal_distribution<double> n01;
    std::vector<Tick> ticks;
    Eigen::Vector3d jump = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < run.ticks.size(); ++i) {
      if (i % 400 == 399) jump = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized() * 3 * r;
      else if (i % 400 == 0) jump.setZero();  // (and back on the next)
      ticks.push_back({run.ticks[i].position + jump, run.ticks[i].velocity, tilt});
    }
    replay(w, stylus, ticks, "truck");
  }
}

TEST(ProxyRenderer, BadParametersAreErrors) {
  std::vector<test::GaussianSpec> gs;
  add_layer(gs, 0.0f, 0.004f, 0.01f);
  const CollisionWorld w = world_of(gs);
  ProxyParams p = test::ellipsoid_params();
  p.stiffness = 0;
  EXPECT_THROW(ProxyRenderer(w, p), InputError);
  p = {};
  p.mu_s = 0.2;
  p.mu_k = 0.5;
  EXPECT_THROW(ProxyRenderer(w, p), InputError);
  p = {};
  p.shading_tail = 0;
  EXPECT_THROW(ProxyRenderer(w, p), InputError);
  p = {};
  p.device_shading = -0.1;
  EXPECT_THROW(ProxyRenderer(w, p), InputError);
  EXPECT_THROW((void)renderer_spec("spring"), InputError);
  EXPECT_EQ(make_force_renderer(renderer_spec("proxy"), w)->name(), "proxy");
  EXPECT_EQ(make_force_renderer(renderer_spec("paper"), w)->name(), "paper");
  EXPECT_EQ(renderer_name(renderer_spec("paper")), "paper");
  // A spec carries its model's own parameters to the renderer.
  ProxyModelSpec bad;
  bad.params.stiffness = -1;
  EXPECT_THROW((void)make_force_renderer(bad, w), InputError);
}

}  // namespace
}  // namespace gshaptics
