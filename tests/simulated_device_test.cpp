// The simulated device in real time: it follows the probe trajectory through the hand, its
// state does not depend on how often it is read, and the commanded wrench acts on it.

#include "gshaptics/device/simulated_device.h"

#include <gtest/gtest.h>

namespace gshaptics {
namespace {

ProbeTrajectory straight_line() {
  // 1 s at rest at the origin, then to (0.2, 0, 0) over 1 s, then rest.
  return ProbeTrajectory({{0.0, Eigen::Vector3d::Zero()}, {1.0, Eigen::Vector3d::Zero()},
                          {2.0, Eigen::Vector3d(0.2, 0, 0)}, {4.0, Eigen::Vector3d(0.2, 0, 0)}},
                         {}, 0.01);
}

constexpr Nanos kMs = 1'000'000;

TEST(SimulatedDevice, FollowsTheTrajectoryThroughTheHand) {
  SimulatedDevice d(straight_line());
  d.start(0);
  DeviceSample s;
  for (Nanos t = kMs; t <= 4000 * kMs; t += kMs) s = d.read(t);
  EXPECT_NEAR(s.position.x(), 0.2, 0.005);
  EXPECT_NEAR(s.velocity.norm(), 0.0, 0.01);
  EXPECT_EQ(s.sequence, 4000u);
  EXPECT_EQ(s.stamp, 4000 * kMs);
}

// `run --device sim` runs one pass (duration + 0.5 s of rest): its last tick lands exactly on the
// loop's period. The hand must not be sent back to the start there (a 34 N "user force" spike
// in run.png at the last tick, issue 35).
TEST(SimulatedDevice, TheLastTickOfAPassIsNotTheStartOfTheNext) {
  SimulatedDevice d(straight_line());
  d.start(0);
  DeviceSample s;
  double peak_late = 0;
  for (Nanos t = kMs; t <= 4500 * kMs; t += kMs) {
    s = d.read(t);
    if (t > 3000 * kMs) peak_late = std::max(peak_late, s.user_force.norm());
  }
  EXPECT_LT(peak_late, 0.5) << "the hand pulled at the end of the pass";
  EXPECT_NEAR(s.position.x(), 0.2, 0.005);
}

TEST(SimulatedDevice, StateDoesNotDependOnTheReadRate) {
  SimulatedDevice a(straight_line()), b(straight_line());
  a.start(0);
  b.start(0);
  DeviceSample sa, sb;
  for (Nanos t = kMs; t <= 1500 * kMs; t += kMs) sa = a.read(t);
  for (Nanos t = 10 * kMs; t <= 1500 * kMs; t += 10 * kMs) sb = b.read(t);  // 100 Hz reader
  EXPECT_NEAR((sa.position - sb.position).norm(), 0.0, 1e-12);
  EXPECT_GT(sa.position.x(), 0.01);  // it is moving at 1.5 s
}

TEST(SimulatedDevice, WrenchPushesTheDeviceAndStopZeroesIt) {
  SimulatedDevice d(straight_line());
  d.start(0);
  Wrench w;
  w.force = {0, 0, 10};
  d.write(w, 0);
  DeviceSample s;
  for (Nanos t = kMs; t <= 500 * kMs; t += kMs) s = d.read(t);
  // The hand holds the origin with 600 N/m: a 10 N push moves the device ~1.7 cm up.
  EXPECT_NEAR(s.position.z(), 10.0 / 600.0, 0.002);
  EXPECT_NEAR(s.user_force.z(), -10.0, 0.5);
  d.stop(600 * kMs);
  EXPECT_EQ(d.last_wrench().force, Eigen::Vector3d::Zero());
}

TEST(SimulatedDevice, WorkspaceCoversTheTrajectoryWithMargin) {
  SimulatedDevice d(straight_line());
  const auto& ws = d.info().workspace;
  EXPECT_TRUE(ws.contains(Eigen::Vector3d(0.1, 0, 0)));
  EXPECT_TRUE(ws.contains(Eigen::Vector3d(0.6, 0.4, -0.4)));
  EXPECT_FALSE(ws.contains(Eigen::Vector3d(1.0, 0, 0)));
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

SimulatedDeviceParams robot() {
  SimulatedDeviceParams p;
  p.causality = Causality::kAdmittance;
  return p;
}

// Admittance causality (issue 73, item 2): a robot under a position servo with a force sensor.
// It holds the setpoint against the hand (the servo's stiffness: 10 N moves it 50 um), ignores a
// commanded wrench, and the sensor reads the hand's force on the handle.
TEST(SimulatedDevice, AnAdmittanceRobotTracksItsSetpointAndItsSensorReadsTheHand) {
  SimulatedDevice d(straight_line(), robot());
  EXPECT_TRUE(d.info().admittance);
  EXPECT_EQ(d.info().max_damping, 0.0);  // the virtual tool's cap applies, not the device's
  d.start(0);
  Setpoint sp;
  sp.position = {0, 0, 0.01};  // 1 cm above the hand's target: the hand pulls down with ~6 N
  Wrench w;
  w.force = {0, 0, 100};  // ignored: position-controlled
  DeviceSample s;
  for (Nanos t = kMs; t <= 500 * kMs; t += kMs) {
    d.write_setpoint(sp, t);
    d.write(w, t);
    s = d.read(t);
  }
  const double hand = -600.0 * s.position.z();  // the hand's spring toward its target (z = 0)
  EXPECT_NEAR(s.user_force.z(), hand, 0.05);
  EXPECT_LT(s.user_force.z(), -5.0);
  // Static balance: k_p (x_sp - x) + F_hand = 0.
  const double kp = DeviceModelParams{}.position_gain;
  EXPECT_NEAR(s.position.z(), sp.position.z() + s.user_force.z() / kp, 2e-6);
  EXPECT_NEAR(s.velocity.norm(), 0.0, 1e-4);
  // A new setpoint is followed within the servo's bandwidth (tens of ms).
  sp.position = {0.05, 0, 0.01};
  for (Nanos t = 501 * kMs; t <= 700 * kMs; t += kMs) {
    d.write_setpoint(sp, t);
    s = d.read(t);
  }
  EXPECT_NEAR(s.position.x(), 0.05, 1e-3);
  // A non-finite setpoint is not taken.
  Setpoint bad;
  bad.position = {std::nan(""), 0, 0};
  d.write_setpoint(bad, 700 * kMs);
  EXPECT_EQ(d.last_setpoint().position, sp.position);
  // Stop leaves the robot at rest where it is.
  d.stop(700 * kMs);
  EXPECT_NEAR((d.last_setpoint().position - s.position).norm(), 0.0, 1e-12);
  EXPECT_EQ(d.last_setpoint().velocity, Eigen::Vector3d::Zero());
}

TEST(SimulatedDevice, ImpedanceCausalityGivesItsDampingLimit) {
  SimulatedDevice d(straight_line());
  EXPECT_FALSE(d.info().admittance);
  // Half of m / T: 3 kg over a 1 ms step.
  EXPECT_DOUBLE_EQ(d.info().max_damping, 1500.0);
}

}  // namespace
}  // namespace gshaptics
