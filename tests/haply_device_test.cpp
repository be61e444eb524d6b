// The Haply Inverse3 client against a fake Inverse Service (support/fake_inverse_service.h) that
// serves the documented messages: positions in, forces out (units and axes), the service
// restarting mid-contact (the force goes to zero, the client reconnects and starts at zero),
// malformed JSON (counted, connection kept), and a missing service or device (clear errors).

#include "gshaptics/device/haply_device.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "gshaptics/error.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/device/workspace_mapping.h"
#include "support/fake_inverse_service.h"
#include "support/device_harness.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

using test::eventually;

HaplyParams params_for(const test::FakeInverseService& service) {
  HaplyParams p;
  p.port = service.port();
  p.connect_timeout = 3.0;
  p.read_timeout = 0.3;
  p.reconnect_interval = 0.05;
  return p;
}

TEST(HaplyDevice, PositionsInForcesOutInMetresAndNewtons) {
  test::FakeInverseService service;
  service.set_position({0.01, -0.02, 0.15});
  service.set_velocity({0.1, 0.0, -0.3});
  service.set_buttons(true, false, true);
  HaplyDevice dev(params_for(service));
  dev.start(0);
  EXPECT_EQ(dev.device_id(), "INV3-0");
  EXPECT_EQ(dev.handedness(), "right");
  DeviceSample s;
  ASSERT_TRUE(eventually([&] {
    s = dev.read(42);
    return s.sequence > 0;
  }));
  EXPECT_EQ(s.stamp, 42);
  EXPECT_TRUE(s.position.isApprox(Eigen::Vector3d(0.01, -0.02, 0.15)));  // metres, axes as served
  EXPECT_TRUE(s.velocity.isApprox(Eigen::Vector3d(0.1, 0.0, -0.3)));
  EXPECT_EQ(s.buttons, 0b101u);
  // New state keeps arriving (lock-step): the sequence advances.
  const std::uint64_t seq = s.sequence;
  ASSERT_TRUE(eventually([&] { return dev.read(43).sequence > seq + 5; }));
  Wrench w;
  w.force = {0.5, -1.0, 2.0};
  ASSERT_TRUE(eventually([&] {
    dev.write(w, 0);
    return service.last_force().isApprox(w.force);  // newtons, axes unchanged
  }));
  EXPECT_TRUE(eventually([&] { return dev.stats().rate_hz > 50.0; })) << dev.stats().rate_hz;
  dev.stop(0);
  EXPECT_EQ(service.last_force(), Eigen::Vector3d::Zero());  // the last command on stop
  EXPECT_EQ(service.bad_commands(), 0);
}

TEST(HaplyDevice, StartStopStartStopEndsEverySessionAtZeroForce) {
  test::FakeInverseService service;
  HaplyParams p = params_for(service);
  p.command_timeout = 0.02;
  HaplyDevice dev(p);
  for (int session = 0; session < 2; ++session) {
    dev.start(0);
    Wrench w;
    w.force = {0, 0, 1.0 + session};
    ASSERT_TRUE(eventually([&] {
      dev.write(w, 0);
      return service.last_force().z() > 0.5 + session;
    })) << "session " << session;
    // The link's counters start afresh each session: let this one go stale once.
    ASSERT_TRUE(eventually([&] { return dev.stats().stale_commands > 0; })) << "session " << session;
    dev.stop(0);
    EXPECT_EQ(service.last_force(), Eigen::Vector3d::Zero()) << "session " << session;
  }
  // Every connection opened with a zero force (nothing replayed from the previous session).
  for (const Eigen::Vector3d& f : service.first_forces()) EXPECT_EQ(f, Eigen::Vector3d::Zero());
  EXPECT_GE(service.first_forces().size(), 2u);
}

TEST(HaplyDevice, StaleCommandIsSentAsZero) {
  test::FakeInverseService service;
  HaplyParams p = params_for(service);
  p.command_timeout = 0.02;
  HaplyDevice dev(p);
  dev.start(0);
  Wrench w;
  w.force = {0, 0, 1.5};
  ASSERT_TRUE(eventually([&] {
    dev.write(w, 0);
    return service.last_force().z() > 1.0;
  }));
  EXPECT_TRUE(eventually([&] { return service.last_force().isZero(); }));  // the servo went silent
  dev.stop(0);
}

TEST(HaplyDevice, ServiceRestartMidContactZeroesThenReconnectsAtZero) {
  test::FakeInverseService service;
  const CollisionWorld& world = test::truck_world();
  const Eigen::Vector3d on_surface = test::contact_point(world);
  ASSERT_FALSE(on_surface.isZero());
  HaplyDevice haply(params_for(service));
  WorkspaceMappingParams mp;
  mp.offset = on_surface;  // the cursor (at 0) sits on a Gaussian
  MappedDevice dev(haply, mp);
  const RuntimeConfig c = test::device_test_config(60);
  HapticRuntime rt(world, dev, c);
  rt.start();
  ASSERT_TRUE(eventually([&] { return service.last_force().norm() > 0.05; })) << "no contact force";
  EXPECT_EQ(service.connections(), 1);
  service.restart(0.3);  // the service goes away for 300 ms
  ASSERT_TRUE(eventually([&] { return service.first_forces().size() >= 2; }, 10.0)) << "no reconnect";
  // The first command on the new connection carries zero force; then contact force returns.
  ASSERT_GE(service.first_forces().size(), 2u);
  EXPECT_EQ(service.first_forces()[1], Eigen::Vector3d::Zero());
  EXPECT_TRUE(eventually([&] { return service.last_force().norm() > 0.05; })) << "force did not come back";
  rt.request_stop();
  rt.wait();
  EXPECT_GT(rt.summary().watchdog_ticks, 0u);  // the outage zeroed the force on the servo side
  EXPECT_GE(haply.stats().connects, 2u);
  haply.stop(0);
  EXPECT_EQ(service.last_force(), Eigen::Vector3d::Zero());
}

TEST(HaplyDevice, MalformedJsonIsCountedAndTheConnectionKept) {
  test::FakeInverseService service;
  service.set_malformed_every(10);
  HaplyDevice dev(params_for(service));
  dev.start(0);
  ASSERT_TRUE(eventually([&] { return dev.stats().malformed >= 5; }));
  const HaplyStats s = dev.stats();
  EXPECT_EQ(s.connects, 1u);
  EXPECT_EQ(service.connections(), 1);
  EXPECT_GT(s.messages, 40u);
  std::uint64_t seq = dev.read(0).sequence;
  EXPECT_TRUE(eventually([&] { return dev.read(0).sequence > seq + 10; }));  // state still flows
  dev.stop(0);
}

TEST(HaplyDevice, NoServiceOrNoDeviceIsAClearError) {
  HaplyParams p;
  p.port = 1;  // nothing listens there
  p.connect_timeout = 0.5;
  HaplyDevice absent(p);
  try {
    absent.start(0);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("ws://127.0.0.1:1/"), std::string::npos) << m;
    EXPECT_NE(m.find("Inverse Service"), std::string::npos) << m;
  }
  test::FakeInverseService service;
  service.set_devices(0);
  HaplyParams q = params_for(service);
  q.connect_timeout = 0.5;
  HaplyDevice none(q);
  try {
    none.start(0);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lists 0 Inverse3"), std::string::npos) << e.what();
  }
}

// A first message that is not the documented state (and, having no device_id, cannot be answered,
// so no better one follows): start() names what is wrong, instead of "no answer" or a read timeout (and a state without device_id, which could never be commanded, is
// refused rather than run without force).
TEST(HaplyDevice, FirstMessageProblemsAreNamed) {
  const std::pair<const char*, const char*> cases[] = {
      {"this is not json", "not JSON"},
      {R"({"devices": []})", "no \"inverse3\" array"},
      {R"({"inverse3": [{"state": {"cursor_position": {"x": "0", "y": 0, "z": 0}}}]})",
       "cursor_position of three finite numbers"},
      {R"({"inverse3": [{"state": {"cursor_position": {"x": 0, "y": 0, "z": 0}}}]})", "no \"device_id\""},
  };
  for (const auto& [first, expected] : cases) {
    test::FakeInverseService service;
    service.set_first_message(first);
    HaplyParams p = params_for(service);
    p.connect_timeout = 0.8;
    HaplyDevice dev(p);
    try {
      dev.start(0);
      ADD_FAILURE() << "started on: " << first;
      dev.stop(0);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  }
}

// The header's promise: a malformed message is answered with zero force (the lock-step goes on).
TEST(HaplyDevice, MalformedMessagesAreAnsweredWithZeroForce) {
  test::FakeInverseService service;
  service.set_malformed_every(5);
  HaplyDevice dev(params_for(service));
  dev.start(0);
  Wrench w;
  w.force = {0, 0, 1.5};
  ASSERT_TRUE(eventually([&] {
    dev.write(w, 0);
    return dev.stats().malformed >= 10;
  }));
  // The force goes out otherwise (the newest command may be one that answered a malformed message).
  EXPECT_TRUE(eventually([&] {
    dev.write(w, 0);
    return service.last_force().z() > 1.0;
  }));
  EXPECT_EQ(service.nonzero_after_malformed(), 0);
  dev.stop(0);
}

// Both documented forms, told apart by the service's first message: 3.1-3.4 take the force as
// "values", 3.5 as "vector" with a session profile handshake on the first command of each
// connection. A command in the wrong form is not applied by the fake (bad_commands).
TEST(HaplyDevice, SpeaksTheFormOfTheServiceVersion) {
  for (int version : {31, 35}) {
    SCOPED_TRACE(version);
    test::FakeInverseService service;
    service.set_version(version);
    HaplyDevice dev(params_for(service));
    for (int session = 0; session < 2; ++session) {
      dev.start(0);
      EXPECT_EQ(dev.stats().format, version);
      const std::string status = dev.status();
      EXPECT_NE(status.find(version == 35 ? "3.5 format" : "3.1-3.4 format"), std::string::npos) << status;
      EXPECT_NE(status.find(" Hz"), std::string::npos) << "no service rate at start: " << status;
      Wrench w;
      w.force = {0.25, -0.5, 1.25};
      ASSERT_TRUE(eventually([&] {
        dev.write(w, 0);
        return service.last_force().isApprox(w.force);
      }));
      dev.stop(0);
      EXPECT_EQ(service.last_force(), Eigen::Vector3d::Zero());
    }
    EXPECT_EQ(service.bad_commands(), 0);
    const std::vector<std::string> profiles = service.session_profiles();
    if (version == 35) {
      ASSERT_EQ(profiles.size(), 2u);  // once per connection, not with every command
      EXPECT_EQ(profiles[0], "gshaptics");
    } else {
      EXPECT_TRUE(profiles.empty());
    }
  }
}

// What the device says about itself: not calibrated or not ready is refused with that reason
// (calibration can be waived); turning not ready mid-run answers with zero force, counted.
TEST(HaplyDevice, StatusNotCalibratedOrNotReadyGetsNoForce) {
  const struct {
    bool calibrated, ready;
    const char* expected;
  } cases[] = {{false, true, "not calibrated"}, {true, false, "not ready"}};
  for (const auto& c : cases) {
    test::FakeInverseService service;
    service.set_version(35);
    service.set_status(c.calibrated, c.ready);
    HaplyParams p = params_for(service);
    p.connect_timeout = 0.5;
    HaplyDevice dev(p);
    try {
      dev.start(0);
      ADD_FAILURE() << "started a device whose status says " << c.expected;
      dev.stop(0);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
    }
    EXPECT_EQ(service.last_force(), Eigen::Vector3d::Zero());
  }
  {
    test::FakeInverseService service;
    service.set_status(false, true);
    HaplyParams p = params_for(service);
    p.require_calibrated = false;
    HaplyDevice dev(p);
    dev.start(0);  // waived
    dev.stop(0);
  }
  test::FakeInverseService service;
  HaplyDevice dev(params_for(service));
  dev.start(0);
  Wrench w;
  w.force = {0, 0, 1.5};
  ASSERT_TRUE(eventually([&] {
    dev.write(w, 0);
    return service.last_force().z() > 1.0;
  }));
  service.set_status(true, false);
  EXPECT_TRUE(eventually([&] {
    dev.write(w, 0);
    return dev.stats().not_ready > 5 && service.last_force().isZero();
  }));
  service.set_status(true, true);
  EXPECT_TRUE(eventually([&] {
    dev.write(w, 0);
    return service.last_force().z() > 1.0;
  }));
  dev.stop(0);
}

}  // namespace
}  // namespace gshaptics
