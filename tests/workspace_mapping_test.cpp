// Workspace mapping: scale and offset, forces unscaled, the clutch re-centres without moving the
// tool in the scene, bubble rate control drifts the mapping outward, and the mapped device.

#include "gshaptics/device/workspace_mapping.h"

#include <gtest/gtest.h>

#include "gshaptics/error.h"

namespace gshaptics {
namespace {

DeviceSample at(const Eigen::Vector3d& p, std::uint32_t buttons = 0, const Eigen::Vector3d& v = Eigen::Vector3d::Zero()) {
  DeviceSample s;
  s.sequence = 1;
  s.position = p;
  s.velocity = v;
  s.buttons = buttons;
  return s;
}

TEST(WorkspaceMapping, ScaleRotationOffsetAndUnscaledForce) {
  WorkspaceMappingParams p;
  p.scale = 20;  // a 16 cm workspace over a 3.2 m truck
  p.rotation = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
  p.offset = Eigen::Vector3d(1, 2, 3);
  WorkspaceMapping m(p);
  const DeviceSample w = m.to_world(at({0.01, 0, 0}, 0, {0.1, 0, 0}), 1e-3);
  EXPECT_TRUE(w.position.isApprox(Eigen::Vector3d(1, 2.2, 3), 1e-12));  // x device -> y world, x20
  EXPECT_TRUE(w.velocity.isApprox(Eigen::Vector3d(0, 2, 0), 1e-12));
  Wrench f;
  f.force = Eigen::Vector3d(0, 1, 0);  // 1 N along world y
  const Wrench d = m.to_device(f);
  EXPECT_TRUE(d.force.isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));  // 1 N in the hand, not 1/20 or 20
  const Eigen::AlignedBox3d box = m.world_box(Eigen::AlignedBox3d(Eigen::Vector3d(-0.08, -0.06, -0.035),
                                                                  Eigen::Vector3d(0.08, 0.06, 0.035)));
  EXPECT_NEAR(box.sizes().x(), 2.4, 1e-9);
  EXPECT_NEAR(box.sizes().y(), 3.2, 1e-9);
}

TEST(WorkspaceMapping, ClutchRecentresWithoutMovingTheTool) {
  WorkspaceMappingParams p;
  p.scale = 10;
  p.clutch_button = 1;
  WorkspaceMapping m(p);
  EXPECT_TRUE(m.to_world(at({0.05, 0, 0}), 1e-3).position.isApprox(Eigen::Vector3d(0.5, 0, 0)));
  // Clutch in at x = 5 cm, move the hand back to the centre: the tool stays, no force.
  const DeviceSample held = m.to_world(at({0.05, 0, 0}, 0b10), 1e-3);
  EXPECT_TRUE(m.clutched());
  for (double x = 0.05; x >= 0; x -= 0.005) {
    const DeviceSample s = m.to_world(at({x, 0, 0}, 0b10, {-5, 0, 0}), 1e-3);
    EXPECT_TRUE(s.position.isApprox(held.position, 1e-12));
    EXPECT_TRUE(s.velocity.isZero(0));
  }
  Wrench f;
  f.force = Eigen::Vector3d(3, 0, 0);
  EXPECT_TRUE(m.to_device(f).force.isZero(0));
  // Release at the centre: the tool continues from where it was held; moving on works from there.
  const DeviceSample r = m.to_world(at({0, 0, 0}), 1e-3);
  EXPECT_FALSE(m.clutched());
  EXPECT_TRUE(r.position.isApprox(Eigen::Vector3d(0.5, 0, 0), 1e-12));
  EXPECT_TRUE(m.to_world(at({0.01, 0, 0}), 1e-3).position.isApprox(Eigen::Vector3d(0.6, 0, 0), 1e-12));
  EXPECT_TRUE(m.to_device(f).force.isApprox(f.force));
}

TEST(WorkspaceMapping, BubbleDriftsOutwardBeyondTheRadiusOnly) {
  WorkspaceMappingParams p;
  p.scale = 1;
  p.bubble_radius = 0.05;
  p.bubble_gain = 10;  // 10 world m/s per device m beyond the radius
  WorkspaceMapping m(p);
  for (int i = 0; i < 1000; ++i) (void)m.to_world(at({0.04, 0, 0}), 1e-3);
  EXPECT_TRUE(m.offset().isZero(0));  // inside: no drift
  for (int i = 0; i < 1000; ++i) (void)m.to_world(at({0, 0.06, 0}), 1e-3);  // 1 cm beyond, 1 s
  EXPECT_NEAR(m.offset().y(), 10 * 0.01 * 1.0, 1e-9);
  EXPECT_NEAR(m.offset().x(), 0, 1e-12);
}

TEST(WorkspaceMapping, RejectsBadParameters) {
  WorkspaceMappingParams p;
  p.scale = 0;
  EXPECT_THROW(WorkspaceMapping{p}, InputError);
  p.scale = 1;
  p.bubble_gain = -1;
  EXPECT_THROW(WorkspaceMapping{p}, InputError);
}

class FakeDevice final : public HapticDevice {
 public:
  FakeDevice() {
    info_.name = "fake";
    info_.workspace = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.1), Eigen::Vector3d::Constant(0.1));
  }
  const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos) override {}
  DeviceSample read(Nanos) noexcept override { return sample; }
  void write(const Wrench& w, Nanos) noexcept override { last = w; }
  void stop(Nanos) noexcept override {}
  DeviceInfo info_;
  DeviceSample sample = at({0, 0, 0});
  Wrench last;
};

TEST(MappedDevice, MapsReadsAndWritesAndRefusesPosesOutsideTheDevice) {
  FakeDevice fake;
  WorkspaceMappingParams p;
  p.scale = 10;
  p.offset = Eigen::Vector3d(0, 0, 1);
  MappedDevice dev(fake, p);
  dev.start(1);
  fake.sample = at({0.02, 0, 0});
  EXPECT_TRUE(dev.read(1000000).position.isApprox(Eigen::Vector3d(0.2, 0, 1)));
  Wrench f;
  f.force = Eigen::Vector3d(0, 0, 2);
  dev.write(f, 2000000);
  EXPECT_TRUE(fake.last.force.isApprox(Eigen::Vector3d(0, 0, 2)));
  fake.sample = at({0.2, 0, 0});  // outside the fake's 10 cm box
  EXPECT_TRUE(dev.read(3000000).position.hasNaN());
  EXPECT_NE(dev.info().name.find("mapped"), std::string::npos);
}

}  // namespace
}  // namespace gshaptics
