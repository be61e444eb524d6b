// The simulated impedance device (device/device_model.h) and the stability trials
// (fidelity/stability.h): the model's physics, its validation against the sampled-wall limit
// (Colgate and Schenkel 1997: b > K T / 2 + |B|), and the passivity controller on a wall above it.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>

#include "gshaptics/error.h"
#include "gshaptics/fidelity/stability.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/collision/collision_world.h"
#include "gshaptics/device/device_model.h"
#include "support/floor_renderer.h"

namespace gshaptics {
namespace {

// A device alone (no runtime): constant force, read at 1 kHz.
DeviceModelParams free_device() {
  DeviceModelParams p;
  p.mass = 0.2;
  p.damping = 2.0;
  return p;
}

TEST(DeviceModel, ConstantForceReachesTerminalVelocityAndDoesWork) {
  DeviceModel d(free_device());
  d.start(0);
  Wrench w;
  w.force = Eigen::Vector3d(1.0, 0, 0);
  d.write(w, 0);
  const Nanos tick = 1'000'000;
  DeviceSample s;
  for (int k = 1; k <= 2000; ++k) s = d.read(k * tick);  // 2 s = 20 time constants m/b
  EXPECT_NEAR(d.velocity().x(), 0.5, 1e-3);              // F / b
  EXPECT_NEAR(s.velocity.x(), 0.5, 1e-3);                // backward difference of positions
  // x(t) = v_inf (t - tau (1 - e^(-t/tau))), tau = m / b = 0.1 s.
  const double tau = 0.1, t = 2.0;
  EXPECT_NEAR(d.position().x(), 0.5 * (t - tau * (1 - std::exp(-t / tau))), 1e-4);
  EXPECT_NEAR(d.work_by_force(), d.position().x() * 1.0, 1e-9);
}

TEST(DeviceModel, DelaysQuantisationAndLimit) {
  DeviceModelParams p = free_device();
  p.delay_down = 0.005;
  p.delay_up = 0.003;
  p.encoder_resolution = 1e-4;
  p.force_resolution = 0.25;
  p.max_force = 2.0;
  DeviceModel d(p);
  d.start(0);
  Wrench w;
  w.force = Eigen::Vector3d(0, 0, 1.1);  // rounds to 1.0 N
  d.write(w, 0);
  const Nanos ms = 1'000'000;
  (void)d.read(4 * ms);
  EXPECT_EQ(d.applied_force().z(), 0.0);  // still in flight
  (void)d.read(6 * ms);
  EXPECT_DOUBLE_EQ(d.applied_force().z(), 1.0);
  // The position read is 3 ms old and on the encoder's grid.
  for (int k = 7; k <= 300; ++k) (void)d.read(k * ms);
  const DeviceSample s = d.read(301 * ms);
  const double counts = s.position.z() / 1e-4;
  EXPECT_NEAR(counts, std::round(counts), 1e-9);
  EXPECT_LT(s.position.z(), d.position().z());
  EXPECT_GT(d.position().z() - s.position.z(), 0.003 * d.velocity().z() - 1e-4 - 1e-6);
  // The output limit binds (12 N asked, 2 N given), after the delay.
  w.force = Eigen::Vector3d(12, 0, 0);
  d.write(w, 301 * ms);
  (void)d.read(307 * ms);
  EXPECT_NEAR(d.applied_force().norm(), 2.0, 1e-12);
  d.stop(308 * ms);
  EXPECT_EQ(d.applied_force().norm(), 0.0);
  DeviceModelParams bad = free_device();
  bad.mass = 0;
  EXPECT_THROW(DeviceModel{bad}, InputError);
}

// A wall trial on the plain spring floor (no virtual damping, B = 0), with the passivity
// controller off: the sampled wall alone against the device's damping.
RuntimeConfig wall_config(double rate_hz, bool passivity) {
  RuntimeConfig c;
  c.rate_hz = rate_hz;
  c.inline_query = true;
  c.safety.f_max = 1000;
  c.safety.max_force_rate = 1e9;
  c.safety.ramp_time = 0;
  c.safety.passivity.enabled = passivity;
  return c;
}

DeviceModelParams wall_device(double delay_each_way, double hand_damping) {
  DeviceModelParams p;
  p.mass = 0.2;
  p.damping = 2.0;
  p.delay_up = p.delay_down = delay_each_way;
  p.hand.damping = hand_damping;
  p.hand.push = Eigen::Vector3d(0, 0, -5.0);
  p.initial_position = Eigen::Vector3d(0, 0, 0.0005);
  return p;
}

bool stable_at(double k, double rate_hz, double delay_each_way, double hand_damping) {
  DeviceModel device(wall_device(delay_each_way, hand_damping));
  return run_wall_trial(device, std::make_unique<test::FloorRenderer>(k), wall_config(rate_hz, false)).stable;
}

// Largest stable stiffness by bisection in log space between predicted / 4 and predicted * 4.
double limit_stiffness(double predicted, const std::function<bool(double)>& stable) {
  double lo = predicted / 4, hi = predicted * 4;
  EXPECT_TRUE(stable(lo)) << "not stable at " << lo << " N/m";
  EXPECT_FALSE(stable(hi)) << "stable at " << hi << " N/m";
  for (int i = 0; i < 12; ++i) {
    const double mid = std::sqrt(lo * hi);
    (stable(mid) ? lo : hi) = mid;
  }
  return std::sqrt(lo * hi);
}

struct LimitCase {
  double rate_hz, delay_each_way, hand_damping;
};

class SampledWallLimit : public ::testing::TestWithParam<LimitCase> {};

// b_total > K (T/2 + d): K_max = b_total / (T/2 + d), d the round-trip transport delay.
TEST_P(SampledWallLimit, MatchesColgateSchenkelWithin20Percent) {
  const LimitCase c = GetParam();
  const double T = 1.0 / c.rate_hz, b = 2.0 + c.hand_damping;
  const double predicted = b / (T / 2 + 2 * c.delay_each_way);
  const double measured = limit_stiffness(
      predicted, [&](double k) { return stable_at(k, c.rate_hz, c.delay_each_way, c.hand_damping); });
  EXPECT_NEAR(measured / predicted, 1.0, 0.2) << "measured " << measured << " N/m, predicted " << predicted;
}

INSTANTIATE_TEST_SUITE_P(Cases, SampledWallLimit,
                         ::testing::Values(LimitCase{1000, 0, 0}, LimitCase{2000, 0, 0}, LimitCase{1000, 0, 1.0},
                                           LimitCase{1000, 0.001, 0}),
                         [](const ::testing::TestParamInfo<LimitCase>& i) {
                           const LimitCase& c = i.param;
                           return std::to_string(int(c.rate_hz)) + "Hz_delay" +
                                  std::to_string(int(c.delay_each_way * 1e6)) + "us_hand" +
                                  std::to_string(int(c.hand_damping * 10)) + "dNsm";
                         });

// Above the limit with a 5 ms round trip (2.5 ms each way; limit 364 N/m, wall 1000 N/m): the
// oscillation grows without the controller; with it (the observer pairing each force with the
// motion a round trip later) the contact settles, within the damping cap.
TEST(PassivityOnDelayedWall, OscillationGrowsWithoutAndDecaysWith) {
  const double k = 1000;
  DeviceModel off_device(wall_device(0.0025, 0));
  const WallTrialResult off =
      run_wall_trial(off_device, std::make_unique<test::FloorRenderer>(k), wall_config(1000, false));
  EXPECT_FALSE(off.stable);
  EXPECT_GT(off.last_amplitude, off.first_amplitude);
  EXPECT_GT(off.last_amplitude, 0.005);   // bouncing off the wall, centimetres
  EXPECT_LT(off.min_energy, -1.0);        // joules generated by the delayed wall
  DeviceModel on_device(wall_device(0.0025, 0));
  const RuntimeConfig on_config = wall_config(1000, true);
  const WallTrialResult on = run_wall_trial(on_device, std::make_unique<test::FloorRenderer>(k), on_config);
  EXPECT_TRUE(on.stable);
  EXPECT_LT(on.last_amplitude, 0.2 * on.first_amplitude);
  EXPECT_GT(on.min_energy, -0.01);
  EXPECT_GT(on.passivity_ticks, 100u);
  EXPECT_LE(on.peak_damping, kDefaultPassivityMaxDamping);  // the device model gives no cap of its own
  EXPECT_NEAR(on.mean_depth, 5.0 / k, 2e-4);  // holds the hand's 5 N on the wall's spring
  // The round trip is what makes it work: told there is no delay, the observer pairs each force
  // with the wrong motion, sees a passive wall and the oscillation grows as without it.
  DeviceModelParams hidden = wall_device(0.0025, 0);
  struct DelayUnknown final : HapticDevice {
    explicit DelayUnknown(const DeviceModelParams& p) : inner(p), info_(inner.info()) { info_.transport_delay = 0; }
    const DeviceInfo& info() const noexcept override { return info_; }
    void start(Nanos now) override { inner.start(now); }
    DeviceSample read(Nanos now) noexcept override { return inner.read(now); }
    void write(const Wrench& w, Nanos now) noexcept override { inner.write(w, now); }
    void stop(Nanos now) noexcept override { inner.stop(now); }
    DeviceModel inner;
    DeviceInfo info_;
  } unknown(hidden);
  const WallTrialResult blind = run_wall_trial(unknown, std::make_unique<test::FloorRenderer>(k), on_config);
  EXPECT_FALSE(blind.stable);
  EXPECT_GT(blind.last_amplitude, 0.005);
}

TEST(WallTrace, JudgesDecayGrowthRestAndLimitCycle) {
  const WallTrialOptions o;
  auto trace = [&](const std::function<double(double)>& z) {
    std::vector<double> t, h;
    for (int i = 0; i < 3000; ++i) {
      t.push_back(i * 1e-3);
      h.push_back(z(i * 1e-3));
    }
    WallTrialResult r;
    judge_wall_trace(t, h, o, r);
    return r;
  };
  const double w = 2 * M_PI * 20;
  const WallTrialResult decaying = trace([&](double t) { return -0.001 + 1e-3 * std::exp(-t) * std::sin(w * t); });
  EXPECT_TRUE(decaying.stable);
  EXPECT_NEAR(decaying.growth, std::exp(-2.25), 0.01);  // windows 0.5-0.75 s and 2.75-3.0 s
  EXPECT_NEAR(decaying.mean_depth, 0.001, 1e-4);
  EXPECT_FALSE(trace([&](double t) { return 1e-4 * std::exp(t) * std::sin(w * t); }).stable);
  EXPECT_FALSE(trace([&](double t) { return 0.01 * std::abs(std::sin(w * t)); }).stable);  // bouncing
  EXPECT_TRUE(trace([&](double) { return -0.002; }).stable);                              // at rest
}

TEST(AdmittanceController, VirtualToolIsAMassDamper) {
  AdmittanceParams p;
  p.mass = 2.0;
  p.damping = 4.0;
  RobotSafetyParams free;  // limits far above this test's motion
  free.max_speed = 10;
  free.max_acceleration = 100;
  AdmittanceController a(p, free);
  a.reset(Eigen::Vector3d(1, 2, 3));
  for (int k = 0; k < 5000; ++k) (void)a.step(Eigen::Vector3d(2, 0, 0), Eigen::Vector3d(0, 0, -1), 1e-3);
  EXPECT_NEAR(a.setpoint().velocity.x(), 0.5, 1e-4);   // F / b, after 10 time constants m / b
  EXPECT_NEAR(a.setpoint().velocity.z(), -0.25, 1e-4);
  EXPECT_DOUBLE_EQ(a.setpoint().position.y(), 2.0);
  const Eigen::Vector3d before = a.setpoint().position;
  (void)a.step(Eigen::Vector3d::Constant(NAN), Eigen::Vector3d::Zero(), 1e-3);  // ignored force
  EXPECT_TRUE(a.setpoint().position.allFinite());
  EXPECT_GT((a.setpoint().position - before).norm(), 0.0);  // it coasts
}

// Rotation (a 6-DoF handle): a wrist torque turns the virtual tool about its axis at tau / b_r,
// the rendered torque adds to it, and the angular speed limit binds.
TEST(AdmittanceController, VirtualToolTurnsUnderTheTorque) {
  AdmittanceParams p;  // 0.015 kg m^2, 0.15 N m s/rad: 0.15 s
  AdmittanceController a(p);
  const Eigen::Quaterniond start(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()));
  a.reset(Eigen::Vector3d::Zero(), start);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero(), tau(0, 0, 0.3);
  double turned = 0;
  for (int k = 0; k < 2000; ++k) {
    (void)a.step(zero, tau, zero, zero, 1e-3);
    turned += a.setpoint().angular_velocity.z() * 1e-3;
  }
  EXPECT_NEAR(a.setpoint().angular_velocity.z(), 0.3 / 0.15, 1e-3);  // 2 rad/s
  EXPECT_NEAR(a.setpoint().angular_velocity.head<2>().norm(), 0.0, 1e-12);
  // The orientation is the start turned about the world's z by the integrated angle.
  const Eigen::Quaterniond expected = Eigen::Quaterniond(Eigen::AngleAxisd(turned, Eigen::Vector3d::UnitZ())) * start;
  EXPECT_LT(a.setpoint().orientation.angularDistance(expected), 1e-9);
  EXPECT_NEAR(a.setpoint().position.norm(), 0.0, 1e-15);
  // The environment's torque against the wrist's holds the tool still.
  AdmittanceController b(p);
  b.reset(Eigen::Vector3d::Zero());
  for (int k = 0; k < 500; ++k) (void)b.step(zero, tau, zero, -tau, 1e-3);
  EXPECT_EQ(b.setpoint().angular_velocity, Eigen::Vector3d::Zero());
  // 1 N m asks for 6.7 rad/s: held to the 3 rad/s limit.
  AdmittanceController c(p);
  c.reset(Eigen::Vector3d::Zero());
  for (int k = 0; k < 2000; ++k) (void)c.step(zero, Eigen::Vector3d(1, 0, 0), zero, zero, 1e-3);
  EXPECT_NEAR(c.setpoint().angular_velocity.norm(), RobotSafetyParams{}.max_angular_speed, 1e-9);
  EXPECT_TRUE(c.limited());
  // Braking stops the turn at the angular acceleration limit.
  int ticks = 0;
  while (!c.at_rest() && ticks < 10000) (void)c.brake(1e-3), ++ticks;
  EXPECT_NEAR(ticks * 1e-3, RobotSafetyParams{}.max_angular_speed / RobotSafetyParams{}.max_angular_acceleration, 2e-3);
}

// The admittance loop: the hand pushes with 5 N toward the plane z = 0; the device's position
// servo follows the virtual tool, which the wall stops.
DeviceModelParams admittance_device() {
  DeviceModelParams p = wall_device(0, 0);
  p.causality = Causality::kAdmittance;
  p.mass = 2.0;       // a robot, not a stylus
  p.damping = 2.0;
  p.hand.stiffness = 300;  // the hand's grip, anchored where the device starts
  p.hand.damping = 3;
  p.hand_anchor = p.initial_position;
  return p;
}

WallTrialResult admittance_trial(double k, DeviceModel& device) {
  RuntimeConfig c = wall_config(1000, true);
  c.control.mode = ControlMode::kAdmittance;
  c.control.admittance.mass = 1.0;
  c.control.admittance.damping = 20.0;
  c.control.robot.tare_time = 0;  // the hand pushes from the first tick: nothing to tare
  return run_wall_trial(device, std::make_unique<test::FloorRenderer>(k), c);
}

TEST(AdmittanceControl, ToolStopsAtTheSurfaceAndTheWallBalancesTheHand) {
  // 10 times the impedance limit of this device and hand at 1 kHz: 2 (b + b_hand) / T = 10,000 N/m.
  const double k = 1e5;
  DeviceModel device(admittance_device());
  const WallTrialResult r = admittance_trial(k, device);
  EXPECT_TRUE(r.stable) << r.first_amplitude << " -> " << r.last_amplitude;
  // At rest the hand pushes 5 N less its spring (anchored 0.5 mm above, it pulls back), and the
  // virtual tool's depth times k answers it; the device sits deeper by its position servo's
  // compliance (hand / position_gain).
  // (The log's last ticks are the stop ramp: look at the last tick before the stop.)
  std::size_t i = 0;
  while (i + 1 < r.time.size() && r.time[i + 1] < WallTrialOptions{}.duration - 1e-9) ++i;
  const double hand = 5.0 - 300 * (0.0005 - r.height[i]);
  EXPECT_NEAR(r.force[i], hand, 0.01 * hand);  // the wall's reaction, upward, equals the hand's push
  const double servo = admittance_device().position_gain;
  EXPECT_NEAR(r.height[i], -(hand / k + hand / servo), 0.05 * hand / k);  // 72 um inside
  EXPECT_LT(std::abs(r.height[i] - r.height[i - 100]), 1e-7);  // at rest
  // The impedance device of the same mass and damping against the same wall bounces.
  DeviceModelParams imp = admittance_device();
  imp.causality = Causality::kImpedance;
  DeviceModel impedance(imp);
  EXPECT_FALSE(run_wall_trial(impedance, std::make_unique<test::FloorRenderer>(k), wall_config(1000, false)).stable);
}

TEST(AdmittanceControl, RefusedOnAnImpedanceDevice) {
  DeviceModel device(wall_device(0, 0));
  RuntimeConfig c = wall_config(1000, true);
  c.control.mode = ControlMode::kAdmittance;
  EXPECT_THROW((void)run_wall_trial(device, std::make_unique<test::FloorRenderer>(1000), c), InputError);
}

// And the reverse (issue 73, item 1): an admittance-type device does not apply a commanded force,
// so impedance control on it is refused, with the option that fixes it named.
TEST(AdmittanceControl, ImpedanceControlRefusedOnAnAdmittanceDevice) {
  DeviceModel device(admittance_device());
  try {
    (void)run_wall_trial(device, std::make_unique<test::FloorRenderer>(1000), wall_config(1000, true));
    FAIL() << "impedance control on an admittance-type device was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--control admittance"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

struct PlaneTrial {
  WallTrialResult r;
  double contact_height = 0;  // the setpoint's height at the first tick with force, m
};

// Issue 73's targets, in process (a shortcut: DeviceModel's delay lines stand for the ROS link,
// no network): the proxy at 20x the default coupling stiffness on a Gaussian plane from synth,
// the hand pushing 10 N, a 2 ms round trip (1 ms each way), passivity on. The tool starts with its
// surface `start` m above the plane's centres (z = 0), on the proxy's `surface`.
PlaneTrial press_plane(ControlMode control, ProxySurface surface, double start) {
  static const CollisionWorld world = [] {
    SynthParams sp;
    sp.spacing = 0.004;
    return CollisionWorld::build(make_synthetic_scene(AnalyticShape(ShapeKind::kPlane), sp).scene, WorldConfig{});
  }();
  const double radius = 0.005;
  DeviceModelParams dp = control == ControlMode::kAdmittance ? StabilityOptions::default_admittance_device()
                                                             : StabilityOptions::default_impedance_device();
  dp.delay_up = dp.delay_down = 0.001;
  dp.hand.push = Eigen::Vector3d(0, 0, -10.0);
  dp.initial_position = Eigen::Vector3d(0.013, 0.021, radius + start);
  DeviceModel device(dp);
  RuntimeConfig c;
  c.tool.semi_axes = Eigen::Vector3d::Constant(radius);
  ProxyModelSpec spec;
  spec.params.surface = surface;
  spec.params.stiffness = 20 * ProxyParams{}.stiffness;
  c.renderer = spec;
  c.safety.ramp_time = 0;
  c.safety.f_max = 50;
  c.control.mode = control;
  c.control.admittance = StabilityOptions{}.virtual_tool;
  c.control.robot.tare_time = 0;  // the hand pushes from the first tick
  c.control.robot.dead_band = 0;
  WallTrialOptions judge;
  judge.duration = 3.0;
  PlaneTrial t;
  t.r = run_wall_trial(device, make_force_renderer(c.renderer, world), c, judge);
  for (std::size_t i = 0; i < t.r.force.size(); ++i)
    if (t.r.force[i] != 0) {
      t.contact_height = t.r.setpoint[i];
      break;
    }
  return t;
}

// Issue 73's trial as it was measured: on the ellipsoids, the tool starting 0.5 mm above the
// plane's centres, 0.4 mm inside the ellipsoids' shell, so the wall holds 9 N of the hand's 10 N
// from the first tick: a preloaded press, not a step (AdmittanceTargets.AStep... is the step).
TEST(AdmittanceTargets, TwentyTimesTheDefaultCouplingHoldsOnAGaussianPlaneWithATwoMillisecondRoundTrip) {
  const PlaneTrial a = press_plane(ControlMode::kAdmittance, ProxySurface::kEllipsoids, 0.0005);
  ASSERT_GT(a.contact_height, 0.0);
  EXPECT_GT(a.r.force[2], 5.0);  // preloaded (measured 9.1 N two ticks in)
  double deepest = 0;
  for (double z : a.r.setpoint) deepest = std::max(deepest, a.contact_height - z);
  // The wall's reaction over the last 0.25 s against the hand's measured push.
  double force = 0, push = 0;
  int n = 0;
  for (std::size_t i = 0; i < a.r.time.size(); ++i)
    if (a.r.time[i] > a.r.time.back() - 0.25) force += a.r.force[i], push -= a.r.user_force[i], ++n;
  force /= n;
  push /= n;
  const double static_depth = 10.0 / (20 * ProxyParams{}.stiffness);
  std::printf("admittance at 20 kN/m, 2 ms: deepest %.3f mm past first contact (static %.3f), rest amplitude "
              "%.4f mm, reaction %.3f N for a push of %.3f N, lowest energy %.3g mJ\n",
              deepest * 1e3, static_depth * 1e3, a.r.last_amplitude * 1e3, force, push, a.r.min_energy * 1e3);
  EXPECT_TRUE(a.r.stable);
  // A spring under a step force overshoots to twice its static depth when undamped (here 0.5 mm
  // static at 10 N on 20 kN/m, so the "0.5 mm past the surface" cannot hold with this
  // push); the virtual tool's approach adds a little, its damping takes a little. Measured: 1.06 mm.
  EXPECT_LT(deepest, 2.2 * static_depth);
  EXPECT_LT(a.r.last_amplitude, 0.05e-3);
  EXPECT_NEAR(force, push, 0.02 * push);
  EXPECT_GT(push, 9.0);
  EXPECT_GE(a.r.min_energy, -1e-6);
  // The impedance device (0.2 kg, 2 N s/m) at the same stiffness and delay goes unstable.
  const PlaneTrial i = press_plane(ControlMode::kImpedance, ProxySurface::kEllipsoids, 0.0005);
  std::printf("impedance at 20 kN/m, 2 ms: amplitude %.3f -> %.3f mm, stable %d\n", i.r.first_amplitude * 1e3,
              i.r.last_amplitude * 1e3, int(i.r.stable));
  EXPECT_FALSE(i.r.stable);
}

// The same press as a step: the tool starts 1 mm above the plane's centres, clear of either solid
// (0.6 mm above the ellipsoids' shell, 1 mm above the seen surface), and meets the wall at the
// speed the hand's 10 N gives it. The 2 ms round trip gives energy back at the impact on either
// solid: the observer learns of it two ticks late, and the coupling's 20 kN/m asks for more
// damping than the passivity controller's 20 N s/m cap. The controller pays the deficit back as
// the tool moves on, so the tool settles slowly (over seconds: the trial's judge reads that slow
// settling as an amplitude of 0.05-0.1 mm, and the ellipsoids' tool, sliding into a dimple between
// discs, ends 1.5 mm past first contact against a static 0.5 mm).
// Issue 73's "no press cycle gives energy back" holds for the preloaded press above, not for a
// step. Measured, lowest observer energy: ellipsoids -0.075 mJ, seen -1.16 mJ (the seen solid's
// tool travels 1 mm to the wall, the ellipsoids' 0.6 mm).
TEST(AdmittanceTargets, AStepOntoEitherSolidHoldsAtTheHandsForce) {
  for (ProxySurface surface : {ProxySurface::kEllipsoids, ProxySurface::kSeen}) {
    const PlaneTrial a = press_plane(ControlMode::kAdmittance, surface, 0.001);
    const std::string name(proxy_surface_name(surface));
    ASSERT_GT(a.contact_height, 0.0) << name;
    ASSERT_GT(a.r.time.size(), 100u) << name;
    EXPECT_EQ(a.r.force[2], 0.0) << name;  // a step: nothing held until the tool arrives
    double deepest = 0, force = 0, push = 0;
    int n = 0;
    for (double z : a.r.setpoint) deepest = std::max(deepest, a.contact_height - z);
    for (std::size_t i = 0; i < a.r.time.size(); ++i)
      if (a.r.time[i] > a.r.time.back() - 0.25) force += a.r.force[i], push -= a.r.user_force[i], ++n;
    force /= n;
    push /= n;
    std::printf("a step onto the %s: deepest %.3f mm past first contact, rest amplitude %.4f mm (first %.4f), "
                "reaction %.3f N for %.3f N, lowest energy %.3g mJ\n", name.c_str(), deepest * 1e3,
                a.r.last_amplitude * 1e3, a.r.first_amplitude * 1e3, force, push, a.r.min_energy * 1e3);
    EXPECT_NEAR(force, push, 0.02 * push) << name;
    EXPECT_GT(a.r.min_energy, -3e-3) << name;  // what the impact gives back: a few mJ at most
  }
}

}  // namespace
}  // namespace gshaptics
