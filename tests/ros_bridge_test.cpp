// The middleware-free pose intake of the ROS bridges: velocity from the sender's header stamps,
// not from arrival times, so transport jitter never reaches the damping term; missing, backward
// and impossible stamps fall back to arrival times and are counted.

#include "gshaptics/error.h"
#include "gshaptics/net/ros_bridge.h"

#include <gtest/gtest.h>

#include <random>

namespace gshaptics {
namespace {

constexpr Nanos kMs = 1'000'000;

struct Intake {
  ManualClock clock{kMs};
  RosBridgeStats stats;
  StreamDevice device{network_device_params("test", 0.1), Eigen::Vector3d::Zero()};
  RosPoseIntake intake{device, clock, stats};
  Intake() { device.start(clock.now()); }
  void send(double x, std::int64_t stamp_ns) {
    RosTime t;
    t.sec = std::int32_t(stamp_ns / 1'000'000'000);
    t.nanosec = std::uint32_t(stamp_ns % 1'000'000'000);
    intake.on_pose({x, 0.0, 0.0}, {0, 0, 0, 1}, t, 1);
  }
  double velocity() { return device.read(clock.now()).velocity.x(); }
};

TEST(RosPoseIntake, VelocityFromStampsIgnoresTransportJitter) {
  const double v_true = 0.157;  // m/s, sent at 1 kHz with exact stamps
  const std::int64_t t0 = 1'700'000'000LL * 1'000'000'000LL;
  std::mt19937_64 rng(4);
  std::uniform_int_distribution<Nanos> delay(0, 5 * kMs);
  Intake jittered, on_time;
  Nanos last_arrival = 0;
  double worst = 0, worst_arrival_based = 0;
  for (int k = 0; k < 2000; ++k) {
    const std::int64_t stamp = t0 + k * kMs;
    const double x = v_true * k * 1e-3;
    // The same stream on time, and with 0-5 ms of random delay (order kept, as DDS does).
    on_time.clock.set(Nanos(k + 1) * kMs);
    on_time.send(x, stamp);
    const Nanos arrival = std::max(last_arrival + 1, Nanos(k + 1) * kMs + delay(rng));
    const Nanos prev_arrival = last_arrival;
    last_arrival = arrival;
    jittered.clock.set(arrival);
    jittered.send(x, stamp);
    if (k < 50) continue;  // the 2 ms filter has settled
    worst = std::max(worst, std::fabs(jittered.velocity() - v_true) / v_true);
    ASSERT_NEAR(on_time.velocity(), v_true, 1e-6 * v_true) << k;
    // What differentiating by arrival time would give.
    worst_arrival_based = std::max(worst_arrival_based, std::fabs(v_true * 1e-3 / (double(arrival - prev_arrival) * 1e-9) - v_true) / v_true);
  }
  EXPECT_LT(worst, 0.10);             // within 10 % of the true speed on every tick (exactly it here)
  EXPECT_GT(worst_arrival_based, 1.0);  // arrival times alone are off by more than 100 %
  EXPECT_EQ(jittered.stats.stamp_fallbacks.load(), 0u);
  EXPECT_EQ(jittered.stats.stamp_rejected.load(), 0u);
}

TEST(RosPoseIntake, MissingBackwardAndImpossibleStampsFallBackAndAreCounted) {
  Intake in;
  const std::int64_t t0 = 1'700'000'000LL * 1'000'000'000LL;
  in.clock.set(1 * kMs);
  in.send(0.000, t0);
  in.clock.set(2 * kMs);
  in.send(0.001, 0);  // no stamp (as `rostopic pub` without `now`)
  EXPECT_EQ(in.stats.stamp_fallbacks.load(), 1u);
  in.clock.set(3 * kMs);
  in.send(0.002, t0 - 5 * kMs);  // goes backwards
  EXPECT_EQ(in.stats.stamp_fallbacks.load(), 2u);
  in.clock.set(4 * kMs);
  in.send(0.003, t0 + 10'000 * kMs);  // 10 s ahead in 1 ms of arrival: impossible
  EXPECT_EQ(in.stats.stamp_rejected.load(), 1u);
  // Arrival times gave the velocity meanwhile: 1 mm per 1 ms (the 2 ms filter still rising).
  EXPECT_GT(in.velocity(), 0.6);
  EXPECT_LT(in.velocity(), 1.0 + 1e-9);
  in.clock.set(5 * kMs);
  in.send(0.004, t0 + 10'001 * kMs);  // stamps usable again
  EXPECT_EQ(in.stats.stamp_fallbacks.load(), 2u);
  EXPECT_EQ(in.stats.stamp_rejected.load(), 1u);
  EXPECT_GT(in.velocity(), 0.75);
  EXPECT_LT(in.velocity(), 1.0 + 1e-9);
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

// Wrench stamps (issue "ROS nodes that behave as ROS users expect", item 3): the pose's stamp while
// poses are fresh, the current time otherwise; never zero, never the last pose's stamp on the
// watchdog's zero-force wrenches.
TEST(RosPoseIntake, WrenchStampEchoesFreshPosesAndIsNeverStaleOrZero) {
  Intake in;
  const std::int64_t wall = RosTime::now().nanos();
  const RosTime before = in.intake.wrench_stamp();  // no pose yet
  EXPECT_NE(before.nanos(), 0);
  EXPECT_NEAR(double(before.nanos() - wall), 0.0, 5e9);
  const std::int64_t stamp = 1'700'000'000LL * 1'000'000'000 + 123;
  in.send(0.001, stamp);
  EXPECT_EQ(in.intake.wrench_stamp().nanos(), stamp);  // fresh: the pose it answers
  in.clock.set(in.clock.now() + 50 * kMs);
  EXPECT_EQ(in.intake.wrench_stamp().nanos(), stamp);  // within the input timeout (0.1 s)
  in.clock.set(in.clock.now() + 60 * kMs);
  const RosTime stale = in.intake.wrench_stamp();      // the publisher stopped: now, not the old stamp
  EXPECT_NE(stale.nanos(), stamp);
  EXPECT_GE(stale.nanos(), wall);
  in.send(0.002, 0);                                   // an unstamped pose: now
  EXPECT_GE(in.intake.wrench_stamp().nanos(), wall);
}

}  // namespace
}  // namespace gshaptics

#include "gshaptics/servo/simulated_runtime.h"
#include "support/floor_renderer.h"

namespace gshaptics {
namespace {

// The pose watchdog of a ROS node at the defaults: the last pose arrives and the force is zero
// 0.1 s later (input timeout 0.09 s, then the servo's device timeout 0.01 s), as docs/ros.md says.
TEST(RosWatchdog, ForceStopsAtTheDocumentedTimeAfterTheLastPose) {
  const RosBridgeOptions topics;
  StreamDevice device(network_device_params("test", topics.input_timeout), Eigen::Vector3d::Zero());
  RuntimeConfig c;
  c.inline_query = true;
  c.duration = 0.4;
  c.safety.ramp_time = 0;
  // A pose inside the spring floor, then silence (set before start: it is the newest at t = 0).
  device.set_target(Eigen::Vector3d(0, 0, -0.002), Eigen::Quaterniond::Identity(), 0);
  SimulatedRuntime rt(device, c, std::make_unique<test::FloorRenderer>(1000));
  rt.run();
  double last_force = -1, first_zero = -1;
  for (const TickRecord& r : rt.log().records()) {
    if (r.force.norm() > 0) last_force = r.time;
    if (first_zero < 0 && last_force >= 0 && r.force.norm() == 0 && (r.flags & kFlagWatchdog)) first_zero = r.time;
  }
  ASSERT_GE(last_force, 0.0) << "the pose never produced a force";
  EXPECT_NEAR(first_zero, 0.1, 0.0015);  // within a tick and a half of 0.1 s
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

// ROS 2 names without rcl (issue "ROS nodes that behave as ROS users expect", item 1): the
// namespace and node name of --ros-args, and remap rules matched after resolution, as rcl does.
TEST(Ros2Names, NamespaceNodeAndRemapsResolveAsRclDoes) {
  const Ros2Names none = Ros2Names::parse({}, "gshaptics_node");
  EXPECT_EQ(none.resolve("gshaptics/tool_pose"), "/gshaptics/tool_pose");
  EXPECT_EQ(none.node, "gshaptics_node");
  const Ros2Names n = Ros2Names::parse({"--ros-args", "-r", "__ns:=/arm1", "-r", "__node:=left", "--remap",
                                        "gshaptics/wrench:=haptic/wrench", "-r", "/abs/in:=/other"},
                                       "gshaptics_node");
  EXPECT_EQ(n.node, "left");
  EXPECT_EQ(n.resolve("gshaptics/tool_pose"), "/arm1/gshaptics/tool_pose");  // relative: under the namespace
  EXPECT_EQ(n.resolve("gshaptics/wrench"), "/arm1/haptic/wrench");           // remapped, then resolved
  EXPECT_EQ(n.resolve("/gshaptics/wrench"), "/gshaptics/wrench");            // absolute: not the rule's name
  EXPECT_EQ(n.resolve("/abs/in"), "/other");
  EXPECT_THROW((void)Ros2Names::parse({"pose:=x"}, "n"), InputError);                     // a ROS 1 remapping
  EXPECT_THROW((void)Ros2Names::parse({"--ros-args", "-p", "x:=1"}, "n"), InputError);     // parameters
  EXPECT_THROW((void)Ros2Names::parse({"--ros-args", "-r", "nonsense"}, "n"), InputError);
  EXPECT_THROW((void)Ros2Names::parse({"--ros-args", "-r", "__ns:=relative"}, "n"), InputError);
}

}  // namespace
}  // namespace gshaptics
