// The ROS 2 bridge seen from outside: a subscriber and publisher written directly against Cyclone
// DDS with the plain IDL types (not the bridge's classes) talk to a runtime whose device is the
// Ros2NetworkDevice: topic and type names of the ROS 2 wire format, poses in, wrenches out with
// the pose's stamp echoed, MarkerArrays, and the faults (publisher dies mid-contact, NaN pose,
// second publisher).

#include "gshaptics/ros2/ros2_bridge.h"

#include <dds/dds.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <thread>

#include "gshaptics/io/scene_loader.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "ros2_interfaces.h"
#include "support/ellipsoid_params.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

using namespace std::chrono_literals;

/// A participant with a best-effort writer of PoseStamped and readers of WrenchStamped and
/// MarkerArray, all from the generated IDL types.
struct PlainDds {
  dds_entity_t pp, pose_topic, wrench_topic, marker_topic, pose_writer, wrench_reader, marker_reader;
  explicit PlainDds(int domain) {
    pp = dds_create_participant(dds_domainid_t(domain), nullptr, nullptr);
    EXPECT_GT(pp, 0);
    pose_topic = dds_create_topic(pp, &geometry_msgs_msg_dds__PoseStamped__desc, "rt/gshaptics/tool_pose", nullptr, nullptr);
    wrench_topic = dds_create_topic(pp, &geometry_msgs_msg_dds__WrenchStamped__desc, "rt/gshaptics/wrench", nullptr, nullptr);
    marker_topic = dds_create_topic(pp, &visualization_msgs_msg_dds__MarkerArray__desc, "rt/gshaptics/markers", nullptr, nullptr);
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
    pose_writer = dds_create_writer(pp, pose_topic, q, nullptr);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 64);
    wrench_reader = dds_create_reader(pp, wrench_topic, q, nullptr);
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    marker_reader = dds_create_reader(pp, marker_topic, q, nullptr);
    dds_delete_qos(q);
  }
  ~PlainDds() { dds_delete(pp); }
  void send(double x, double y, double z, std::int32_t sec, std::uint32_t nsec) {
    geometry_msgs_msg_dds__PoseStamped_ m{};
    m.header.stamp.sec = sec;
    m.header.stamp.nanosec = nsec;
    m.header.frame_id = const_cast<char*>("world");
    m.pose.position = {x, y, z};
    m.pose.orientation = {0, 0, 0, 1};
    dds_write(pose_writer, &m);
  }
  /// Newest wrench within `wait`; returns false if none.
  bool newest_wrench(geometry_msgs_msg_dds__WrenchStamped_& out, std::string& frame,
                     std::chrono::milliseconds wait = 200ms) {
    const auto t0 = std::chrono::steady_clock::now();
    bool got = false;
    while (!got && std::chrono::steady_clock::now() - t0 < wait) {
      void* s[64] = {};
      dds_sample_info_t info[64];
      const int n = dds_take(wrench_reader, s, info, 64, 64);
      for (int i = 0; i < n; ++i)
        if (info[i].valid_data) {
          out = *static_cast<geometry_msgs_msg_dds__WrenchStamped_*>(s[i]);
          frame = out.header.frame_id;
          got = true;
        }
      if (n > 0) dds_return_loan(wrench_reader, s, n);
      if (!got) std::this_thread::sleep_for(2ms);
    }
    return got;
  }
};

class Ros2Bridge : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world_ = &test::truck_world();
  }
  void SetUp() override {
    domain_ = 10 + int(getpid() % 200);  // ctest runs tests in parallel: one domain each
    options_.domain = domain_;
    options_.marker_hz = 50;
    device_ = std::make_unique<Ros2NetworkDevice>(options_, MonotonicClock::instance());
    RuntimeConfig rc;
    // (The poses stream the tool straight into the truck and hold it there: the ellipsoid proxy
    // pushes it out from the first pose; the seen solid, seen from an approach, would see none.)
    rc.renderer = ProxyModelSpec{test::ellipsoid_params(), nullptr};
    rc.tool.semi_axes = Eigen::Vector3d::Constant(0.08);
    rc.safety.ramp_time = 0.02;
    rc.realtime.servo_priority = rc.realtime.worker_priority = 0;
    runtime_ = std::make_unique<HapticRuntime>(*world_, *device_, rc);
    snapshots_ = std::make_unique<ContactSnapshotObserver>(50, MonotonicClock::instance());
    runtime_->set_observer(snapshots_.get());
    markers_ = std::make_unique<Ros2MarkerPublisher>(*device_, *world_, *snapshots_, rc.tool.semi_axes);
    plain_ = std::make_unique<PlainDds>(domain_);
    runtime_->start();
    markers_->start();
    // Discovery: wait until our pose writer sees the node's reader.
    for (int i = 0; i < 500; ++i) {
      dds_publication_matched_status_t st{};
      dds_get_publication_matched_status(plain_->pose_writer, &st);
      if (st.current_count > 0) break;
      std::this_thread::sleep_for(10ms);
    }
  }
  void TearDown() override {
    markers_->stop();
    runtime_->request_stop();
    runtime_->wait();
  }
  /// Streams poses at ~1 kHz for `d`, pressing into the truck's middle.
  void stream(std::chrono::milliseconds d, double z = 0.5, int* count = nullptr) {
    const auto t0 = std::chrono::steady_clock::now();
    int n = 0;
    while (std::chrono::steady_clock::now() - t0 < d) {
      plain_->send(0.0, 0.0, z, 1000 + n, 12345);
      ++n;
      std::this_thread::sleep_for(1ms);
    }
    if (count) *count = n;
  }

  static const CollisionWorld* world_;
  int domain_ = 0;
  Ros2Options options_;
  std::unique_ptr<Ros2NetworkDevice> device_;
  std::unique_ptr<HapticRuntime> runtime_;
  std::unique_ptr<ContactSnapshotObserver> snapshots_;
  std::unique_ptr<Ros2MarkerPublisher> markers_;
  std::unique_ptr<PlainDds> plain_;
};
const CollisionWorld* Ros2Bridge::world_ = nullptr;

TEST(Ros2Names, TopicAndTypeNamesOfTheRos2WireFormat) {
  EXPECT_EQ(ros2_dds_topic("/gshaptics/wrench"), "rt/gshaptics/wrench");
  EXPECT_EQ(ros2_dds_topic("tool_pose"), "rt/tool_pose");
  EXPECT_STREQ(geometry_msgs_msg_dds__PoseStamped__desc.m_typename, "geometry_msgs::msg::dds_::PoseStamped_");
  EXPECT_STREQ(geometry_msgs_msg_dds__WrenchStamped__desc.m_typename, "geometry_msgs::msg::dds_::WrenchStamped_");
  EXPECT_STREQ(visualization_msgs_msg_dds__MarkerArray__desc.m_typename, "visualization_msgs::msg::dds_::MarkerArray_");
}

TEST_F(Ros2Bridge, PosesInWrenchOutWithTheStampEchoed) {
  stream(600ms);
  geometry_msgs_msg_dds__WrenchStamped_ w{};
  std::string frame;
  ASSERT_TRUE(plain_->newest_wrench(w, frame));
  const double f = std::hypot(w.wrench.force.x, w.wrench.force.y, w.wrench.force.z);
  EXPECT_GT(f, 0.1);  // the tool sits in the truck
  EXPECT_EQ(frame, "world");
  EXPECT_GE(w.header.stamp.sec, 1000);  // the stamp of a pose we sent
  EXPECT_EQ(w.header.stamp.nanosec, 12345u);
  EXPECT_GT(device_->stats().poses_received.load(), 100u);
  EXPECT_EQ(device_->stats().pose_publishers.load(), 1u);
}

TEST_F(Ros2Bridge, MarkerArrayHasTheToolAndTheContacts) {
  stream(500ms);
  const auto t0 = std::chrono::steady_clock::now();
  bool checked = false;
  while (!checked && std::chrono::steady_clock::now() - t0 < 3s) {
    void* s[8] = {};
    dds_sample_info_t info[8];
    const int n = dds_take(plain_->marker_reader, s, info, 8, 8);
    for (int i = 0; i < n && !checked; ++i) {
      if (!info[i].valid_data) continue;
      const auto* a = static_cast<visualization_msgs_msg_dds__MarkerArray_*>(s[i]);
      if (a->markers._length < 3) continue;
      const auto& clear = a->markers._buffer[0];
      const auto& tool = a->markers._buffer[1];
      const auto& c = a->markers._buffer[2];
      EXPECT_EQ(clear.action, 3);  // DELETEALL
      EXPECT_EQ(tool.type, 2);     // SPHERE
      EXPECT_STREQ(tool.ns, "tool");
      EXPECT_NEAR(tool.scale.x, 0.16, 1e-9);  // diameter
      EXPECT_NEAR(tool.pose.position.z, 0.5, 1e-9);
      EXPECT_STREQ(c.ns, "contacts");
      EXPECT_GE(c.id, 0);
      EXPECT_LT(c.id, 116544);
      EXPECT_GT(c.scale.x, 0.0);
      EXPECT_STREQ(c.header.frame_id, "world");
      checked = true;
    }
    if (n > 0) dds_return_loan(plain_->marker_reader, s, n);
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_TRUE(checked);
}

// The node's writers are RELIABLE keep-last 1 by default: a reliable subscriber (ROS 2's default)
// and a best-effort one (the fixture's) both receive the wrench.
TEST_F(Ros2Bridge, ReliableAndBestEffortSubscribersBothGetTheWrench) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 8);
  const dds_entity_t reliable = dds_create_reader(plain_->pp, plain_->wrench_topic, q, nullptr);
  dds_delete_qos(q);
  ASSERT_GT(reliable, 0);
  stream(500ms);
  geometry_msgs_msg_dds__WrenchStamped_ w{};
  std::string frame;
  ASSERT_TRUE(plain_->newest_wrench(w, frame));  // best-effort reader
  int got = 0;
  const auto t0 = std::chrono::steady_clock::now();
  while (got == 0 && std::chrono::steady_clock::now() - t0 < 3s) {
    stream(20ms);
    void* samples[8] = {};
    dds_sample_info_t infos[8];
    const int n = dds_take(reliable, samples, infos, 8, 8);
    for (int i = 0; i < n; ++i) got += infos[i].valid_data ? 1 : 0;
    if (n > 0) dds_return_loan(reliable, samples, n);
  }
  EXPECT_GT(got, 0);
  EXPECT_EQ(device_->stats().qos_incompatible.load(), 0u);
}

// A reliable subscriber against a node told to write best-effort cannot match: the node counts
// it and names the policy.
TEST(Ros2BridgeQos, AnIncompatibleSubscriberIsReported) {
  Ros2Options o;
  o.domain = 10 + int((getpid() + 97) % 200);
  o.reliable_output = false;
  Ros2NetworkDevice node(o, MonotonicClock::instance());
  node.start(MonotonicClock::instance().now());
  PlainDds peer(o.domain);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  const dds_entity_t reliable = dds_create_reader(peer.pp, peer.wrench_topic, q, nullptr);
  dds_delete_qos(q);
  ASSERT_GT(reliable, 0);
  const auto t0 = std::chrono::steady_clock::now();
  while (node.stats().qos_incompatible.load() == 0 && std::chrono::steady_clock::now() - t0 < 5s)
    std::this_thread::sleep_for(20ms);
  EXPECT_GT(node.stats().qos_incompatible.load(), 0u);
  EXPECT_EQ(ros2_qos_policy_name(node.stats().qos_last_policy.load()), "RELIABILITY");
  node.stop(MonotonicClock::instance().now());
}

// Rigid objects (issue 72): each object's pose goes out as a PoseStamped on
// gshaptics/objects/objectI, the markers draw it as a box at that pose, and a contact on the
// object is drawn where the object is now (its body-frame Gaussian moved by the pose).
TEST(Ros2BridgeObjects, EachObjectsPoseIsPublishedAndDrawnAsABox) {
  Ros2Options o;
  o.domain = 10 + int((getpid() + 53) % 200);
  o.marker_hz = 50;
  Ros2NetworkDevice node(o, MonotonicClock::instance());
  GaussianScene g;
  g.push_back({0.05f, 0.f, 0.f}, {0.01f, 0.01f, 0.001f}, {1.f, 0.f, 0.f, 0.f}, 0.9f, 77);
  const CollisionWorld scene = CollisionWorld::build(g, WorldConfig{});
  const RosObjects objects{{std::make_shared<const CollisionWorld>(CollisionWorld::build(g, WorldConfig{}))},
                           std::make_shared<ObjectPoseChannel>(), {Eigen::Vector3d(0.1, 0.08, 0.06)}};
  ContactSnapshotObserver snapshots(0, MonotonicClock::instance());
  Ros2MarkerPublisher markers(node, scene, snapshots, Eigen::Vector3d::Constant(0.01), objects);
  PlainDds peer(o.domain);
  const dds_entity_t pose_topic = dds_create_topic(peer.pp, &geometry_msgs_msg_dds__PoseStamped__desc,
                                                   "rt/gshaptics/objects/object0", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  const dds_entity_t pose_reader = dds_create_reader(peer.pp, pose_topic, q, nullptr);
  dds_delete_qos(q);
  ASSERT_GT(pose_reader, 0);
  markers.start();
  // What the servo thread would publish: the object moved and turned, the tool touching it.
  ObjectPoses poses;
  poses.count = 1;
  poses.poses[0].position = {0.2, 0.1, 0.03};
  poses.poses[0].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  const Contact touched{77, 0, 0.9f, 0, 1, 0.5, Eigen::Vector3d::Zero()};
  CollisionResult result;
  result.pose_sequence = 1;
  result.counts.contacts = 1;
  bool pose_seen = false, box_seen = false, contact_seen = false;
  const auto t0 = std::chrono::steady_clock::now();
  while (!(pose_seen && box_seen && contact_seen) && std::chrono::steady_clock::now() - t0 < 10s) {
    objects.poses->write(poses);
    snapshots.on_result(PoseCommand{}, std::span<const Contact>(&touched, 1), result);
    std::this_thread::sleep_for(20ms);
    void* s[8] = {};
    dds_sample_info_t info[8];
    int n = dds_take(pose_reader, s, info, 8, 8);
    for (int i = 0; i < n; ++i) {
      if (!info[i].valid_data) continue;
      const auto* m = static_cast<geometry_msgs_msg_dds__PoseStamped_*>(s[i]);
      EXPECT_NEAR(m->pose.position.x, 0.2, 1e-12);
      EXPECT_NEAR(m->pose.position.z, 0.03, 1e-12);
      EXPECT_NEAR(m->pose.orientation.z, std::sqrt(0.5), 1e-9);  // ROS order x, y, z, w
      EXPECT_NEAR(m->pose.orientation.w, std::sqrt(0.5), 1e-9);
      EXPECT_STREQ(m->header.frame_id, "world");
      pose_seen = true;
    }
    if (n > 0) dds_return_loan(pose_reader, s, n);
    n = dds_take(peer.marker_reader, s, info, 8, 8);
    for (int i = 0; i < n; ++i) {
      if (!info[i].valid_data) continue;
      const auto* a = static_cast<visualization_msgs_msg_dds__MarkerArray_*>(s[i]);
      for (std::uint32_t k = 0; k < a->markers._length; ++k) {
        const auto& m = a->markers._buffer[k];
        if (std::strcmp(m.ns, "objects") == 0) {
          EXPECT_EQ(m.type, 1);  // CUBE
          EXPECT_NEAR(m.pose.position.y, 0.1, 1e-12);
          EXPECT_NEAR(m.scale.x, 0.1, 1e-12);
          box_seen = true;
        }
        if (std::strcmp(m.ns, "contacts") == 0) {
          EXPECT_EQ(m.id, 77);
          EXPECT_NEAR(m.pose.position.x, 0.2, 1e-6);  // (0.05, 0, 0) turned to (0, 0.05, 0), then moved
          EXPECT_NEAR(m.pose.position.y, 0.15, 1e-6);
          contact_seen = true;
        }
      }
    }
    if (n > 0) dds_return_loan(peer.marker_reader, s, n);
  }
  markers.stop();
  EXPECT_TRUE(pose_seen) << "no PoseStamped on rt/gshaptics/objects/object0";
  EXPECT_TRUE(box_seen) << "no object box among the markers";
  EXPECT_TRUE(contact_seen) << "the object's contact was not drawn";
}

TEST_F(Ros2Bridge, PublisherDiesMidContactAndTheForceGoesToZero) {
  stream(500ms);
  geometry_msgs_msg_dds__WrenchStamped_ w{};
  std::string frame;
  ASSERT_TRUE(plain_->newest_wrench(w, frame));
  ASSERT_GT(std::hypot(w.wrench.force.x, w.wrench.force.y, w.wrench.force.z), 0.1);
  // The publisher stops (dies): after the input timeout (0.1 s) the watchdog zeroes the force.
  std::this_thread::sleep_for(300ms);
  ASSERT_TRUE(plain_->newest_wrench(w, frame));
  EXPECT_EQ(w.wrench.force.x, 0.0);
  EXPECT_EQ(w.wrench.force.y, 0.0);
  EXPECT_EQ(w.wrench.force.z, 0.0);
  EXPECT_GT(runtime_->stats().watchdog_ticks.load(), 100u);
}

TEST_F(Ros2Bridge, NanPosesAreDroppedAndCounted) {
  stream(300ms);
  for (int i = 0; i < 20; ++i) {
    plain_->send(std::nan(""), 0, 0.5, 1, 0);
    std::this_thread::sleep_for(1ms);
  }
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(device_->stats().poses_dropped.load(), 20u);
  EXPECT_EQ(runtime_->stats().invalid_pose_ticks.load(), 0u);  // never reached the servo loop
}

TEST_F(Ros2Bridge, SecondPublisherIsCountedAndTheNewestSampleWins) {
  PlainDds second(domain_);
  for (int i = 0; i < 500; ++i) {
    dds_publication_matched_status_t st{};
    dds_get_publication_matched_status(second.pose_writer, &st);
    if (st.current_count > 0) break;
    std::this_thread::sleep_for(10ms);
  }
  stream(200ms, 3.0);
  for (int i = 0; i < 200; ++i) {
    second.send(0.0, 0.0, 5.0, 1, 0);
    std::this_thread::sleep_for(1ms);
  }
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(device_->stats().pose_publishers.load(), 2u);
  TickRecord tick;
  ASSERT_TRUE(runtime_->latest_tick(tick));
  EXPECT_NEAR(tick.position.z(), 5.0, 1e-9);  // the newest sample (from the second publisher)
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

// Issue 73, item 5: ROS 2 tools find nodes through ros_discovery_info (rmw_dds_common
// ParticipantEntitiesInfo). A late reader (transient local) gets the node's namespace and name
// from --ros-args, and GIDs that are DDS GUIDs of one participant (same 12-octet prefix, the
// participant's entity id 0x000001c1), zero padded to 24 octets; two readers and a writer, and
// under admittance one reader and two writers more.
TEST(Ros2Discovery, TheNodeSaysItsNameAndEntitiesOnRosDiscoveryInfo) {
  for (const bool admittance : {false, true}) {
    Ros2Options o;
    o.domain = 10 + int((getpid() + 53 + (admittance ? 1 : 0)) % 200);
    o.ros_args = {"--ros-args", "-r", "__ns:=/arm1", "-r", "__node:=left"};
    o.admittance = admittance;
    Ros2NetworkDevice node(o, MonotonicClock::instance());
    const dds_entity_t pp = dds_create_participant(dds_domainid_t(o.domain), nullptr, nullptr);
    ASSERT_GT(pp, 0);
    const dds_entity_t topic = dds_create_topic(pp, &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
                                                "ros_discovery_info", nullptr, nullptr);
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
    const dds_entity_t reader = dds_create_reader(pp, topic, q, nullptr);
    dds_delete_qos(q);
    ASSERT_GT(reader, 0);
    bool got = false;
    const auto t0 = std::chrono::steady_clock::now();
    while (!got && std::chrono::steady_clock::now() - t0 < 10s) {
      void* s[4] = {};
      dds_sample_info_t info[4];
      const int n = dds_take(reader, s, info, 4, 4);
      for (int i = 0; i < n; ++i) {
        if (!info[i].valid_data) continue;
        const auto* m = static_cast<const rmw_dds_common_msg_dds__ParticipantEntitiesInfo_*>(s[i]);
        ASSERT_EQ(m->node_entities_info_seq._length, 1u);
        const auto& node_info = m->node_entities_info_seq._buffer[0];
        EXPECT_STREQ(node_info.node_namespace, "/arm1");
        EXPECT_STREQ(node_info.node_name, "left");
        EXPECT_EQ(node_info.reader_gid_seq._length, admittance ? 3u : 2u);
        EXPECT_EQ(node_info.writer_gid_seq._length, admittance ? 3u : 1u);
        const std::uint8_t* p = m->gid.data;
        EXPECT_EQ(p[12], 0x00);  // ENTITYID_PARTICIPANT: 0x000001c1
        EXPECT_EQ(p[13], 0x00);
        EXPECT_EQ(p[14], 0x01);
        EXPECT_EQ(p[15], 0xc1);
        for (int k = 16; k < 24; ++k) EXPECT_EQ(p[k], 0) << k;
        auto same_participant = [&](const rmw_dds_common_msg_dds__Gid_& g) {
          return std::memcmp(g.data, p, 12) == 0 && std::memcmp(g.data + 12, p + 12, 4) != 0;
        };
        for (std::uint32_t k = 0; k < node_info.reader_gid_seq._length; ++k)
          EXPECT_TRUE(same_participant(node_info.reader_gid_seq._buffer[k])) << k;
        for (std::uint32_t k = 0; k < node_info.writer_gid_seq._length; ++k)
          EXPECT_TRUE(same_participant(node_info.writer_gid_seq._buffer[k])) << k;
        got = true;
      }
      if (n > 0) dds_return_loan(reader, s, n);
      if (!got) std::this_thread::sleep_for(20ms);
    }
    EXPECT_TRUE(got) << "no ros_discovery_info within 10 s";
    dds_delete(pp);
  }
}

}  // namespace
}  // namespace gshaptics
