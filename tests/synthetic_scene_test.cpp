// Ground-truth scenes: Gaussians where the analytic surface is, counts that follow the spacing,
// byte-reproducible files that load through the normal path.

#include "gshaptics/fidelity/synthetic_scene.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

TEST(SyntheticScene, SurfaceGaussiansLieWithinTheirJitterOfTheSurface) {
  for (ShapeKind k : all_shapes()) {
    const AnalyticShape shape(k);
    SynthParams p;
    p.spacing = 0.004;
    const SyntheticScene s = make_synthetic_scene(shape, p);
    ASSERT_GT(s.surface_count, 500u) << shape.name();
    double sum2 = 0, worst = 0;
    for (std::size_t i = 0; i < s.surface_count; ++i) {
      const double d = shape.signed_distance(s.scene.means[i].cast<double>());
      sum2 += d * d;
      worst = std::max(worst, std::fabs(d));
    }
    const double sigma = std::sqrt(sum2 / double(s.surface_count));
    // Normal jitter N(0, 0.5 mm): the spread matches it, and nothing is past 6 sigma (float means).
    EXPECT_NEAR(sigma, p.normal_jitter, 0.15 * p.normal_jitter) << shape.name();
    EXPECT_LT(worst, 6 * p.normal_jitter) << shape.name();
    for (std::size_t i = s.surface_count; i < s.scene.size(); ++i) {
      const double d = shape.signed_distance(s.scene.means[i].cast<double>());
      EXPECT_GE(d, p.floater_min - 1e-6) << shape.name() << " floater " << i;
      EXPECT_LE(d, p.floater_max + 1e-6) << shape.name() << " floater " << i;
      // Its whole ellipsoid clears the surface (the largest semi-axis is the first).
      EXPECT_GE(d - double(s.scene.scales[i].maxCoeff()), p.floater_clearance - 1e-6) << shape.name() << " floater " << i;
    }
  }
}

TEST(SyntheticScene, FloatersTouchNoGaussianOfTheSurface) {
  // Grown by the clearance, no floater touches a Gaussian of the surface the default world keeps
  // (a face's discs overhang a cube's edges by up to a disc radius: with the distance rule alone,
  // seed 14's 8 mm cube had a floater resting on them, 3.5 mm off the analytic surface).
  for (ShapeKind k : all_shapes())
    for (std::uint64_t seed = 1; seed <= 16; ++seed) {
      const AnalyticShape shape(k);
      SynthParams sparse;
      sparse.spacing = 0.008;
      sparse.seed = seed;
      const SyntheticScene c = make_synthetic_scene(shape, sparse);
      GaussianScene surface;
      surface.frame = c.scene.frame;
      for (std::size_t i = 0; i < c.surface_count; ++i) surface.push_back_from(c.scene, i);
      const CollisionWorld world = CollisionWorld::build(surface, WorldConfig{});
      ContactQuery query(world);
      for (std::size_t i = c.surface_count; i < c.scene.size(); ++i) {
        const Eigen::Vector4f& w = c.scene.rotations[i];
        ToolEllipsoid grown;
        grown.center = c.scene.means[i].cast<double>();
        grown.rotation = Eigen::Quaterniond(w[0], w[1], w[2], w[3]).normalized();
        grown.semi_axes = c.scene.scales[i].cast<double>().array() + sparse.floater_clearance;
        EXPECT_FALSE(query.any_contact(grown)) << shape.name() << " seed " << seed << " floater " << i;
      }
    }
}

TEST(SyntheticScene, DiscsLieFlatOnTheSurfaceWithTheStatedSizes) {
  const AnalyticShape shape(ShapeKind::kSphere);
  SynthParams p;
  const SyntheticScene s = make_synthetic_scene(shape, p);
  double tilt2 = 0, log_scale = 0;
  std::size_t low_opacity = 0;
  for (std::size_t i = 0; i < s.surface_count; ++i) {
    const Eigen::Vector4f& q = s.scene.rotations[i];
    const Eigen::Matrix3d R = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).toRotationMatrix();
    const Eigen::Vector3f& sc = s.scene.scales[i];
    // The thin axis is the third one, along the normal, 2-10 % of the in-plane scale.
    EXPECT_LE(sc.z(), 0.1f * std::min(sc.x(), sc.y()) * 1.0001f);
    EXPECT_GE(sc.z(), 0.02f * std::min(sc.x(), sc.y()) * 0.9999f);
    const Eigen::Vector3d n = s.scene.means[i].cast<double>().normalized();
    const double angle = std::acos(std::min(1.0, std::fabs(R.col(2).dot(n)))) * 180 / 3.14159265358979;
    tilt2 += angle * angle;
    log_scale += std::log(double(sc.x()) / p.spacing);
    low_opacity += s.scene.opacities[i] < 0.2f ? 1 : 0;
  }
  const double n = double(s.surface_count);
  // Tilt N(0, 3 deg) in two directions: rms angle ~ 3 deg (the normal's own jitter adds a little).
  EXPECT_NEAR(std::sqrt(tilt2 / n), p.tilt_deg, 1.0);
  EXPECT_NEAR(log_scale / n, 0.0, 0.02);  // log-normal around the spacing
  EXPECT_NEAR(double(low_opacity) / n, p.low_opacity_share, 0.02);
}

TEST(SyntheticScene, CountsScaleWithTheSpacing) {
  for (ShapeKind k : all_shapes()) {
    const AnalyticShape shape(k);
    std::size_t count[3];
    const double spacing[3] = {0.002, 0.004, 0.008};
    for (int i = 0; i < 3; ++i) {
      SynthParams p;
      p.spacing = spacing[i];
      count[i] = make_synthetic_scene(shape, p).surface_count;
    }
    // Halving the spacing quadruples the count (rounding of the grids on small faces aside).
    EXPECT_NEAR(double(count[0]) / double(count[1]), 4.0, 0.4) << shape.name();
    EXPECT_NEAR(double(count[1]) / double(count[2]), 4.0, 0.8) << shape.name();
  }
}

TEST(SyntheticScene, SeedReproducesTheFileByteForByteAndLoadsAsPly) {
  const AnalyticShape shape(ShapeKind::kCube);
  SynthParams p;
  p.spacing = 0.008;
  p.seed = 42;
  const std::string a = test::temp_path(".ply"), b = test::temp_path(".ply"), c = test::temp_path(".ply");
  write_synthetic_scene(a, make_synthetic_scene(shape, p));
  write_synthetic_scene(b, make_synthetic_scene(shape, p));
  p.seed = 43;
  write_synthetic_scene(c, make_synthetic_scene(shape, p));
  EXPECT_EQ(test::read_bytes(a), test::read_bytes(b));
  EXPECT_NE(test::read_bytes(a), test::read_bytes(c));

  const LoadedScene loaded = load_scene(a);
  p.seed = 42;
  const SyntheticScene s = make_synthetic_scene(shape, p);
  ASSERT_EQ(loaded.scene.size(), s.scene.size());
  EXPECT_EQ(loaded.report.format, SceneFormat::kInriaPly);
  for (std::size_t i = 0; i < s.scene.size(); i += 97) {
    EXPECT_EQ(loaded.scene.means[i], s.scene.means[i]);
    EXPECT_NEAR(loaded.scene.opacities[i], s.scene.opacities[i], 1e-6);
    EXPECT_NEAR(loaded.scene.scales[i].x(), s.scene.scales[i].x(), 1e-6 * s.scene.scales[i].x());
  }
  const std::vector<std::uint8_t> bytes = test::read_bytes(a);
  const std::string header(bytes.begin(), bytes.begin() + 1200);
  EXPECT_NE(header.find("comment shape cube"), std::string::npos);
  EXPECT_NE(header.find("comment spacing_m 0.008"), std::string::npos);
  EXPECT_NE(header.find("comment seed 42"), std::string::npos);
  std::ifstream in(a + ".json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["surface"]["type"], "box");
  EXPECT_EQ(j["counts"]["total"].get<std::size_t>(), s.scene.size());
  EXPECT_DOUBLE_EQ(j["parameters"]["spacing_m"].get<double>(), 0.008);
}

TEST(SyntheticScene, BadParametersAreErrors) {
  SynthParams p;
  p.spacing = 0;
  EXPECT_THROW((void)make_synthetic_scene(AnalyticShape(ShapeKind::kPlane), p), InputError);
  p = {};
  p.low_opacity_share = 1.5;
  EXPECT_THROW((void)make_synthetic_scene(AnalyticShape(ShapeKind::kPlane), p), InputError);
  EXPECT_THROW((void)parse_shape("torus", "test"), InputError);
  EXPECT_EQ(parse_shape("v-groove-60", "test"), ShapeKind::kVGroove60);
}

}  // namespace
}  // namespace gshaptics
