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
#include "gshaptics/scene/seen_surface.h"
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

// The share of vertical rays, `past` m beyond the 0.2 m cube's top edge (x = 0.1) at y across the
// face, on which the top face is seen (median depth within 1 mm of its level).
double top_seen_past_edge(const SeenSurface& seen, double past) {
  int top = 0;
  constexpr int kRays = 100;
  for (int i = 0; i < kRays; ++i) {
    const double y = -0.08 + 0.16 * (i + 0.5) / kRays;
    const SeenDepth d = seen.median_depth(Eigen::Vector3d(0.1 + past, y, 0.3), -Eigen::Vector3d::UnitZ());
    if (d.hit && 0.3 - d.depth > 0.099) ++top;
  }
  return double(top) / kRays;
}

TEST(SyntheticScene, EdgeSigmasKeepTheCubesDiscsWithinItsEdges) {
  const AnalyticShape cube(ShapeKind::kCube);
  SynthParams p;
  p.spacing = 0.008;
  const SyntheticScene alike = make_synthetic_scene(cube, p);
  p.edge_sigmas = 1.17;
  const SyntheticScene crisp = make_synthetic_scene(cube, p);
  ASSERT_EQ(alike.surface_count, crisp.surface_count);
  const std::vector<SurfaceSample> samples = cube.sample_surface(p.spacing);
  ASSERT_EQ(samples.size(), crisp.surface_count);
  std::size_t narrowed = 0;
  for (std::size_t i = 0; i < crisp.surface_count; ++i) {
    std::array<FaceBorder, 2> borders;
    ASSERT_EQ(cube.convex_borders(samples[i], borders), 2);
    const auto cov = [](const GaussianScene& g, std::size_t k) {
      const Eigen::Vector4f& q = g.rotations[k];
      const Eigen::Matrix3d r = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
      return Eigen::Matrix3d(r * g.scales[k].cast<double>().cwiseAbs2().asDiagonal() * r.transpose());
    };
    bool reached = false;
    for (const FaceBorder& b : borders) {
      // Toward each edge, at most its distance over 1.17 standard deviations (float rounding aside).
      EXPECT_LE(std::sqrt(b.outward.dot(cov(crisp.scene, i) * b.outward)), b.distance / 1.17 * (1 + 1e-5) + 1e-9) << i;
      reached = reached || std::sqrt(b.outward.dot(cov(alike.scene, i) * b.outward)) > b.distance / 1.17;
    }
    // A disc the edges do not reach is the one drawn without the option, bit for bit.
    if (!reached) {
      EXPECT_EQ(crisp.scene.scales[i], alike.scene.scales[i]) << i;
      EXPECT_EQ(crisp.scene.rotations[i], alike.scene.rotations[i]) << i;
    }
    EXPECT_EQ(crisp.scene.means[i], alike.scene.means[i]) << i;
    narrowed += reached ? 1 : 0;
  }
  EXPECT_GT(narrowed, crisp.surface_count / 20);
  // Seen from above, 5 mm past the edge: the overhanging top face without the option, nothing
  // with it; the corner is still seen where it is along its diagonal (not a hole).
  EXPECT_GT(top_seen_past_edge(SeenSurface(alike.scene), 0.005), 0.8);
  const SeenSurface seen(crisp.scene);
  EXPECT_LT(top_seen_past_edge(seen, 0.005), 0.05);
  const Eigen::Vector3d diagonal = -Eigen::Vector3d(1, 1, 1).normalized();
  const SeenDepth corner = seen.median_depth(Eigen::Vector3d(0.1, 0.1, 0.1) - 0.1 * diagonal, diagonal);
  ASSERT_TRUE(corner.hit);
  EXPECT_NEAR(corner.depth, 0.1, 0.001);
}

TEST(SyntheticScene, BadParametersAreErrors) {
  SynthParams p;
  p.spacing = 0;
  EXPECT_THROW((void)make_synthetic_scene(AnalyticShape(ShapeKind::kPlane), p), InputError);
  p = {};
  p.low_opacity_share = 1.5;
  EXPECT_THROW((void)make_synthetic_scene(AnalyticShape(ShapeKind::kPlane), p), InputError);
  p = {};
  p.edge_sigmas = -1;
  EXPECT_THROW((void)make_synthetic_scene(AnalyticShape(ShapeKind::kCube), p), InputError);
  EXPECT_THROW((void)parse_shape("torus", "test"), InputError);
  EXPECT_EQ(parse_shape("v-groove-60", "test"), ShapeKind::kVGroove60);
}

}  // namespace
}  // namespace gshaptics
