// One servo step for every path: the probe run (simulate), the fidelity scripts and a replayed
// log (run --device replay) all go through ServoController, so on one trajectory and in one
// execution mode they command the same force, tick by tick. Also the simulated decoupled worker's
// latency, and a caller's own renderer in both runtimes.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "gshaptics/error.h"
#include "gshaptics/fidelity/analytic_shape.h"
#include "gshaptics/fidelity/interaction.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/device/replay_device.h"
#include "gshaptics/servo/simulated_runtime.h"
#include "gshaptics/sim/probe_run.h"
#include "gshaptics/sim/probe_trajectory.h"
#include "support/floor_renderer.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

/// A replayable log of a run's device poses (time, position, velocity), one row per tick.
PoseLog pose_log_of(const std::vector<TickRecord>& ticks, std::size_t n) {
  PoseLog log;
  log.has_velocity = true;
  for (std::size_t i = 0; i < n && i < ticks.size(); ++i) {
    PoseLogRow r;
    r.time = ticks[i].time;
    r.position = ticks[i].position;
    r.velocity = ticks[i].velocity;
    log.rows.push_back(r);
  }
  return log;
}

double peak_force(const std::vector<TickRecord>& t) {
  double p = 0;
  for (const TickRecord& r : t) p = std::max(p, r.force.norm());
  return p;
}

/// W = -sum F . dx over the ticks (trapezoidal in F), J.
double energy(const std::vector<TickRecord>& t, std::size_t n) {
  double w = 0;
  for (std::size_t i = 0; i + 1 < n && i + 1 < t.size(); ++i)
    w -= 0.5 * (t[i].force + t[i + 1].force).dot(t[i + 1].position - t[i].position);
  return w;
}

class StepEquivalence : public ::testing::TestWithParam<bool> {};

// The probe run's poses, replayed through SimulatedRuntime and through the real-time
// HapticRuntime on a manual clock, give the probe run's forces tick by tick.
TEST_P(StepEquivalence, ProbeRunAndReplayCommandTheSameForce) {
  const bool inline_query = GetParam();
  const CollisionWorld& world = test::truck_world();
  ProbeParams pp;
  pp.tool_radius = 0.07;
  pp.sites = 2;
  pp.approach_speed = 2 * pp.tool_radius;
  pp.travel_speed = 8 * pp.tool_radius;
  const ProbeTrajectory traj = generate_probe_trajectory(world, pp);
  ProbeRunParams rp;
  rp.inline_query = inline_query;
  const ProbeRunResult probe = run_probe(world, traj, rp);
  const double peak = peak_force(probe.ticks);
  ASSERT_GT(peak, 1.0) << "the probe run must touch for the comparison to mean anything";
  const std::size_t n = std::size_t(std::ceil((traj.duration() + 0.5) * 1000));
  ASSERT_GE(probe.ticks.size(), n);

  RuntimeConfig c;
  c.rate_hz = 1000;
  c.inline_query = inline_query;
  c.tool.semi_axes = Eigen::Vector3d::Constant(traj.tool_radius());
  c.duration = probe.ticks[n - 1].time;
  {
    ReplayDevice replay(pose_log_of(probe.ticks, n));
    SimulatedRuntime sim(world, replay, c);
    sim.run();
    const auto& rec = sim.log().records();
    ASSERT_GE(rec.size(), n - 1);
    for (std::size_t i = 0; i + 1 < n; ++i)
      ASSERT_LE((rec[i].force - probe.ticks[i].force).norm(), 0.01 * peak) << "tick " << i;
    EXPECT_NEAR(energy(rec, n - 1), energy(probe.ticks, n - 1), 0.01 * std::abs(energy(probe.ticks, n - 1)) + 1e-9);
  }
  if (inline_query) {
    // The real-time runtime: deterministic in the inline mode on a manual clock (its worker
    // thread is not used).
    ManualClock clock(0);
    ReplayDevice replay(pose_log_of(probe.ticks, n));
    RuntimeConfig rc = c;
    rc.realtime.servo_priority = 0;
    rc.realtime.worker_priority = 0;
    rc.realtime.pin_threads = false;
    HapticRuntime rt(world, replay, rc, clock);
    rt.start();
    rt.wait();
    const auto& rec = rt.log().records();
    ASSERT_GE(rec.size(), n - 1);
    for (std::size_t i = 0; i + 1 < n; ++i)
      ASSERT_LE((rec[i].force - probe.ticks[i].force).norm(), 0.01 * peak) << "tick " << i;
  }
}

INSTANTIATE_TEST_SUITE_P(Modes, StepEquivalence, ::testing::Values(true, false),
                         [](const ::testing::TestParamInfo<bool>& p) { return p.param ? "Inline" : "Decoupled"; });

// A fidelity press, replayed as a pose log, commands what play_script recorded.
TEST(StepEquivalenceFidelity, PressScriptAndItsReplayAgree) {
  const AnalyticShape plane(ShapeKind::kPlane);
  SynthParams sp;
  sp.spacing = 0.004;
  const SyntheticScene synth = make_synthetic_scene(plane, sp);
  const CollisionWorld world = CollisionWorld::build(synth.scene, WorldConfig{});
  const ContactSite site{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), "face"};
  const Script s = press_script(plane, site, 0.005, 0.01, 1000);
  for (const bool inline_query : {true, false}) {
    auto renderer = make_force_renderer(ProxyModelSpec{}, world);
    PlayOptions po;
    po.inline_query = inline_query;
    const ScriptTrace tr = play_script(*renderer, s, 1000, po);
    double peak = 0;
    for (const auto& f : tr.force) peak = std::max(peak, f.norm());
    ASSERT_GT(peak, 1.0);
    PoseLog log;
    log.has_velocity = true;
    for (const ScriptTick& t : s.ticks) log.rows.push_back({t.time, t.position, Eigen::Quaterniond::Identity(), t.velocity});
    ReplayDevice replay(std::move(log));
    RuntimeConfig c;
    c.inline_query = inline_query;
    c.tool.semi_axes = Eigen::Vector3d::Constant(0.005);
    c.duration = s.ticks.back().time;
    SimulatedRuntime sim(world, replay, c);
    sim.run();
    const auto& rec = sim.log().records();
    ASSERT_GE(rec.size(), s.ticks.size());
    for (std::size_t i = 0; i < s.ticks.size(); ++i)
      ASSERT_LE((rec[i].force - tr.force[i]).norm(), 0.01 * peak) << (inline_query ? "inline" : "decoupled") << " tick " << i;
  }
}

// The decoupled mode on simulated time renders the result of the pose latency_ticks ago; the
// inline mode the pose of this tick. A caller's own renderer drives the run.
TEST(SimulatedRuntime, DecoupledWorkerLatencyIsExactInTicks) {
  PoseLog log;
  for (int i = 0; i <= 1000; ++i) log.rows.push_back({i * 1e-3, Eigen::Vector3d(0, 0, -1e-3 * i), Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -1)});
  log.has_velocity = true;
  for (const int latency : {0, 1, 3}) {
    ReplayDevice replay(log);
    RuntimeConfig c;
    c.inline_query = latency == 0;
    c.latency_ticks = std::max(1, latency);
    c.duration = 0.9;
    c.safety.ramp_time = 0;
    c.safety.max_force_rate = 1e9;
    auto floor = std::make_unique<test::FloorRenderer>(10.0);
    test::FloorRenderer* raw = floor.get();
    SimulatedRuntime sim(replay, c, std::move(floor));
    sim.run();
    EXPECT_GT(raw->calls, 800);
    const auto& rec = sim.log().records();
    ASSERT_GT(rec.size(), 900u);
    for (std::size_t k = 10; k < 900; ++k) {
      // At tick k the device is at z = -k mm; the force answers the pose of tick k - latency.
      const double expect = 10.0 * 1e-3 * double(k - std::size_t(latency));
      ASSERT_NEAR(rec[k].force.z(), expect, 1e-9) << "latency " << latency << " tick " << k;
    }
    EXPECT_EQ(rec.back().force, Eigen::Vector3d::Zero());  // the stop ramp ends at zero
  }
}

TEST(SimulatedRuntime, RejectsBadLatencyAndAMissingRenderer) {
  PoseLog log;
  log.rows.push_back({0, Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()});
  ReplayDevice replay(log);
  RuntimeConfig c;
  c.latency_ticks = 0;
  EXPECT_THROW(SimulatedRuntime(replay, c, std::make_unique<test::FloorRenderer>(10.0)), InputError);
  c.latency_ticks = 1;
  EXPECT_THROW(SimulatedRuntime(replay, c, nullptr), InputError);
}

}  // namespace
}  // namespace gshaptics
