// The fidelity metrics can fail: an oracle force (F = k delta n_true) scores perfectly, and
// deliberately wrong models (a rotated normal, stiffness counting contacts, an active spring,
// sideways drag) score what they should.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "gshaptics/fidelity/fidelity_run.h"
#include "gshaptics/percentile.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

// These tests check the metrics on synthetic renderers, so the servo step's passivity
// controller stays off (observe only): it would dissipate what the soft start makes look active.
PlayOptions metrics_only() {
  PlayOptions o;
  o.safety.passivity.enabled = false;
  return o;
}

constexpr double kK = 1000.0;  // N/m = 1 N/mm

// F = k delta n against the analytic surface. With a site: delta along the site's normal line
// (what a press sees, also through a plate); without: delta = r - signed distance, n its gradient.
class Oracle : public ForceRenderer {
 public:
  Oracle(const AnalyticShape& shape, const ContactSite* site, double rotate_deg = 0, double unload_gain = 1,
         double drag = 0)
      : shape_(shape), site_(site), rotate_(rotate_deg), unload_gain_(unload_gain), drag_(drag) {}
  std::string_view name() const noexcept override { return "oracle"; }
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& v, double) noexcept override {
    const double r = tool.semi_axes.x();
    Eigen::Vector3d n;
    double delta;
    if (site_ != nullptr) {
      n = site_->normal;
      delta = r - (tool.center - site_->point).dot(n);
    } else {
      n = distance_gradient(shape_, tool.center);
      delta = r - shape_.signed_distance(tool.center);
    }
    RenderOutput out;
    if (delta <= 0) return out;
    const double gain = v.dot(n) > 0 ? unload_gain_ : 1.0;  // moving out: unloading
    Eigen::Vector3d dir = n;
    if (rotate_ != 0) {
      const Eigen::Vector3d axis = n.cross(std::fabs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).normalized();
      dir = Eigen::AngleAxisd(rotate_ * M_PI / 180, axis) * n;
    }
    out.force = gain * kK * delta * dir;
    if (drag_ != 0 && v.norm() > 0) {
      const Eigen::Vector3d vt = v - v.dot(n) * n;
      if (vt.norm() > 1e-9) out.force -= drag_ * kK * delta * vt.normalized();
    }
    out.counts.contacts = 1;
    return out;
  }
  std::span<const Contact> contacts() const noexcept override { return {}; }
  void reset() noexcept override {}

 private:
  const AnalyticShape& shape_;
  const ContactSite* site_;
  double rotate_, unload_gain_, drag_;
};

// Stiffness that counts contacts (the paper's F_elastic = k_base N), along the true normal.
class CountingModel : public ForceRenderer {
 public:
  CountingModel(const CollisionWorld& w, const ContactSite& site) : query_(w), site_(site) {}
  std::string_view name() const noexcept override { return "counting"; }
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d&, double) noexcept override {
    RenderOutput out;
    query_.run(tool);
    out.counts = query_.result().counts;
    out.force = 0.05 * double(out.counts.contacts) * site_.normal;
    return out;
  }
  std::span<const Contact> contacts() const noexcept override { return query_.result().contacts(); }
  void reset() noexcept override {}

 private:
  ContactQuery query_;
  const ContactSite& site_;
};

TEST(FidelityMetrics, OracleScoresPerfectly) {
  for (ShapeKind k : {ShapeKind::kPlane, ShapeKind::kSphere, ShapeKind::kCube, ShapeKind::kCylinder}) {
    const AnalyticShape shape(k);
    for (const ContactSite& site : shape.press_sites(5, 3, 0.03)) {
      Oracle oracle(shape, &site);
      const Script s = press_script(shape, site, 0.005, 0.01, 1000);
      const PressMetrics m = press_metrics(shape, s, play_script(oracle, s, 1000, metrics_only()));
      ASSERT_FALSE(m.direction_deg.empty());
      EXPECT_LT(*std::max_element(m.direction_deg.begin(), m.direction_deg.end()), 1e-3) << shape.name();
      EXPECT_NEAR(m.stiffness_n_per_mm, kK * 1e-3, 1e-6) << shape.name();
      EXPECT_NEAR(m.onset_mm, 0.1, 0.021) << shape.name();  // |F| > 0.1 N at delta > 0.1 mm
      EXPECT_TRUE(m.never_lost) << shape.name();
      EXPECT_NEAR(m.hold_through_mm, 10.0, 0.05) << shape.name();
      EXPECT_NEAR(m.energy_j, 0.0, 1e-9) << shape.name();  // conservative spring, same samples in and out
      EXPECT_NEAR(m.peak_force, kK * 0.01, 1e-6);
    }
  }
}

TEST(FidelityMetrics, OracleHoldsThroughAPlateAndIntoAConcaveCorner) {
  const AnalyticShape plate(ShapeKind::kPlate2mm);
  const ContactSite site = plate.press_sites(1, 1, 0.03)[0];
  Oracle oracle(plate, &site);
  const Script s = press_script(plate, site, 0.005, 0.03, 1000);
  const PressMetrics m = press_metrics(plate, s, play_script(oracle, s, 1000, metrics_only()));
  EXPECT_TRUE(m.never_lost);
  EXPECT_NEAR(m.hold_through_mm, 30.0, 0.05);

  // Concave corner line: pressed along the bisector; F = k delta along the bisector lies inside
  // the cone of the two faces.
  const AnalyticShape corner(ShapeKind::kCorner90);
  for (const ContactSite& c : corner.press_sites(6, 2, 0.03)) {
    Oracle o(corner, &c);
    const Script cs = press_script(corner, c, 0.005, 0.01, 1000);
    const PressMetrics cm = press_metrics(corner, cs, play_script(o, cs, 1000, metrics_only()));
    EXPECT_LT(percentile(cm.direction_deg, 100), 1e-3) << c.feature;
    // On the corner line the faces see delta at 1/sqrt(2) of the bisector travel.
    EXPECT_GT(cm.stiffness_n_per_mm, 0.99) << c.feature;
  }
}

TEST(FidelityMetrics, RotatedNormalScoresItsAngle) {
  const AnalyticShape shape(ShapeKind::kPlane);
  const ContactSite site = shape.press_sites(1, 1, 0.03)[0];
  Oracle rotated(shape, &site, 20.0);
  const Script s = press_script(shape, site, 0.005, 0.01, 1000);
  const PressMetrics m = press_metrics(shape, s, play_script(rotated, s, 1000, metrics_only()));
  EXPECT_NEAR(percentile(m.direction_deg, 50), 20.0, 1e-6);
  EXPECT_NEAR(percentile(m.direction_deg, 95), 20.0, 1e-6);
  EXPECT_NEAR(m.stiffness_n_per_mm, 1.0, 1e-6);  // |F| unchanged
}

TEST(FidelityMetrics, ActiveSpringHasNegativeEnergy) {
  const AnalyticShape shape(ShapeKind::kSphere);
  const ContactSite site = shape.press_sites(1, 1, 0.03)[0];
  Oracle active(shape, &site, 0, /*unload_gain=*/1.5);
  const Script s = press_script(shape, site, 0.005, 0.01, 1000);
  const PressMetrics m = press_metrics(shape, s, play_script(active, s, 1000, metrics_only()));
  // In: 0.5 k d^2 = 0.05 J taken; out: 1.5 times that given back: W = -0.025 J.
  EXPECT_NEAR(m.energy_j, -0.5 * 0.5 * kK * 0.01 * 0.01, 2e-4);
}

TEST(FidelityMetrics, StiffnessThatCountsContactsDependsOnDensity) {
  const AnalyticShape shape(ShapeKind::kPlane);
  const ContactSite site{{0.01, -0.02, 0}, Eigen::Vector3d::UnitZ(), "face"};
  double stiffness[2];
  const double spacing[2] = {0.002, 0.008};
  for (int i = 0; i < 2; ++i) {
    SynthParams p;
    p.spacing = spacing[i];
    p.floater_share = 0;
    const SyntheticScene sc = make_synthetic_scene(shape, p);
    const CollisionWorld world = CollisionWorld::build(sc.scene, WorldConfig{});
    CountingModel model(world, site);
    const Script s = press_script(shape, site, 0.01, 0.01, 1000);
    stiffness[i] = press_metrics(shape, s, play_script(model, s, 1000, metrics_only())).stiffness_n_per_mm;
  }
  // 4x finer Gaussians, ~16x the contacts per mm of penetration.
  EXPECT_GT(stiffness[0] / stiffness[1], 5.0) << stiffness[0] << " vs " << stiffness[1];
}

TEST(FidelityMetrics, SlidesScoreSmoothnessAndDrag) {
  for (ShapeKind k : {ShapeKind::kPlane, ShapeKind::kSphere, ShapeKind::kCube, ShapeKind::kCorner90}) {
    const AnalyticShape shape(k);
    const Script s = slide_script(shape, 0.005, 1000);
    Oracle ideal(shape, nullptr);
    const SlideMetrics m = slide_metrics(shape, s, play_script(ideal, s, 1000, metrics_only()));
    EXPECT_NEAR(m.mean_force, kK * 0.002, 1e-3) << shape.name();  // 2 mm deep all along
    EXPECT_LT(m.force_rsd, 1e-3) << shape.name();
    EXPECT_LT(m.tangential_over_normal, 1e-3) << shape.name();
    EXPECT_LT(percentile(m.direction_deg, 100), 0.05) << shape.name();
    Oracle dragging(shape, nullptr, 0, 1, /*drag=*/0.3);
    const SlideMetrics d = slide_metrics(shape, s, play_script(dragging, s, 1000, metrics_only()));
    EXPECT_NEAR(d.tangential_over_normal, 0.3, 0.01) << shape.name();
  }
}

// The oracle that lets go once the tool's centre is past the cube's edge (x > 0.1): the force a
// proxy gives when it loses the side face over a convex edge.
class LosesTheSideFace : public Oracle {
 public:
  using Oracle::Oracle;
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& v, double dt) noexcept override {
    return tool.center.x() > 0.1 ? RenderOutput{} : Oracle::render(tool, v, dt);
  }
};

// A slide's lost share counts the scored ticks without force; the direction error cannot see
// them (it is scored over ticks with force only), the largest step sees where they begin.
TEST(FidelityMetrics, ASlideThatLetsGoOfTheSurfaceIsCountedLost) {
  const AnalyticShape cube(ShapeKind::kCube);
  const Script s = slide_script(cube, 0.005, 1000);
  Oracle ideal(cube, nullptr);
  const SlideMetrics held = slide_metrics(cube, s, play_script(ideal, s, 1000, metrics_only()));
  EXPECT_EQ(held.lost_share, 0.0);
  EXPECT_LT(held.largest_step, 0.05 * held.mean_force);  // (the exact god-object rolls round the edge)
  int measured = 0, past = 0;
  for (const ScriptTick& t : s.ticks) {
    if (!t.measured) continue;
    ++measured;
    past += t.position.x() > 0.1 ? 1 : 0;
  }
  ASSERT_GT(past, measured / 4);  // (the path goes down the side face for a third of its length)
  LosesTheSideFace losing(cube, nullptr);
  const SlideMetrics m = slide_metrics(cube, s, play_script(losing, s, 1000, metrics_only()));
  EXPECT_NEAR(m.lost_share, double(past) / measured, 2.0 / measured);
  EXPECT_GT(m.largest_step, 0.9 * held.mean_force);  // and the force ended in one tick
  EXPECT_LT(percentile(m.direction_deg, 100), 0.05);  // the ticks with force are all right
}

// A slide's force is scored against the faces the sphere reaches: in the concave corner a rigid
// 5 mm sphere 3 mm above the floor and 4 mm from the wall touches both, and the exact god-object
// (the sphere's centre held at 5 mm from each) pushes it along (1, 0, 2). The face nearest the
// device alone (the floor) would call that 26.6 degrees off; 8 mm from the wall the sphere reaches
// the floor only, and the same push is 26.6 degrees off. Convex shapes keep their normal cone.
TEST(FidelityMetrics, ASlideIsScoredAgainstTheFacesTheSphereReaches) {
  const AnalyticShape corner(ShapeKind::kCorner90);
  const double r = 0.005;
  const Eigen::Vector3d device(0.004, 0, 0.003);
  const Eigen::Vector3d push = Eigen::Vector3d(r, 0, r) - device;  // to the god-object
  const double off = std::atan2(1.0, 2.0) * 180 / M_PI;
  EXPECT_NEAR(corner.normal_cone(device).angle_deg(push), off, 1e-6);
  EXPECT_NEAR(corner.sphere_cone(device, r).angle_deg(push), 0.0, 1e-9);
  EXPECT_NEAR(corner.sphere_cone({0.008, 0, 0.003}, r).angle_deg(push), off, 1e-6);
  // ... a push out of both walls' cone is still off (into the wall: 45 degrees from the floor).
  EXPECT_NEAR(corner.sphere_cone(device, r).angle_deg({-1, 0, 1}), 45.0, 1e-6);
  // The 60-degree groove: a sphere 1.1 and 2.9 mm from its walls reaches both; one of 1.5 mm the
  // nearer only.
  const AnalyticShape groove(ShapeKind::kVGroove60);
  EXPECT_EQ(groove.sphere_cone({0.001, 0, 0.004}, r).count, 2);
  EXPECT_EQ(groove.sphere_cone({0.001, 0, 0.004}, 0.0015).count, 1);
  const AnalyticShape cube(ShapeKind::kCube);
  const Eigen::Vector3d beside(0.103, 0.0, 0.099);
  EXPECT_EQ(cube.sphere_cone(beside, r).count, cube.normal_cone(beside).count);
  EXPECT_NEAR(cube.sphere_cone(beside, r).angle_deg({0, 0, 1}), cube.normal_cone(beside).angle_deg({0, 0, 1}), 1e-12);
}

TEST(FidelityMetrics, NormalConeAnglesAtEdgesAndCorners) {
  const AnalyticShape cube(ShapeKind::kCube);
  const NormalCone edge = cube.normal_cone({0.1, 0.0, 0.1});
  ASSERT_EQ(edge.count, 2);
  EXPECT_NEAR(edge.angle_deg({1, 0, 1}), 0.0, 1e-9);
  EXPECT_NEAR(edge.angle_deg({1, 0, 0.2}), 0.0, 1e-9);
  EXPECT_NEAR(edge.angle_deg({1, 0, -1}), 45.0, 1e-9);
  const NormalCone corner = cube.normal_cone({0.1, 0.1, 0.1});
  ASSERT_EQ(corner.count, 3);
  EXPECT_NEAR(corner.angle_deg({1, 2, 3}), 0.0, 1e-9);
  EXPECT_NEAR(corner.angle_deg({-1, -1, -1}), 180.0 - std::acos(1 / std::sqrt(3.0)) * 180 / M_PI, 1e-6);
  const NormalCone face = cube.normal_cone({0.1, 0.02, 0.03});
  ASSERT_EQ(face.count, 1);
  EXPECT_NEAR(face.angle_deg({-1, 0, 0}), 180.0, 1e-9);
}

}  // namespace
}  // namespace gshaptics
