// The drivers' shared I/O-thread link (DeviceLink): new samples advance the sequence, a command
// the servo thread stopped refreshing is sent as zero and counted, a command older than a fresh
// connection is never replayed, and a new session starts at zero.

#include "gshaptics/device/device_link.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

namespace gshaptics {
namespace {

TEST(DeviceLink, SamplesAdvanceTheSequenceOnlyWhenNew) {
  DeviceLink link(0.05);
  EXPECT_EQ(link.read(1).sequence, 0u);
  LinkSample s;
  s.position = {0.1, 0.2, 0.3};
  s.buttons = 2;
  link.publish(s);
  DeviceSample d = link.read(5);
  EXPECT_EQ(d.sequence, 1u);
  EXPECT_EQ(d.stamp, 5);
  EXPECT_EQ(d.position, s.position);
  EXPECT_EQ(d.buttons, 2u);
  d = link.read(6);  // nothing new: the same sample, the same sequence (the watchdog decides)
  EXPECT_EQ(d.sequence, 1u);
  EXPECT_EQ(d.stamp, 5);
  s.position.x() = 0.5;
  link.publish(s);
  link.publish(s);  // two before a read: one new sample, the newest
  EXPECT_EQ(link.read(7).sequence, 2u);
}

TEST(DeviceLink, AStaleCommandIsSentAsZeroAndCounted) {
  DeviceLink link(0.02);
  link.begin_session();
  link.command({1, 2, 3});
  EXPECT_EQ(link.force_to_send(), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(link.stale_commands(), 0u);
  // Bounded by wall time: well past the 20 ms timeout.
  std::this_thread::sleep_for(std::chrono::milliseconds(60));
  EXPECT_EQ(link.force_to_send(), Eigen::Vector3d::Zero());
  EXPECT_EQ(link.stale_commands(), 1u);
  link.command({4, 5, 6});  // refreshed: sent again
  EXPECT_EQ(link.force_to_send(), Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(link.stale_commands(), 1u);
  link.begin_session();  // a new session: zero, counters at zero
  EXPECT_EQ(link.stale_commands(), 0u);
  EXPECT_EQ(link.force_to_send(), Eigen::Vector3d::Zero());
}

TEST(DeviceLink, ACommandOlderThanTheConnectionIsNotReplayed) {
  DeviceLink link(10.0);
  link.command({0, 0, 1});
  const std::int64_t connected_at = steady_ns() + 1;
  EXPECT_EQ(link.force_to_send(connected_at), Eigen::Vector3d::Zero());
  EXPECT_EQ(link.zeroed_before(), 1u);
  link.command(Eigen::Vector3d::Zero());
  EXPECT_EQ(link.force_to_send(steady_ns() + 1), Eigen::Vector3d::Zero());
  EXPECT_EQ(link.zeroed_before(), 1u);  // a zero command is not a loss
  std::this_thread::sleep_for(std::chrono::milliseconds(2));
  link.command({0, 1, 0});  // written after the connection: sent
  EXPECT_EQ(link.force_to_send(connected_at), Eigen::Vector3d(0, 1, 0));
  // An invalid timeout makes every command stale rather than none.
  DeviceLink bad(std::nan(""));
  bad.command({1, 0, 0});
  EXPECT_EQ(bad.force_to_send(), Eigen::Vector3d::Zero());
}

}  // namespace
}  // namespace gshaptics
