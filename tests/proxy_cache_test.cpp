// The proxy's work-saving paths give the plain computation's answers (issue 38): the tick's
// candidates gathered once (SweepQuery::gather_region) against every sweep traversing the BVH,
// on a replayed probe run of the bundled Truck, random jumps that leave the gathered region, and
// a slide across a fidelity cube's edge. Bit-identical proxy positions, forces and blockers.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <random>

#include "gshaptics/fidelity/analytic_shape.h"
#include "gshaptics/fidelity/interaction.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/sim/probe_run.h"
#include "gshaptics/sim/probe_trajectory.h"

namespace gshaptics {
namespace {

struct Step {
  Eigen::Vector3d position, velocity;
};

// Plays `path` through a gathering and a plain proxy and asserts that every tick agrees to the bit.
// Returns the ticks in contact (so a test can check it exercised contact at all).
int expect_identical(const CollisionWorld& w, const std::vector<Step>& path, double radius) {
  ProxyParams gathered, plain;
  plain.gather_region = false;
  ProxyRenderer a(w, gathered), b(w, plain);
  int in_contact = 0;
  for (std::size_t i = 0; i < path.size(); ++i) {
    const ToolEllipsoid tool = ToolEllipsoid::sphere(path[i].position, radius);
    const RenderOutput oa = a.render(tool, path[i].velocity, 1e-3);
    const RenderOutput ob = b.render(tool, path[i].velocity, 1e-3);
    EXPECT_EQ(oa.proxy, ob.proxy) << "tick " << i;
    EXPECT_EQ(oa.force, ob.force) << "tick " << i;
    EXPECT_EQ(oa.constraints, ob.constraints) << "tick " << i;
    const auto ca = a.contacts(), cb = b.contacts();
    EXPECT_EQ(ca.size(), cb.size()) << "tick " << i;
    for (std::size_t k = 0; k < std::min(ca.size(), cb.size()); ++k) EXPECT_EQ(ca[k].slot, cb[k].slot) << "tick " << i;
    if (::testing::Test::HasFailure()) return in_contact;  // one tick's report is enough
    in_contact += ob.constraints > 0;
  }
  return in_contact;
}

TEST(ProxyCandidateRegion, ReplayedTruckProbeRunIsBitIdentical) {
  const std::string scene = std::string(GSHAPTICS_DATA_DIR) + "/truck.splat";
  if (!std::filesystem::exists(scene)) GTEST_SKIP() << scene << " not found";
  WorldConfig cfg;
  cfg.registration = load_registration_file(std::string(GSHAPTICS_DATA_DIR) + "/truck.registration.json");
  const CollisionWorld w = CollisionWorld::build(load_scene(scene).scene, cfg);
  const double r = default_tool_radius(w);
  ProbeParams pp = default_probe_params(w, r, 3, 2, 1.5 * r);
  const ProbeRunResult run = run_probe(w, generate_probe_trajectory(w, pp), {});
  std::vector<Step> path;
  for (const TickRecord& t : run.ticks) path.push_back({t.position, t.velocity});
  EXPECT_GT(expect_identical(w, path, r), 1000);
}

TEST(ProxyCandidateRegion, JumpsThatLeaveTheRegionAreBitIdentical) {
  const AnalyticShape shape(ShapeKind::kSphere);
  SynthParams sp;
  sp.spacing = 0.004;
  const CollisionWorld w = CollisionWorld::build(make_synthetic_scene(shape, sp).scene, WorldConfig{});
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  // A walk pressed into the sphere's top with random jumps of up to 3 tool radii (the region
  // of one tick holds the goal's ball only: a jump leaves it), and teleports past 10 radii.
  const double r = 0.005;
  std::vector<Step> path;
  Eigen::Vector3d x(0, 0, 0.12);
  for (int i = 0; i < 4000; ++i) {
    const double jump = i % 97 == 0 ? 0.06 : (i % 13 == 0 ? 3 * r : 0.0005);
    const Eigen::Vector3d step = Eigen::Vector3d(u(rng), u(rng), u(rng) - 0.3).normalized() * jump;
    x += step;
    x = x.normalized() * std::clamp(x.norm(), 0.09, 0.115);  // stay near the sphere (radius 10 cm)
    path.push_back({x, step / 1e-3});
  }
  EXPECT_GT(expect_identical(w, path, r), 500);
}

TEST(ProxyCandidateRegion, SlideAcrossACubeEdgeIsBitIdentical) {
  const AnalyticShape shape(ShapeKind::kCube);
  SynthParams sp;
  sp.spacing = 0.004;
  const CollisionWorld w = CollisionWorld::build(make_synthetic_scene(shape, sp).scene, WorldConfig{});
  const double r = 0.005;
  const Script s = slide_script(shape, r, 1000);
  std::vector<Step> path;
  for (const ScriptTick& t : s.ticks) path.push_back({t.position, t.velocity});
  EXPECT_GT(expect_identical(w, path, r), 1000);
}

}  // namespace
}  // namespace gshaptics
