// The edge normal (edge_normal.h): a tool resting on a clean convex edge of flat discs gets the
// support normal across the edge; a face, a groove and a messy patch keep the shaded normal.

#include "gshaptics/force/edge_normal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "support/gaussian_worlds.h"

namespace gshaptics {
namespace {

using test::GaussianSpec;
using test::world_of;

// Discs 4 mm apart, 2.4 mm wide, 0.2 mm thick, on two half-planes meeting along the y axis: the
// first with normal n1 over direction -d1 from the edge, the second with n2 over -d2.
CollisionWorld two_faces(const Eigen::Vector3f& n1, const Eigen::Vector3f& d1, const Eigen::Vector3f& n2,
                         const Eigen::Vector3f& d2) {
  std::vector<GaussianSpec> gs;
  const Eigen::Quaternionf q1 = Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), n1);
  const Eigen::Quaternionf q2 = Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), n2);
  for (float y = -0.04f; y <= 0.04f; y += 0.004f)
    for (float s = 0.002f; s <= 0.06f; s += 0.004f) {
      gs.emplace_back(Eigen::Vector3f(0, y, 0) - s * d1, Eigen::Vector3f(0.0024f, 0.0024f, 0.0001f), q1);
      gs.emplace_back(Eigen::Vector3f(0, y, 0) - s * d2, Eigen::Vector3f(0.0024f, 0.0024f, 0.0001f), q2);
    }
  return world_of(gs);
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180 / M_PI;
}

TEST(EdgeNormal, AStylusOnAConvexEdgeGetsItsOwnNormalAndAGrooveKeepsTheShadedOne) {
  const double tilt = 30 * M_PI / 180;
  const Eigen::Vector3d axis(-std::cos(tilt), 0, std::sin(tilt)), n(std::sin(tilt), 0, std::cos(tilt));
  ToolEllipsoid part;
  part.semi_axes = {0.015, 0.005, 0.005};
  part.rotation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitX(), axis);
  part.center = n * 0.0052;
  const Eigen::Vector3d shaded = Eigen::Vector3d(1, 0, 1).normalized();  // the faces' blend
  // A block: top face (z = 0, x < 0), side face (x = 0, z < 0).
  const CollisionWorld block = two_faces({0, 0, 1}, {1, 0, 0}, {1, 0, 0}, {0, 0, 1});
  EdgeNormal edges(block);
  EdgeNormalCache cache;
  const EdgeNormalAnswer on_edge = edges.read(part, shaded, 0.005, 0.0, {}, cache);
  ASSERT_TRUE(on_edge.edge);
  EXPECT_LT(angle_deg(on_edge.normal, n), 3.0);
  EXPECT_NEAR(on_edge.normal.y(), 0.0, 1e-12);  // across the edge only
  // blend(): the shaded normal 15 deg away is replaced; one 2 deg away is kept.
  EXPECT_LT(angle_deg(EdgeNormal::blend(shaded, on_edge, n), on_edge.normal), 1e-9);
  const Eigen::Vector3d near = Eigen::AngleAxisd(2 * M_PI / 180, Eigen::Vector3d::UnitY()) * on_edge.normal;
  EXPECT_LT(angle_deg(EdgeNormal::blend(near, on_edge, n), near), 1e-9);
  // The cache answers while the part stays put, and re-reads once it moved.
  const EdgeNormalAnswer again = edges.read(part, shaded, 0.005, 0.001, {}, cache);
  EXPECT_EQ(again.normal, on_edge.normal);

  // A groove: floor (z = 0, x > 0) and wall (x = 0, z > 0); the stylus rests in it against both.
  const CollisionWorld groove = two_faces({0, 0, 1}, {-1, 0, 0}, {1, 0, 0}, {0, 0, -1});
  EdgeNormal grooves(groove);
  EdgeNormalCache gc;
  ToolEllipsoid in_groove = part;
  in_groove.rotation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY());
  in_groove.center = {0.0052, 0, 0.0052};
  EXPECT_FALSE(grooves.read(in_groove, shaded, 0.005, 0.0, {}, gc).edge);

  // A face: the stylus lying on the block's top face, far from the edge.
  ToolEllipsoid on_face = part;
  on_face.rotation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY());
  on_face.center = {-0.03, 0, 0.0052};
  EdgeNormalCache fc;
  EXPECT_FALSE(edges.read(on_face, Eigen::Vector3d::UnitZ(), 0.005, 0.0, {}, fc).edge);
}

TEST(EdgeNormal, AMessyPatchKeepsTheShadedNormal) {
  // Discs in random orientations around a plane (a real scene's reconstruction noise).
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<GaussianSpec> gs;
  for (float x = -0.04f; x <= 0.04f; x += 0.004f)
    for (float y = -0.04f; y <= 0.04f; y += 0.004f)
      gs.emplace_back(Eigen::Vector3f(x, y, 0.001f * u(rng)), Eigen::Vector3f(0.0024f, 0.0024f, 0.0001f),
                      Eigen::Quaternionf(u(rng), u(rng), u(rng), u(rng)).normalized());
  const CollisionWorld messy = world_of(gs);
  EdgeNormal edges(messy);
  EdgeNormalCache cache;
  ToolEllipsoid sphere = ToolEllipsoid::sphere({0, 0, 0.008}, 0.005);
  EXPECT_FALSE(edges.read(sphere, Eigen::Vector3d::UnitZ(), 0.005, 0.0, {}, cache).edge);
}

}  // namespace
}  // namespace gshaptics
