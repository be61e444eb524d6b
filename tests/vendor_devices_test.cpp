// The DHD and OpenHaptics devices against stand-in vendor libraries built by the tests
// (support/fake_dhd.c, support/fake_hd.c), which export the same C symbols and record the calls:
// call order, units (m vs mm), axes, buttons, calibration, and zero force on stop and on the
// watchdog.

#include "gshaptics/servo/vendor_devices.h"

#include <dlfcn.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <string>
#include <thread>

#include "gshaptics/error.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/servo/workspace_mapping.h"
#include "support/device_harness.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

using test::eventually;

// The libraries are looked up once per process: point both at the fakes before any test runs.
const bool kEnvSet = [] {
  ::setenv("GSHAPTICS_DHD_LIBRARY", GSHAPTICS_FAKE_DHD, 1);
  ::setenv("GSHAPTICS_HD_LIBRARY", GSHAPTICS_FAKE_HD, 1);
  return true;
}();

/// The test hooks of a fake library (same handle as the device's: dlopen counts references).
template <class F>
F hook(const char* lib, const char* name) {
  void* h = dlopen(lib, RTLD_NOW | RTLD_LOCAL);
  EXPECT_NE(h, nullptr) << dlerror();
  auto f = reinterpret_cast<F>(dlsym(h, name));
  EXPECT_NE(f, nullptr) << name;
  return f;
}

struct FakeDhd {
  const char* (*log)() = hook<const char* (*)()>(GSHAPTICS_FAKE_DHD, "fake_dhd_log");
  void (*clear_log)() = hook<void (*)()>(GSHAPTICS_FAKE_DHD, "fake_dhd_clear_log");
  void (*set_position)(double, double, double) = hook<void (*)(double, double, double)>(GSHAPTICS_FAKE_DHD, "fake_dhd_set_position");
  void (*set_velocity)(double, double, double) = hook<void (*)(double, double, double)>(GSHAPTICS_FAKE_DHD, "fake_dhd_set_velocity");
  void (*set_buttons)(int) = hook<void (*)(int)>(GSHAPTICS_FAKE_DHD, "fake_dhd_set_buttons");
  void (*set_fail_reads)(int) = hook<void (*)(int)>(GSHAPTICS_FAKE_DHD, "fake_dhd_set_fail_reads");
  void (*set_reset_mode)(int) = hook<void (*)(int)>(GSHAPTICS_FAKE_DHD, "fake_dhd_set_reset_mode");
  void (*force_raw)(double*) = hook<void (*)(double*)>(GSHAPTICS_FAKE_DHD, "fake_dhd_force");
  int (*force_enabled)() = hook<int (*)()>(GSHAPTICS_FAKE_DHD, "fake_dhd_force_enabled");
  Eigen::Vector3d force() const {
    Eigen::Vector3d f;
    force_raw(f.data());
    return f;
  }
};

struct FakeHd {
  const char* (*log)() = hook<const char* (*)()>(GSHAPTICS_FAKE_HD, "fake_hd_log");
  void (*set_position_mm)(double, double, double) = hook<void (*)(double, double, double)>(GSHAPTICS_FAKE_HD, "fake_hd_set_position_mm");
  void (*set_velocity_mm)(double, double, double) = hook<void (*)(double, double, double)>(GSHAPTICS_FAKE_HD, "fake_hd_set_velocity_mm");
  void (*set_buttons)(int) = hook<void (*)(int)>(GSHAPTICS_FAKE_HD, "fake_hd_set_buttons");
  void (*set_calibration)(int) = hook<void (*)(int)>(GSHAPTICS_FAKE_HD, "fake_hd_set_calibration");
  void (*force_raw)(double*) = hook<void (*)(double*)>(GSHAPTICS_FAKE_HD, "fake_hd_force");
  unsigned long (*force_writes)() = hook<unsigned long (*)()>(GSHAPTICS_FAKE_HD, "fake_hd_force_writes");
  int (*frame_errors)() = hook<int (*)()>(GSHAPTICS_FAKE_HD, "fake_hd_frame_errors");
  Eigen::Vector3d force() const {
    Eigen::Vector3d f;
    force_raw(f.data());
    return f;
  }
};

TEST(VendorFrames, DhdAndHdAxesAndUnits) {
  // DHD: x towards the user, y right, z up -> device: x right, y away, z up.
  EXPECT_EQ(dhd_to_device({1, 0, 0}), Eigen::Vector3d(0, -1, 0));
  EXPECT_EQ(dhd_to_device({0, 1, 0}), Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(dhd_to_device({0, 0, 1}), Eigen::Vector3d(0, 0, 1));
  const Eigen::Vector3d v(0.3, -0.7, 1.1);
  EXPECT_EQ(device_to_dhd(dhd_to_device(v)), v);
  // HD: x right, y up, z towards the user, mm -> device, m.
  EXPECT_TRUE(hd_mm_to_device_m({1000, 0, 0}).isApprox(Eigen::Vector3d(1, 0, 0)));
  EXPECT_TRUE(hd_mm_to_device_m({0, 1000, 0}).isApprox(Eigen::Vector3d(0, 0, 1)));
  EXPECT_TRUE(hd_mm_to_device_m({0, 0, 1000}).isApprox(Eigen::Vector3d(0, -1, 0)));
  // A force maps with the same axis change as positions (no unit change): push up = HD +y.
  EXPECT_EQ(device_force_to_hd({0, 0, 2}), Eigen::Vector3d(0, 2, 0));
  EXPECT_TRUE((device_force_to_hd(v) * 1000).isApprox(Eigen::Vector3d(v.x(), v.z(), -v.y()) * 1000));
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(10, 20, 30), Eigen::Vector3d(-5, 7, 2)}) {
    // The force frame is the position frame: f . dp is the same power in both.
    const Eigen::Vector3d f(0.1, -0.4, 0.9);
    EXPECT_NEAR(device_force_to_hd(f).dot(p), f.dot(hd_mm_to_device_m(p)) * 1000, 1e-9);
  }
}

TEST(DhdDevice, CallOrderUnitsAxesButtonsAndStop) {
  FakeDhd fake;
  fake.clear_log();
  fake.set_reset_mode(0);
  DhdDevice dev(1);
  dev.start(0);
  EXPECT_EQ(std::string(fake.log()), "dhdOpenID(1) dhdGetStatus dhdSetForce(0) dhdEnableForce(on) ");
  EXPECT_EQ(dev.status(), "powered, connected, calibrated");
  EXPECT_NE(dev.info().name.find("fake omega.3"), std::string::npos);
  EXPECT_EQ(fake.force_enabled(), 1);

  fake.set_position(0.01, 0.02, 0.03);  // DHD frame, metres
  fake.set_velocity(0.1, 0.0, -0.2);
  fake.set_buttons(0b101);
  const DeviceSample s = dev.read(1000);
  EXPECT_EQ(s.sequence, 1u);
  EXPECT_EQ(s.stamp, 1000);
  EXPECT_TRUE(s.position.isApprox(Eigen::Vector3d(0.02, -0.01, 0.03)));  // metres, no scaling
  EXPECT_TRUE(s.velocity.isApprox(Eigen::Vector3d(0.0, -0.1, -0.2)));
  EXPECT_EQ(s.buttons, 0b101u);

  Wrench w;
  w.force = {1, 2, 3};  // device frame, N
  dev.write(w, 2000);
  EXPECT_TRUE(fake.force().isApprox(Eigen::Vector3d(-2, 1, 3)));  // DHD frame, N

  // A failed read repeats the previous sample: same sequence, for the runtime's watchdog.
  fake.set_fail_reads(1);
  EXPECT_EQ(dev.read(3000).sequence, 1u);
  fake.set_fail_reads(0);
  EXPECT_EQ(dev.read(4000).sequence, 2u);

  fake.clear_log();
  dev.stop(5000);
  EXPECT_EQ(std::string(fake.log()), "dhdSetForce(0) dhdEnableForce(off) dhdClose ");
  EXPECT_EQ(fake.force(), Eigen::Vector3d::Zero());
  EXPECT_EQ(fake.force_enabled(), 0);
}

TEST(DhdDevice, ReportsResetModeAndMissingDevices) {
  FakeDhd fake;
  fake.set_reset_mode(1);
  DhdDevice dev(0);
  dev.start(0);
  EXPECT_NE(dev.status().find("RESET"), std::string::npos) << dev.status();
  dev.stop(0);
  fake.set_reset_mode(0);
  try {
    DhdDevice absent(2);  // the fake reports two devices
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("reports 2 device(s)"), std::string::npos) << e.what();
  }
}

TEST(DhdDevice, RuntimeWatchdogZeroesTheForceWhenTheDeviceStopsAnswering) {
  FakeDhd fake;
  const CollisionWorld& world = test::truck_world();
  // Put the device origin on a Gaussian of the Truck: the tool is in contact from the start.
  const Eigen::Vector3d on_surface = test::contact_point(world);
  ASSERT_FALSE(on_surface.isZero());
  fake.set_position(0, 0, 0);
  fake.set_velocity(0, 0, 0);
  fake.set_fail_reads(0);
  DhdDevice dhd(0);
  WorkspaceMappingParams mp;
  mp.offset = on_surface;
  MappedDevice dev(dhd, mp);
  const RuntimeConfig c = test::device_test_config(30);
  HapticRuntime rt(world, dev, c);
  rt.start();
  ASSERT_TRUE(eventually([&] { return fake.force().norm() > 0.05; })) << "no contact force";
  fake.set_fail_reads(1);  // the device stops answering
  EXPECT_TRUE(eventually([&] { return fake.force().norm() == 0.0; }));
  rt.request_stop();
  rt.wait();
  fake.set_fail_reads(0);
  EXPECT_GT(rt.summary().watchdog_ticks, 0u);
  EXPECT_EQ(fake.force(), Eigen::Vector3d::Zero());
  EXPECT_EQ(fake.force_enabled(), 0);
}

TEST(OpenHapticsDevice, CallOrderUnitsAxesAndZeroOnStop) {
  FakeHd fake;
  fake.set_calibration(0x5000);
  fake.set_position_mm(10, 20, 30);  // HD frame, mm
  fake.set_velocity_mm(100, 0, -50);
  fake.set_buttons(0b11);
  OpenHapticsDevice dev;
  dev.start(0);
  EXPECT_EQ(dev.status(), "calibrated");
  EXPECT_DOUBLE_EQ(dev.max_force(), 3.3);
  EXPECT_EQ(dev.info().max_rate_hz, 1000);
  // Usable workspace 160 x 120 x 70 mm (x, y up, z to the user) -> device x 0.16, y 0.07, z 0.12 m.
  EXPECT_TRUE(dev.info().workspace.sizes().isApprox(Eigen::Vector3d(0.16, 0.07, 0.12)));
  ASSERT_TRUE(eventually([&] { return dev.callbacks() > 3; }));
  DeviceSample s;
  ASSERT_TRUE(eventually([&] {
    s = dev.read(123);
    return s.sequence > 0;
  }));
  EXPECT_EQ(s.stamp, 123);
  EXPECT_TRUE(s.position.isApprox(Eigen::Vector3d(0.010, -0.030, 0.020)));
  EXPECT_TRUE(s.velocity.isApprox(Eigen::Vector3d(0.1, 0.05, 0.0)));
  EXPECT_EQ(s.buttons, 0b11u);

  Wrench w;
  w.force = {1, 2, 3};
  // Keep writing, as the servo loop does, until the HD callback has applied it.
  ASSERT_TRUE(eventually([&] {
    dev.write(w, 0);
    return fake.force().isApprox(Eigen::Vector3d(1, 3, -2));
  }));
  dev.stop(0);
  EXPECT_EQ(fake.force(), Eigen::Vector3d::Zero());
  EXPECT_EQ(fake.frame_errors(), 0);
  const std::string log = fake.log();
  const char* order[] = {"hdInitDevice", "hdCheckCalibration", "hdEnable(HD_FORCE_OUTPUT)",
                         "hdScheduleAsynchronous(65535)", "hdStartScheduler", "callback-done",
                         "hdStopScheduler", "hdUnschedule", "hdDisableDevice"};
  std::size_t at = 0;
  for (const char* step : order) {
    const std::size_t found = log.find(step, at);
    ASSERT_NE(found, std::string::npos) << step << " missing or out of order in: " << log;
    at = found;
  }
}

TEST(OpenHapticsDevice, CallbackZeroesAStaleCommand) {
  FakeHd fake;
  fake.set_calibration(0x5000);
  OpenHapticsParams p;
  p.command_timeout = 0.02;
  OpenHapticsDevice dev(p);
  dev.start(0);
  Wrench w;
  w.force = {0, 0, 1.5};
  ASSERT_TRUE(eventually([&] {
    dev.write(w, 0);
    return fake.force().norm() > 1.0;
  }));
  // The servo thread goes silent: within the timeout (+ scheduling slack) the callback zeroes.
  EXPECT_TRUE(eventually([&] { return fake.force().norm() == 0.0; }));
  EXPECT_GT(dev.stale_commands(), 0u);
  dev.stop(0);
}

TEST(OpenHapticsDevice, CalibrationUpdatedOrAskedFor) {
  FakeHd fake;
  fake.set_calibration(0x5001);  // HD_CALIBRATION_NEEDS_UPDATE: the device does it itself
  {
    OpenHapticsDevice dev;
    dev.start(0);
    EXPECT_EQ(dev.status(), "calibration updated");
    EXPECT_NE(std::string(fake.log()).find("hdUpdateCalibration(4)"), std::string::npos);  // inkwell
    dev.stop(0);
  }
  fake.set_calibration(0x5002);  // HD_CALIBRATION_NEEDS_MANUAL_INPUT: the user must act
  OpenHapticsDevice dev;
  try {
    dev.start(0);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("inkwell"), std::string::npos) << e.what();
  }
  fake.set_calibration(0x5000);
}

}  // namespace
}  // namespace gshaptics
