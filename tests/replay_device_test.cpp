// Pose logs: parsing and its error messages, interpolation, finishing, and a round trip through
// the runtime's own CSV log.

#include "gshaptics/device/replay_device.h"

#include <gtest/gtest.h>

#include <fstream>

#include "gshaptics/error.h"
#include "gshaptics/servo/tick_log.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

constexpr Nanos kMs = 1'000'000;

std::string write_text(const std::string& text) {
  const std::string path = test::temp_path(".csv");
  std::ofstream(path) << text;
  return path;
}

std::string error_of(const std::string& text) {
  const std::string path = write_text(text);
  try {
    (void)load_pose_log(path);
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(path), std::string::npos) << m;  // names the file
    return m;
  }
  return "";
}

TEST(PoseLog, ReadsColumnsByNameAndRebasesTime) {
  const PoseLog log = load_pose_log(write_text("z,extra,time_s,y,x\n3,9,10.0,2,1\n6,9,10.5,4,2\n"));
  ASSERT_EQ(log.rows.size(), 2u);
  EXPECT_DOUBLE_EQ(log.rows[0].time, 0.0);
  EXPECT_DOUBLE_EQ(log.rows[1].time, 0.5);
  EXPECT_EQ(log.rows[1].position, Eigen::Vector3d(2, 4, 6));
  EXPECT_FALSE(log.has_velocity);
  EXPECT_NEAR(log.rows[0].velocity.x(), 2.0, 1e-12);  // finite difference
}

TEST(PoseLog, ErrorsNameFileLineAndColumn) {
  EXPECT_NE(error_of("").find("empty"), std::string::npos);
  EXPECT_NE(error_of("time_s,x,y\n0,0,0\n").find("time_s, x, y, z"), std::string::npos);
  const std::string bad = error_of("time_s,x,y,z\n0,0,0,0\n0.1,0,zz,0\n");
  EXPECT_NE(bad.find("line 3"), std::string::npos) << bad;
  EXPECT_NE(bad.find("'y'"), std::string::npos) << bad;
  EXPECT_NE(error_of("time_s,x,y,z\n0,0,0,0\n0,1,1,1\n").find("does not increase"), std::string::npos);
  EXPECT_NE(error_of("time_s,x,y,z\n0,0,0\n").find("fields"), std::string::npos);
  EXPECT_NE(error_of("time_s,x,y,z\n").find("no rows"), std::string::npos);
}

TEST(PoseLog, NonFiniteRowsAreKeptAndCounted) {
  const PoseLog log = load_pose_log(write_text("time_s,x,y,z\n0,0,0,0\n0.1,nan,0,0\n0.2,0,0,0\n"));
  EXPECT_EQ(log.rows.size(), 3u);
  EXPECT_EQ(log.non_finite_rows, 1u);
}

TEST(ReplayDevice, InterpolatesAndFinishes) {
  PoseLog log = load_pose_log(write_text("time_s,x,y,z,vx,vy,vz\n0,0,0,0,1,0,0\n1,1,0,0,1,0,0\n2,1,2,0,0,2,0\n"));
  ReplayDevice d(std::move(log));
  d.start(100 * kMs);
  DeviceSample s = d.read(100 * kMs + 250 * kMs);
  EXPECT_NEAR(s.position.x(), 0.25, 1e-12);
  EXPECT_NEAR(s.velocity.x(), 1.0, 1e-12);
  EXPECT_FALSE(d.finished());
  s = d.read(100 * kMs + 1500 * kMs);
  EXPECT_NEAR(s.position.y(), 1.0, 1e-12);
  EXPECT_NEAR(s.velocity.x(), 0.5, 1e-12);
  const std::uint64_t seq = s.sequence;
  s = d.read(100 * kMs + 3000 * kMs);
  EXPECT_EQ(s.position, Eigen::Vector3d(1, 2, 0));
  EXPECT_TRUE(d.finished());
  EXPECT_GT(s.sequence, seq);  // still alive: the watchdog must not trip at the end
}

TEST(ReplayDevice, ReplaysTheRuntimesOwnLog) {
  std::vector<TickRecord> recs(5);
  for (int i = 0; i < 5; ++i) {
    recs[std::size_t(i)].time = to_seconds(i * kMs);
    recs[std::size_t(i)].position = {0.1 * i, -0.2 * i, 1.0};
    recs[std::size_t(i)].velocity = {100, -200, 0};
  }
  const std::string path = test::temp_path(".csv");
  write_tick_log_csv(path, recs, kServoLogColumns);
  const PoseLog log = load_pose_log(path);
  ASSERT_EQ(log.rows.size(), 5u);
  EXPECT_TRUE(log.has_velocity);
  EXPECT_NEAR(log.rows[3].position.y(), -0.6, 1e-6);
  EXPECT_NEAR(log.rows[3].time, 0.003, 1e-9);
}

}  // namespace
}  // namespace gshaptics
