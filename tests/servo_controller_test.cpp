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
