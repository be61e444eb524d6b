// One servo tick at a time on a ManualClock, with a scripted device and the real collision
// worker: the hand-off, hold and fade with a stalled worker, the watchdog with a stalled device,
// NaN and far-away poses, the inline mode, deadline misses, the stop ramp and no allocation.

#include "gshaptics/servo/servo_controller.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "support/allocation_counter.h"

namespace gshaptics {
namespace {

constexpr Nanos kMs = 1'000'000;

/// A floor of flat opaque Gaussians at z = 0 over [-1, 1]^2 (world = scene frame).
const CollisionWorld& floor_world() {
  static const CollisionWorld world = [] {
    GaussianScene s;
    std::uint32_t i = 0;
    for (int x = -20; x <= 20; ++x)
      for (int y = -20; y <= 20; ++y)
        s.push_back({0.05f * float(x), 0.05f * float(y), 0.f}, {0.03f, 0.03f, 0.001f}, {1, 0, 0, 0}, 0.9f, i++);
    return CollisionWorld::build(s, WorldConfig{});
  }();
  return world;
}

/// A device whose sample the test sets; it can stall (stop delivering data) and can make its
/// read() take time on the ManualClock.
class ScriptedDevice final : public HapticDevice {
 public:
  explicit ScriptedDevice(ManualClock& clock) : clock_(clock) {
    info_.name = "scripted";
    info_.workspace = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-2), Eigen::Vector3d::Constant(2));
  }
  const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos) override { started = true; }
  DeviceSample read(Nanos now) noexcept override {
    if (!stalled) {
      ++sample.sequence;
      sample.stamp = now;
    }
    clock_.advance(read_cost);
    return sample;
  }
  void write(const Wrench& w, Nanos) noexcept override {
    last = w;
    ++writes;
  }
  void stop(Nanos) noexcept override { stopped = true; }
  void set_renders_torque(bool on) noexcept { info_.renders_torque = on; }

  DeviceSample sample;
  bool stalled = false;
  Nanos read_cost = 0;
  Wrench last;
  int writes = 0;
  bool started = false, stopped = false;

 private:
  ManualClock& clock_;
  DeviceInfo info_;
};

class ServoTick : public ::testing::Test {
 protected:
  void SetUp() override { make({}); }
  void make(SafetyParams safety, double tool_radius = 0.02, ForceParams force = {}, const ToolShape* shape = nullptr) {
    tool_.semi_axes = Eigen::Vector3d::Constant(tool_radius);
    if (shape != nullptr) tool_ = *shape;
    safety_ = safety;
    worker_ = std::make_unique<CollisionWorker>(floor_world(), tool_, force, QueryOptions{}, 1e-3, clock_);
    servo_ = std::make_unique<ServoController>(device_, safety, kMs, poses_, results_, stats_, &log_, clock_);
    device_.sample.position = {0.0, 0.0, 0.012};  // pressing into the floor
    servo_->start(clock_.now());
  }
  /// Advances the clock to the next period and ticks; returns the record of the tick.
  const TickRecord& tick(bool worker_runs, bool inline_mode = false) {
    clock_.advance(kMs);
    const Nanos scheduled = clock_.now();
    servo_->tick(scheduled, inline_mode ? worker_.get() : nullptr);
    if (worker_runs && !inline_mode) worker_->step(poses_, results_);
    return log_.records().back();
  }
  static SafetyParams direct() {  // safety that passes the force model's output unchanged
    SafetyParams p;
    p.ramp_time = 0;
    p.max_force_rate = 1e9;
    return p;
  }

  ManualClock clock_{5 * kNanosPerSecond};
  ScriptedDevice device_{clock_};
  PoseChannel poses_;
  ResultChannel results_;
  RuntimeStats stats_;
  TickLog log_{10000};
  ToolShape tool_;
  SafetyParams safety_;
  std::unique_ptr<CollisionWorker> worker_;
  std::unique_ptr<ServoController> servo_;
};

TEST_F(ServoTick, DecoupledHandOffRendersTheResultOneTickLater) {
  make(direct());
  const TickRecord& first = tick(/*worker_runs=*/true);
  EXPECT_TRUE(first.flags & kFlagNoResult);
  EXPECT_EQ(first.force, Eigen::Vector3d::Zero());
  EXPECT_EQ(device_.last.force, Eigen::Vector3d::Zero());
  const TickRecord& second = tick(true);
  EXPECT_EQ(second.flags, 0u);
  EXPECT_GT(second.counts.contacts, 0u);
  EXPECT_GT(second.force.z(), 0.0);  // the floor pushes the tool up
  EXPECT_NEAR(second.force.x(), 0.0, 1e-9);
  EXPECT_EQ(second.force, second.desired);
  EXPECT_EQ(device_.last.force, second.force);
  EXPECT_NEAR(second.result_age_us, 1000.0, 1e-3);  // answers the previous tick's pose
  EXPECT_EQ(stats_.results_used.load(), 1u);
}

TEST_F(ServoTick, StalledWorkerHoldsThenFadesThenZeroes) {
  make(direct());  // hold 20 ms, fade 20 ms
  tick(true);
  tick(true);
  const double f0 = tick(true).force.z();
  ASSERT_GT(f0, 0.0);
  // Fault: the worker stops. The first tick still gets the result of the step before the stall
  // (age 1 ms); from then on the same result is held and ages by 1 ms per tick.
  double prev = f0;
  for (int k = 1; k <= 45; ++k) {
    const TickRecord& r = tick(/*worker_runs=*/false);
    const double age_ms = r.result_age_us / 1000.0;
    EXPECT_NEAR(age_ms, double(k), 1e-6);
    EXPECT_EQ((r.flags & kFlagHeld) != 0, k > 1) << k;
    if (age_ms <= 20) {
      EXPECT_DOUBLE_EQ(r.force.z(), f0) << k;
    } else if (age_ms < 40) {
      EXPECT_TRUE(r.flags & kFlagFading) << k;
      EXPECT_NEAR(r.force.z(), f0 * (1 - (age_ms - 20) / 20), 1e-9) << k;
      EXPECT_LT(r.force.z(), prev);
    } else {
      EXPECT_TRUE(r.flags & kFlagFaded) << k;
      EXPECT_EQ(r.force, Eigen::Vector3d::Zero()) << k;
    }
    prev = r.force.z();
  }
  EXPECT_EQ(device_.last.force, Eigen::Vector3d::Zero());
  EXPECT_EQ(stats_.fades.load(), 1u);
  EXPECT_EQ(stats_.stale_ticks.load(), 44u);
  // The worker comes back: the force returns at the next tick.
  tick(true);
  EXPECT_GT(tick(true).force.z(), 0.0);
}

TEST_F(ServoTick, StalledDeviceTripsTheWatchdogAndResumeRampsUp) {
  SafetyParams p = direct();
  p.ramp_time = 0.1;
  make(p);
  for (int k = 0; k < 150; ++k) tick(true);
  ASSERT_GT(device_.last.force.z(), 0.0);
  device_.stalled = true;  // fault: the driver stops delivering data
  int watchdog_tick = -1;
  for (int k = 1; k <= 30; ++k) {
    const TickRecord& r = tick(true);
    if (k <= 10) {
      EXPECT_GT(r.force.z(), 0.0) << k;  // within the 10 ms timeout
    } else {
      EXPECT_TRUE(r.flags & kFlagWatchdog) << k;
      EXPECT_EQ(r.force, Eigen::Vector3d::Zero()) << k;
      if (watchdog_tick < 0) watchdog_tick = k;
    }
  }
  EXPECT_EQ(watchdog_tick, 11);
  EXPECT_EQ(device_.last.force, Eigen::Vector3d::Zero());
  EXPECT_EQ(stats_.watchdog_ticks.load(), 20u);
  // No pose went to the worker while the device was stalled past the timeout.
  EXPECT_FALSE(worker_->step(poses_, results_));
  device_.stalled = false;  // data returns: the soft start re-arms
  const double f1 = tick(true).force.z();
  EXPECT_EQ(f1, 0.0);
  for (int k = 0; k < 49; ++k) tick(true);
  const TickRecord& half = tick(true);  // 50 ms into a 100 ms ramp
  EXPECT_TRUE(half.flags & kFlagRamping);
  EXPECT_NEAR(half.force.z(), 0.5 * half.desired.z(), 0.02 * half.desired.z());
}

TEST_F(ServoTick, NanPoseIsDroppedAndZeroesTheForce) {
  make(direct());
  for (int k = 0; k < 5; ++k) tick(true);
  ASSERT_GT(device_.last.force.z(), 0.0);
  const std::uint64_t steps_before = worker_->steps();
  device_.sample.position.y() = std::nan("");  // fault: NaN from the device
  for (int k = 0; k < 3; ++k) {
    const TickRecord& r = tick(true);
    EXPECT_TRUE(r.flags & kFlagInvalidPose);
    EXPECT_EQ(r.force, Eigen::Vector3d::Zero());
  }
  EXPECT_EQ(worker_->steps(), steps_before);  // the NaN pose never reached the query
  EXPECT_EQ(stats_.invalid_pose_ticks.load(), 3u);
  device_.sample.orientation.coeffs().setZero();  // a zero quaternion is invalid too
  device_.sample.position.y() = 0;
  EXPECT_TRUE(tick(true).flags & kFlagInvalidPose);
}

TEST_F(ServoTick, PoseFarOutsideTheSceneGivesNoContactAndZeroForce) {
  make(direct());
  for (int k = 0; k < 5; ++k) tick(true);
  device_.sample.position = {1e6, -3e5, 2e4};  // fault: a wild pose
  const TickRecord& r = tick(true);
  EXPECT_TRUE(r.flags & kFlagOutsideWorkspace);
  EXPECT_EQ(r.force, Eigen::Vector3d::Zero());
  const TickRecord& r2 = tick(true);  // the worker answered it: no contact there
  EXPECT_EQ(r2.counts.contacts, 0u);
  EXPECT_EQ(r2.counts.candidates, 0u);
  EXPECT_EQ(r2.desired, Eigen::Vector3d::Zero());
  EXPECT_EQ(stats_.outside_workspace_ticks.load(), 2u);
}

TEST_F(ServoTick, InlineModeRendersTheSameTicksPose) {
  make(direct());
  for (int k = 0; k < 3; ++k) {
    const TickRecord& r = tick(false, /*inline_mode=*/true);
    EXPECT_EQ(r.flags, 0u);
    EXPECT_EQ(r.result_age_us, 0.0f);
    EXPECT_GT(r.force.z(), 0.0);
  }
}

TEST_F(ServoTick, DeadlineMissCountedWhenTheTickOverrunsItsPeriod) {
  make(direct());
  tick(true);
  device_.read_cost = 2 * kMs;  // fault: a driver call that takes two periods
  tick(true);
  EXPECT_EQ(stats_.deadline_misses.load(), 1u);
  device_.read_cost = 0;
  tick(true);
  EXPECT_EQ(stats_.deadline_misses.load(), 1u);
  EXPECT_GE(log_.records().back().jitter_us, 0.0f);
}

TEST_F(ServoTick, StopRampsTheForceDownAndLeavesTheDeviceAtZero) {
  SafetyParams p = direct();
  p.max_force_rate = 500;  // 0.5 N per tick, so the ramp takes several ticks
  ForceParams stiff;
  stiff.k_base = 2.0;
  make(p, 0.03, stiff);
  for (int k = 0; k < 100; ++k) tick(true);
  const double f = device_.last.force.norm();
  ASSERT_GT(f, 1.0);
  servo_->request_stop();
  int ticks = 0;
  double prev = f;
  while (!servo_->force_released() && ticks < 1000) {
    const TickRecord& r = tick(true);
    EXPECT_LE(r.force.norm(), prev + 1e-12);
    prev = r.force.norm();
    ++ticks;
  }
  EXPECT_EQ(ticks, int(std::ceil(f / 0.5 - 1e-9)));
  servo_->finish(clock_.now());
  EXPECT_TRUE(device_.stopped);
  EXPECT_EQ(device_.last.force, Eigen::Vector3d::Zero());
}

TEST_F(ServoTick, TickAndWorkerStepAllocateNothing) {
  make(SafetyParams{});
  for (int k = 0; k < 20; ++k) tick(true);  // warm up
  const std::size_t before = test::allocation_count();
  for (int k = 0; k < 600; ++k) {
    device_.sample.position.z() = 0.05 - 0.0001 * k;  // from free space into the floor
    device_.stalled = k % 97 == 50;
    tick(k % 5 != 0);
  }
  const std::size_t after = test::allocation_count();
  EXPECT_EQ(after - before, 0u);
  EXPECT_GT(log_.records().back().counts.contacts, 0u);
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

// A compound tool's torque through the servo step: a device that renders force only gets none
// (and the run counts the ticks), a 6-DoF device gets the safety layer's torque.
TEST_F(ServoTick, TorqueGoesToTorqueDevicesAndIsCountedWhereDropped) {
  // Two spheres 10 cm apart on the tool's x axis, the tool tilted so only the +x one presses.
  CompoundTool bell;
  bell.count = 2;
  bell.parts[0].offset = {-0.05, 0, 0};
  bell.parts[1].offset = {0.05, 0, 0};
  bell.parts[0].semi_axes = bell.parts[1].semi_axes = Eigen::Vector3d::Constant(0.02);
  const ToolShape shape = tool_shape_for(bell);
  SafetyParams p = direct();
  p.max_torque_rate = 1e9;
  for (bool renders : {false, true}) {
    device_.set_renders_torque(renders);
    make(p, 0.02, {}, &shape);
    device_.sample.position = {0.0, 0.0, 0.03};
    device_.sample.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()));
    const std::uint64_t dropped0 = stats_.torque_dropped_ticks.load();
    TickRecord r;
    for (int k = 0; k < 5; ++k) r = tick(/*worker_runs=*/true, /*inline_mode=*/true);
    ASSERT_GT(r.force.z(), 0.0) << renders;
    // The +x sphere (at x ~ +0.046) pushes up: torque about -y.
    EXPECT_LT(r.desired.z(), 1e9);
    if (renders) {
      EXPECT_LT(device_.last.torque.y(), 0.0);
      EXPECT_EQ(device_.last.torque, r.torque);
      EXPECT_EQ(stats_.torque_dropped_ticks.load(), dropped0);
      EXPECT_FALSE(r.flags & kFlagTorqueDropped);
    } else {
      EXPECT_EQ(device_.last.torque, Eigen::Vector3d::Zero());
      EXPECT_EQ(r.torque, Eigen::Vector3d::Zero());
      EXPECT_GE(stats_.torque_dropped_ticks.load(), dropped0 + 5);
      EXPECT_TRUE(r.flags & kFlagTorqueDropped);
    }
    EXPECT_GT(stats_.peak_torque.load(), 0.0);
  }
  // The compound tick allocates nothing either (inline: worker step inside the tick).
  const std::size_t before = test::allocation_count();
  for (int k = 0; k < 300; ++k) {
    device_.sample.position.z() = 0.06 - 0.0001 * k;
    device_.sample.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.4 + 0.001 * k, Eigen::Vector3d::UnitY()));
    tick(true, true);
  }
  EXPECT_EQ(test::allocation_count() - before, 0u);
  EXPECT_GT(log_.records().back().counts.contacts, 0u);
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

/// An admittance-type device (a robot with a force sensor at its handle) whose sample and sensor
/// reading the test sets; it records every setpoint written and can stall.
class ScriptedRobot final : public HapticDevice {
 public:
  ScriptedRobot() {
    info_.name = "scripted robot";
    info_.admittance = true;
    info_.workspace = Eigen::AlignedBox3d(Eigen::Vector3d(-0.5, -0.5, 0.05), Eigen::Vector3d(0.5, 0.5, 1.0));
    info_.force_sensor_range = 100;
  }
  const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos) override {}
  DeviceSample read(Nanos now) noexcept override {
    if (!stalled) {
      ++sample.sequence;
      sample.stamp = now;
    }
    return sample;
  }
  void write(const Wrench&, Nanos) noexcept override {}
  void write_setpoint(const Setpoint& s, Nanos) noexcept override {
    setpoint = s;
    ++setpoints;
  }
  void stop(Nanos) noexcept override { stopped = true; }

  DeviceSample sample;
  bool stalled = false, stopped = false;
  Setpoint setpoint;
  int setpoints = 0;

 private:
  DeviceInfo info_;
};

/// The servo step driving ScriptedRobot under admittance control, far above the floor (free
/// space), tick by tick on a ManualClock.
class RobotTick : public ::testing::Test {
 protected:
  void SetUp() override { make(RobotSafetyParams{}); }
  void make(const RobotSafetyParams& robot) {
    control_.mode = ControlMode::kAdmittance;
    control_.robot = robot;
    tool_.semi_axes = Eigen::Vector3d::Constant(0.02);
    worker_ = std::make_unique<CollisionWorker>(floor_world(), tool_, ForceParams{}, QueryOptions{}, 1e-3, clock_);
    robot_.sample.position = {0, 0, 0.5};
    servo_ = std::make_unique<ServoController>(robot_, SafetyParams{}, kMs, poses_, results_, stats_, &log_, clock_,
                                               nullptr, control_);
    servo_->start(clock_.now());
  }
  const TickRecord& tick() {
    clock_.advance(kMs);
    servo_->tick(clock_.now(), worker_.get());
    // The robot follows its setpoint exactly (an ideal position servo).
    robot_.sample.position = robot_.setpoint.position;
    robot_.sample.velocity = robot_.setpoint.velocity;
    return log_.records().back();
  }
  void ticks(int n) {
    for (int k = 0; k < n; ++k) tick();
  }

  ManualClock clock_{5 * kNanosPerSecond};
  ScriptedRobot robot_;
  ControlParams control_;
  PoseChannel poses_;
  ResultChannel results_;
  RuntimeStats stats_;
  TickLog log_{20000};
  ToolShape tool_;
  std::unique_ptr<CollisionWorker> worker_;
  std::unique_ptr<ServoController> servo_;
};

// Issue 73, item 4: the setpoint's acceleration, speed and workspace are limited in the step.
TEST_F(RobotTick, SetpointKeepsToTheRobotsAccelerationSpeedAndWorkspace) {
  const RobotSafetyParams lim;
  ticks(int(lim.tare_time * 1000) + 2);  // the tare: the virtual tool holds still
  EXPECT_EQ(robot_.setpoint.velocity, Eigen::Vector3d::Zero());
  robot_.sample.user_force = {90, 0, 0};  // 30 m/s^2 on the 3 kg virtual tool
  Eigen::Vector3d v_prev = robot_.setpoint.velocity;
  bool limited = false;
  for (int k = 0; k < 3000; ++k) {
    const TickRecord& r = tick();
    const Eigen::Vector3d v = robot_.setpoint.velocity;
    ASSERT_LE((v - v_prev).norm(), lim.max_acceleration * 1e-3 * (1 + 1e-9)) << k << " v " << v.transpose() << " prev " << v_prev.transpose() << " x " << robot_.setpoint.position.transpose();
    ASSERT_LE(v.norm(), lim.max_speed * (1 + 1e-9)) << k;
    ASSERT_TRUE(robot_.info().workspace.contains(robot_.setpoint.position)) << k;
    limited |= (r.flags & kFlagSetpointLimited) != 0;
    v_prev = v;
  }
  EXPECT_TRUE(limited);
  // Pushed against the workspace's wall at x = 0.5: held there, not moving out.
  EXPECT_DOUBLE_EQ(robot_.setpoint.position.x(), 0.5);
  EXPECT_EQ(robot_.setpoint.velocity.x(), 0.0);
  EXPECT_GT(servo_->safety().params().f_max, 0.0);
  EXPECT_GT(stats_.setpoint_limited_ticks.load(), 100u);
}

// A stale device holds the setpoint still: the virtual tool brakes to rest within the watchdog
// time plus speed / deceleration, and setpoints keep coming.
TEST_F(RobotTick, AStaleDeviceBringsTheRobotToRestWithinTheWatchdogAndTheBrakingTime) {
  ticks(110);
  robot_.sample.user_force = {0, 12, 0};
  ticks(300);  // toward 12 N / 20 N s/m = 0.6 m/s
  const double v0 = robot_.setpoint.velocity.norm();
  ASSERT_GT(v0, 0.3);
  robot_.stalled = true;
  const RobotSafetyParams lim;
  const double bound = SafetyParams{}.device_timeout + v0 / lim.max_acceleration + 2e-3;
  const int written = robot_.setpoints;
  int k = 0;
  while (!robot_.setpoint.velocity.isZero(0) && k < 5000) {
    const TickRecord& r = tick();
    if (robot_.setpoint.velocity.norm() < v0 * 0.999) {
      EXPECT_NE(r.flags & kFlagBraking, 0u) << k;
    }
    ++k;
  }
  EXPECT_LE(k * 1e-3, bound);
  EXPECT_GE(k * 1e-3, v0 / lim.max_acceleration - 1e-3);  // no faster than the deceleration limit
  EXPECT_EQ(robot_.setpoints - written, k);  // a setpoint every tick
  const Eigen::Vector3d rest = robot_.setpoint.position;
  ticks(50);  // held still while stale
  EXPECT_EQ(robot_.setpoint.position, rest);
  // Fresh data again: the virtual tool moves on from where it rests (not from a reset).
  robot_.stalled = false;
  robot_.sample.user_force.setZero();
  ticks(5);
  EXPECT_NEAR((robot_.setpoint.position - rest).norm(), 0.0, 1e-12);
}

// The sensor is tared at start (a bias of the sensor does not move the robot), readings within
// the dead band do nothing, and a reading at the sensor's range stops the run with the robot at rest.
TEST_F(RobotTick, TareDeadBandAndASaturatedSensorStopsTheRunAtRest) {
  robot_.sample.user_force = {1.5, -0.7, 2.0};  // the sensor's bias, nobody holding the handle
  ticks(400);
  EXPECT_NEAR((robot_.setpoint.position - Eigen::Vector3d(0, 0, 0.5)).norm(), 0.0, 1e-12);
  robot_.sample.user_force += Eigen::Vector3d(0.2, 0, 0);  // within the 0.3 N dead band
  ticks(200);
  EXPECT_NEAR((robot_.setpoint.position - Eigen::Vector3d(0, 0, 0.5)).norm(), 0.0, 1e-12);
  robot_.sample.user_force += Eigen::Vector3d(3.0, 0, 0);  // a push: the robot moves along +x
  ticks(200);
  EXPECT_GT(robot_.setpoint.position.x(), 0.01);
  EXPECT_NEAR(robot_.setpoint.position.y(), 0.0, 1e-12);
  EXPECT_FALSE(servo_->faulted());
  // Saturated: the run is to stop, the virtual tool brakes, and the run ends at rest.
  robot_.sample.user_force = {0, 0, 99.5};
  const TickRecord& r = tick();
  EXPECT_NE(r.flags & kFlagSensorSaturated, 0u);
  EXPECT_TRUE(servo_->faulted());
  servo_->request_stop();
  int k = 0;
  while (!servo_->force_released() && k < 5000) tick(), ++k;
  EXPECT_TRUE(servo_->force_released());
  servo_->finish(clock_.now());
  EXPECT_TRUE(robot_.stopped);
  EXPECT_EQ(robot_.setpoint.velocity, Eigen::Vector3d::Zero());
  EXPECT_GT(stats_.sensor_saturated_ticks.load(), 0u);
}

// Every run ends with the robot at rest: a stop request brakes the moving virtual tool first.
TEST_F(RobotTick, AStopWhileMovingBrakesToRestBeforeTheRunEnds) {
  ticks(110);
  robot_.sample.user_force = {0, 0, 9};
  ticks(200);
  ASSERT_GT(robot_.setpoint.velocity.norm(), 0.2);
  servo_->request_stop();
  EXPECT_FALSE(servo_->force_released());
  int k = 0;
  while (!servo_->force_released() && k < 5000) tick(), ++k;
  EXPECT_GT(k, 10);
  EXPECT_EQ(robot_.setpoint.velocity, Eigen::Vector3d::Zero());
  const Eigen::Vector3d at = robot_.setpoint.position;
  servo_->finish(clock_.now());
  EXPECT_EQ(robot_.setpoint.position, at);
  EXPECT_EQ(robot_.setpoint.velocity, Eigen::Vector3d::Zero());
}

// A 6-DoF handle: the sensor's torque (tared with the force) turns the setpoint about its axis.
TEST_F(RobotTick, TheSensorsTorqueTurnsTheSetpoint) {
  robot_.sample.user_torque = {0, 0, 0.05};  // the sensor's bias while nobody holds the handle
  ticks(150);
  EXPECT_LT(robot_.setpoint.orientation.angularDistance(Eigen::Quaterniond::Identity()), 1e-12);
  robot_.sample.user_torque.z() += 0.3;  // a wrist torque about z
  ticks(1000);
  const Eigen::AngleAxisd turned(robot_.setpoint.orientation);
  EXPECT_GT(turned.angle(), 0.5);
  EXPECT_GT(std::abs(turned.axis().z()), 0.999);
  EXPECT_NEAR(robot_.setpoint.angular_velocity.z(), 0.3 / AdmittanceParams{}.angular_damping, 0.05);
  // A stop brakes the turn too before the run ends.
  servo_->request_stop();
  int k = 0;
  while (!servo_->force_released() && k < 5000) tick(), ++k;
  EXPECT_EQ(robot_.setpoint.angular_velocity, Eigen::Vector3d::Zero());
}

// Admittance ticks allocate nothing either (the sensor, the limits, the braking).
TEST_F(RobotTick, AdmittanceTicksAllocateNothing) {
  ticks(20);
  const std::size_t before = test::allocation_count();
  for (int k = 0; k < 600; ++k) {
    robot_.sample.user_force = {k % 7 == 0 ? 120.0 : 4.0, 1, 0};
    robot_.stalled = k % 97 == 50;
    tick();
  }
  EXPECT_EQ(test::allocation_count() - before, 0u);
}

}  // namespace
}  // namespace gshaptics
