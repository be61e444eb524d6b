// The safety layer on its own, with hand-set times: hold, fade, soft start, force and force-rate
// limits, the device gate and the stop ramp.

#include "gshaptics/servo/safety.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace gshaptics {
namespace {

constexpr double kDt = 1e-3;
constexpr Nanos kMs = 1'000'000;

SafetyParams no_ramp() {
  SafetyParams p;
  p.ramp_time = 0;
  p.max_force_rate = 1e9;
  return p;
}

SafetyParams with_f_max(SafetyParams p, double f_max) {
  p.f_max = f_max;
  return p;
}

SafetyInput fresh(Nanos now, const Eigen::Vector3d& f) {
  SafetyInput in;
  in.now = now;
  in.desired = f;
  in.have_result = true;
  in.fresh_result = true;
  in.result_age = kMs;
  return in;
}

TEST(Safety, FreshResultPassesUnchanged) {
  SafetyFilter s(no_ramp());
  s.reset(0);
  const SafetyOutput o = s.apply(fresh(10 * kMs, {1, 2, 3}), kDt);
  EXPECT_EQ(o.force, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(o.flags, 0u);
  EXPECT_DOUBLE_EQ(o.scale, 1.0);
}

TEST(Safety, StaleResultIsHeldThenFadedLinearlyThenZero) {
  SafetyFilter s(no_ramp());  // hold 20 ms, fade 20 ms
  s.reset(0);
  SafetyInput in = fresh(0, {0, 0, 10});
  in.fresh_result = false;
  in.result_age = 15 * kMs;  // within the hold
  SafetyOutput o = s.apply(in, kDt);
  EXPECT_EQ(o.flags, std::uint32_t(kFlagHeld));
  EXPECT_DOUBLE_EQ(o.force.z(), 10.0);
  in.result_age = 25 * kMs;  // a quarter into the fade
  o = s.apply(in, kDt);
  EXPECT_EQ(o.flags, std::uint32_t(kFlagHeld | kFlagFading));
  EXPECT_NEAR(o.force.z(), 7.5, 1e-12);
  in.result_age = 40 * kMs + 1;  // past the fade
  o = s.apply(in, kDt);
  EXPECT_EQ(o.flags, std::uint32_t(kFlagHeld | kFlagFaded));
  EXPECT_EQ(o.force, Eigen::Vector3d::Zero());
}

TEST(Safety, NoResultYetGivesZero) {
  SafetyFilter s(no_ramp());
  s.reset(0);
  SafetyInput in;
  in.now = kMs;
  in.desired = {5, 0, 0};
  const SafetyOutput o = s.apply(in, kDt);
  EXPECT_TRUE(o.flags & kFlagNoResult);
  EXPECT_EQ(o.force, Eigen::Vector3d::Zero());
}

TEST(Safety, SoftStartRampsOverHalfASecond) {
  SafetyParams p = no_ramp();
  p.ramp_time = 0.5;
  SafetyFilter s(p);
  s.reset(100 * kMs);
  EXPECT_NEAR(s.apply(fresh(100 * kMs, {0, 8, 0}), kDt).force.y(), 0.0, 1e-12);
  const SafetyOutput o = s.apply(fresh(225 * kMs, {0, 8, 0}), kDt);
  EXPECT_TRUE(o.flags & kFlagRamping);
  EXPECT_NEAR(o.force.y(), 8 * 0.25, 1e-9);
  const SafetyOutput full = s.apply(fresh(600 * kMs, {0, 8, 0}), kDt);
  EXPECT_FALSE(full.flags & kFlagRamping);
  EXPECT_DOUBLE_EQ(full.force.y(), 8.0);
}

TEST(Safety, SoftStartBoundsALimitedForceByTheRamp) {
  SafetyParams p = no_ramp();
  p.ramp_time = 0.5;
  SafetyFilter s(with_f_max(p, 5));
  s.reset(0);
  // A request of 40 N at a quarter of the ramp: 0.25 * 5 N, not min(0.25 * 40, 5) = 5 N.
  const SafetyOutput o = s.apply(fresh(125 * kMs, {0, 40, 0}), kDt);
  EXPECT_TRUE(o.flags & kFlagRamping);
  EXPECT_TRUE(o.flags & kFlagForceLimited);
  EXPECT_NEAR(o.force.y(), 0.25 * 5, 1e-9);
  EXPECT_NEAR(o.scale, 0.25, 1e-12);
}

TEST(Safety, ForceLimitKeepsDirection) {
  SafetyParams p = no_ramp();
  SafetyFilter s(with_f_max(p, 5));
  s.reset(0);
  const SafetyOutput o = s.apply(fresh(kMs, {30, 40, 0}), kDt);
  EXPECT_TRUE(o.flags & kFlagForceLimited);
  EXPECT_NEAR(o.force.x(), 3, 1e-12);
  EXPECT_NEAR(o.force.y(), 4, 1e-12);
}

TEST(Safety, ForceRateLimitBoundsTheStepPerTick) {
  SafetyParams p = no_ramp();
  p.max_force_rate = 2000;  // 2 N per 1 ms tick
  SafetyFilter s(p);
  s.reset(0);
  double prev = 0;
  for (int k = 1; k <= 5; ++k) {
    const SafetyOutput o = s.apply(fresh(k * kMs, {0, 0, 7}), kDt);
    EXPECT_LE(o.force.z() - prev, 2.0 + 1e-12);
    prev = o.force.z();
    if (k <= 3) {
      EXPECT_TRUE(o.flags & kFlagRateLimited);
      EXPECT_NEAR(o.force.z(), 2.0 * k, 1e-12);
    }
  }
  EXPECT_DOUBLE_EQ(prev, 7.0);
}

TEST(Safety, DeviceGateZeroesAtOnceAndResumeRampsAgain) {
  SafetyParams p = no_ramp();
  p.ramp_time = 0.5;
  SafetyFilter s(p);
  s.reset(0);
  ASSERT_DOUBLE_EQ(s.apply(fresh(kNanosPerSecond, {0, 0, 10}), kDt).force.z(), 10.0);
  SafetyInput bad = fresh(kNanosPerSecond + kMs, {0, 0, 10});
  bad.device_ok = false;
  bad.device_flags = kFlagWatchdog;
  const SafetyOutput z = s.apply(bad, kDt);
  EXPECT_EQ(z.force, Eigen::Vector3d::Zero());  // not rate-limited: at once
  EXPECT_EQ(z.flags, std::uint32_t(kFlagWatchdog));
  // Data returns at t = 1.1 s: the soft start re-arms there.
  const Nanos resume = kNanosPerSecond + 100 * kMs;
  EXPECT_NEAR(s.apply(fresh(resume, {0, 0, 10}), kDt).force.z(), 0.0, 1e-12);
  EXPECT_NEAR(s.apply(fresh(resume + 250 * kMs, {0, 0, 10}), kDt).force.z(), 5.0, 1e-9);
}

TEST(Safety, StopRampsToExactlyZeroThroughTheRateLimit) {
  SafetyParams p = no_ramp();
  p.max_force_rate = 5000;
  SafetyFilter s(p);
  s.reset(0);
  for (int k = 1; k <= 3; ++k) s.apply(fresh(k * kMs, {0, 0, 12}), kDt);  // 5, 10, 12
  ASSERT_DOUBLE_EQ(s.last_force().z(), 12.0);
  SafetyInput in = fresh(4 * kMs, {0, 0, 12});
  in.stopping = true;
  int ticks = 0;
  while (s.last_force().squaredNorm() > 0 && ticks < 100) {
    const SafetyOutput o = s.apply(in, kDt);
    EXPECT_TRUE(o.flags & kFlagStopping);
    ++ticks;
  }
  EXPECT_EQ(ticks, 3);  // 12 -> 7 -> 2 -> 0
  EXPECT_EQ(s.last_force(), Eigen::Vector3d::Zero());
}

TEST(Safety, NonFiniteDesiredForceIsDropped) {
  SafetyFilter s(no_ramp());
  s.reset(0);
  const SafetyOutput o = s.apply(fresh(kMs, {std::nan(""), 0, 0}), kDt);
  EXPECT_EQ(o.force, Eigen::Vector3d::Zero());
}

// The device's peak force binds whatever the configured F_max says; a device without a limit
// of its own (+inf) leaves the configured one.
TEST(Safety, DevicePeakForceBindsBelowTheConfiguredLimit) {
  SafetyFilter s(with_f_max(no_ramp(), 30.0));
  s.set_device_limits(3.3, std::numeric_limits<double>::infinity());
  s.reset(0);
  EXPECT_DOUBLE_EQ(s.f_max(), 3.3);
  EXPECT_TRUE(s.limits().bound_by_device);
  const SafetyOutput o = s.apply(fresh(kMs, {0, 0, 25}), kDt);
  EXPECT_NEAR(o.force.norm(), 3.3, 1e-12);
  EXPECT_TRUE(o.flags & kFlagForceLimited);

  SafetyFilter loose(with_f_max(no_ramp(), 2.0));
  loose.set_device_limits(std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(loose.f_max(), 2.0);
  EXPECT_FALSE(loose.limits().bound_by_device);
  SafetyFilter above(with_f_max(no_ramp(), 2.0));
  above.set_device_limits(12.0, 12.0);  // the option is the tighter one
  EXPECT_DOUBLE_EQ(above.f_max(), 2.0);
  EXPECT_FALSE(above.limits().bound_by_device);
}

// The continuous limit (I^2 t): a short peak passes at the peak limit, a sustained push settles
// at the continuous force, and the mean square over the window never exceeds its square.
TEST(Safety, ContinuousLimitBoundsTheMeanSquareOverTheWindow) {
  SafetyParams p = no_ramp();
  p.continuous_window = 1.0;
  SafetyFilter s(with_f_max(p, 30.0));
  s.set_device_limits(3.3, 0.88);
  s.reset(0);
  double heat = 0, worst = 0;
  const double a = -std::expm1(-kDt / p.continuous_window);
  Eigen::Vector3d f;
  std::uint64_t limited = 0;
  for (int k = 1; k <= 6000; ++k) {  // 6 s pushing for 3.3 N
    const SafetyOutput o = s.apply(fresh(k * kMs, {0, 0, 3.3}), kDt);
    f = o.force;
    heat += (f.squaredNorm() - heat) * a;
    worst = std::max(worst, heat);
    if (k == 20) {
      EXPECT_NEAR(f.norm(), 3.3, 1e-12) << "a short peak passes";
    }
    limited += (o.flags & kFlagContinuousLimited) != 0;
  }
  EXPECT_LE(std::sqrt(worst), 0.88 * 1.001);
  EXPECT_NEAR(f.norm(), 0.88, 1e-6) << "a sustained push settles at the continuous force";
  EXPECT_NEAR(s.mean_square_force(), heat, 1e-9);
  EXPECT_GT(limited, 5000u);
  // After a rest the budget comes back: the peak passes again.
  for (int k = 6001; k <= 12000; ++k) s.apply(fresh(k * kMs, {0, 0, 0}), kDt);
  EXPECT_NEAR(s.apply(fresh(12001 * kMs, {0, 0, 3.3}), kDt).force.norm(), 3.3, 1e-12);
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

SafetyInput fresh_wrench(Nanos now, const Eigen::Vector3d& f, const Eigen::Vector3d& tau) {
  SafetyInput in = fresh(now, f);
  in.desired_torque = tau;
  return in;
}

TEST(SafetyTorque, LimitedOnItsOwnKeepingDirectionAndTheDeviceLimitBinds) {
  SafetyParams p = no_ramp();
  p.tau_max = 0.4;
  p.max_torque_rate = 1e9;
  SafetyFilter s(p);
  s.reset(0);
  // Below the limit: unchanged, and the force is untouched by the torque path.
  SafetyOutput o = s.apply(fresh_wrench(10 * kMs, {0, 0, 2}, {0.1, -0.2, 0.05}), kDt);
  EXPECT_EQ(o.torque, Eigen::Vector3d(0.1, -0.2, 0.05));
  EXPECT_EQ(o.force, Eigen::Vector3d(0, 0, 2));
  EXPECT_EQ(o.flags, 0u);
  // Above: scaled to 0.4 N m along the same axis.
  o = s.apply(fresh_wrench(11 * kMs, {0, 0, 2}, {0, 3, 4}), kDt);
  EXPECT_NEAR(o.torque.norm(), 0.4, 1e-12);
  EXPECT_NEAR(o.torque.normalized().dot(Eigen::Vector3d(0, 0.6, 0.8)), 1.0, 1e-12);
  EXPECT_TRUE(o.flags & kFlagTorqueLimited);
  EXPECT_FALSE(o.flags & kFlagForceLimited);
  // A device that allows 0.25 N m binds below the option; +inf or 0 leaves the option.
  s.set_device_torque_limit(0.25);
  EXPECT_DOUBLE_EQ(s.tau_max(), 0.25);
  EXPECT_NEAR(s.apply(fresh_wrench(12 * kMs, Eigen::Vector3d::Zero(), {0, 3, 4}), kDt).torque.norm(), 0.25, 1e-12);
  s.set_device_torque_limit(std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(s.tau_max(), 0.4);
}

TEST(SafetyTorque, RateLimitedRampedGatedAndFadedLikeTheForce) {
  SafetyParams p = no_ramp();
  p.tau_max = 10;
  p.max_torque_rate = 50;  // 0.05 N m per 1 ms tick
  SafetyFilter s(p);
  s.reset(0);
  const SafetyOutput a = s.apply(fresh_wrench(10 * kMs, Eigen::Vector3d::Zero(), {0, 0, 1}), kDt);
  EXPECT_NEAR(a.torque.z(), 0.05, 1e-12);
  EXPECT_TRUE(a.flags & kFlagTorqueLimited);
  const SafetyOutput b = s.apply(fresh_wrench(11 * kMs, Eigen::Vector3d::Zero(), {0, 0, 1}), kDt);
  EXPECT_NEAR(b.torque.z(), 0.10, 1e-12);
  // The device gate zeroes the torque at once.
  SafetyInput bad = fresh_wrench(12 * kMs, Eigen::Vector3d::Zero(), {0, 0, 1});
  bad.device_ok = false;
  bad.device_flags = kFlagWatchdog;
  EXPECT_EQ(s.apply(bad, kDt).torque, Eigen::Vector3d::Zero());
  // The soft start scales it as it scales the force (half way through a 0.5 s ramp).
  SafetyParams r = no_ramp();
  r.ramp_time = 0.5;
  r.max_torque_rate = 1e9;
  SafetyFilter ramped(r);
  ramped.reset(0);
  const SafetyOutput half = ramped.apply(fresh_wrench(250 * kMs, {0, 0, 4}, {0, 0.2, 0}), kDt);
  EXPECT_NEAR(half.force.z(), 2.0, 1e-9);
  EXPECT_NEAR(half.torque.y(), 0.1, 1e-9);
  // A result older than hold + fade: zero torque too.
  SafetyFilter old(no_ramp());
  old.reset(0);
  SafetyInput stale = fresh_wrench(kNanosPerSecond, {0, 0, 4}, {0, 0.2, 0});
  stale.fresh_result = false;
  stale.result_age = 100 * kMs;
  EXPECT_EQ(old.apply(stale, kDt).torque, Eigen::Vector3d::Zero());
  // Non-finite torque is dropped, the force still passes.
  SafetyFilter nan_filter(no_ramp());
  nan_filter.reset(0);
  const SafetyOutput n = nan_filter.apply(fresh_wrench(10 * kMs, {0, 0, 1}, {NAN, 0, 0}), kDt);
  EXPECT_EQ(n.torque, Eigen::Vector3d::Zero());
  EXPECT_EQ(n.force, Eigen::Vector3d(0, 0, 1));
}

}  // namespace
}  // namespace gshaptics
