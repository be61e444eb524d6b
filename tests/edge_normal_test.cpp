// The edge normal (edge_normal.h): a tool resting on a clean convex edge of flat discs gets the
// support normal across the edge; a face, a groove and a messy patch keep the shaded normal. At a
// clean convex corner (three faces), when asked for, the support normal whole; an inside corner
// and an edge with a row of bevelled discs along it are no corner.

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

TEST(EdgeNormal, AFlatFaceAnswersItsDiscsMeanAxisWhenAskedAndACurvedPatchIsNoFace) {
  // Level discs 4 mm apart whose centres alternate 0.3 mm above and below z = 0 (the height
  // scatter that tilts the density's gradient), a 5 mm sphere resting on them.
  std::vector<GaussianSpec> gs;
  int i = 0;
  for (float x = -0.04f; x <= 0.04f; x += 0.004f)
    for (float y = -0.04f; y <= 0.04f; y += 0.004f, ++i)
      gs.emplace_back(Eigen::Vector3f(x, y, i % 2 ? 0.0003f : -0.0003f), Eigen::Vector3f(0.0024f, 0.0024f, 0.0001f),
                      Eigen::Quaternionf::Identity());
  const CollisionWorld plate = world_of(gs);
  ToolEllipsoid ball;
  ball.semi_axes = Eigen::Vector3d::Constant(0.005);
  ball.center = {0.0011, 0.0007, 0.0054};
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d shaded = Eigen::AngleAxisd(2 * M_PI / 180, Eigen::Vector3d::UnitX()) * z;
  EdgeNormal faces(plate);
  EdgeNormalCache cache;
  const EdgeNormalAnswer face = faces.read(ball, shaded, 0.005, 0.0, {}, cache, ConvexFeatures::kEdgesAndFaces);
  ASSERT_TRUE(face.face);
  EXPECT_FALSE(face.feature());
  EXPECT_LT(angle_deg(face.normal, z), 1e-6);  // every disc's thin axis is z
  // Only when asked for: the edges alone leave a face unanswered.
  EdgeNormalCache plain;
  EXPECT_FALSE(faces.read(ball, shaded, 0.005, 0.0, {}, plain).face);
  // face_blend(): within 3 deg the mean of the two, past 6 deg the shaded normal alone.
  EXPECT_NEAR(angle_deg(EdgeNormal::face_blend(shaded, face, z), z), 1.0, 1e-3);
  const Eigen::Vector3d off = Eigen::AngleAxisd(8 * M_PI / 180, Eigen::Vector3d::UnitX()) * z;
  EXPECT_EQ(EdgeNormal::face_blend(off, face, z), off);
  EXPECT_EQ(EdgeNormal::blend(shaded, face, z), shaded);  // a face is no edge

  // The same discs tangent to a cylinder of 2 cm radius (axis y): the patch under the sphere
  // spans tens of degrees of normals, no face.
  std::vector<GaussianSpec> curved;
  for (float a = -1.0f; a <= 1.0f; a += 0.2f)
    for (float y = -0.04f; y <= 0.04f; y += 0.004f)
      curved.emplace_back(Eigen::Vector3f(0.02f * std::sin(a), y, 0.02f * std::cos(a) - 0.02f),
                          Eigen::Vector3f(0.0024f, 0.0024f, 0.0001f),
                          Eigen::Quaternionf(Eigen::AngleAxisf(a, Eigen::Vector3f::UnitY())));
  const CollisionWorld cylinder = world_of(curved);
  EdgeNormal round(cylinder);
  EdgeNormalCache rc;
  ToolEllipsoid on_top = ball;
  on_top.center = {0.0, 0.0007, 0.0051};
  EXPECT_FALSE(round.read(on_top, z, 0.005, 0.0, {}, rc, ConvexFeatures::kEdgesAndFaces).face);
  // And an edge stays an edge.
  const CollisionWorld block = two_faces({0, 0, 1}, {1, 0, 0}, {1, 0, 0}, {0, 0, 1});
  EdgeNormal edges(block);
  EdgeNormalCache ec;
  const double tilt = 30 * M_PI / 180;
  ToolEllipsoid part;
  part.semi_axes = {0.015, 0.005, 0.005};
  part.rotation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitX(),
                                                     Eigen::Vector3d(-std::cos(tilt), 0, std::sin(tilt)));
  part.center = Eigen::Vector3d(std::sin(tilt), 0, std::cos(tilt)) * 0.0052;
  const EdgeNormalAnswer e =
      edges.read(part, Eigen::Vector3d(1, 0, 1).normalized(), 0.005, 0.0, {}, ec, ConvexFeatures::kEdgesAndFaces);
  EXPECT_TRUE(e.edge);
  EXPECT_FALSE(e.face);
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

// Discs 4 mm apart, 2.4 mm wide, 0.1 mm thick, on the three faces of the octant corner at the
// origin, each tilted by up to 3 degrees (a fixed pseudo-random draw): the block x, y, z < 0
// (convex: outward normals +x, +y, +z) or, with `inside`, the walls of the octant x, y, z > 0
// seen from within it (concave: the same normals, the solid outside the octant). Plus, with
// `bevel_only`, only the two faces y = 0 and z = 0 and a row of discs along their edge (the x
// axis) tilted half way: an edge with three groups of discs.
CollisionWorld octant(bool inside, bool bevel_only = false) {
  std::vector<GaussianSpec> gs;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1);
  const float sg = inside ? 1.0f : -1.0f;
  const auto disc = [&](const Eigen::Vector3f& c, const Eigen::Vector3f& n) {
    const Eigen::Vector3f tilt_axis = Eigen::Vector3f(u(rng), u(rng), u(rng)).cross(n).normalized();
    const Eigen::Quaternionf q = Eigen::AngleAxisf(3.0f * float(M_PI) / 180 * u(rng), tilt_axis) *
                                 Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitZ(), n);
    gs.emplace_back(c, Eigen::Vector3f(0.0024f, 0.0024f, 0.0001f), q);
  };
  for (float a = 0.002f; a <= 0.04f; a += 0.004f)
    for (float b = 0.002f; b <= 0.04f; b += 0.004f) {
      if (!bevel_only) disc({0, sg * a, sg * b}, Eigen::Vector3f::UnitX());
      disc({sg * a, 0, sg * b}, Eigen::Vector3f::UnitY());
      disc({sg * a, sg * b, 0}, Eigen::Vector3f::UnitZ());
    }
  if (bevel_only)
    for (float a = -0.04f; a <= 0.04f; a += 0.004f) disc({a, 0, 0}, Eigen::Vector3f(0, 1, 1).normalized());
  return world_of(gs);
}

// The angle (degrees) from `d` to the positive octant's cone (0 inside it).
double angle_to_octant(const Eigen::Vector3d& d) {
  const Eigen::Vector3d in = d.cwiseMax(0.0);
  return in.norm() > 0 ? angle_deg(d, in) : 90.0 + angle_deg(-d, Eigen::Vector3d::Ones());
}

TEST(EdgeNormal, AToolResting2mmFromAConvexCornerGetsANormalInsideItsCone) {
  // A 5 mm sphere resting on the top face (z = 0) 2 and 3 mm from the corner's two other faces,
  // the shaded normal tilted 6 degrees out of the corner's cone (toward -x: a face's discs'
  // jitter, or a fin); the god-object's spring points up.
  const CollisionWorld block = octant(false);
  ToolEllipsoid sphere = ToolEllipsoid::sphere({-0.002, -0.003, 0.0052}, 0.005);
  const Eigen::Vector3d shaded(-std::sin(6 * M_PI / 180), 0, std::cos(6 * M_PI / 180));
  const Eigen::Vector3d spring(0, 0, 1);
  EdgeNormal corners(block);
  EdgeNormalCache cache;
  const EdgeNormalAnswer a = corners.read(sphere, shaded, 0.005, 0.0, {}, cache, ConvexFeatures::kCorners, spring);
  ASSERT_TRUE(a.corner);
  EXPECT_FALSE(a.edge);
  EXPECT_LT(angle_to_octant(a.normal), 0.5) << a.normal.transpose();
  EXPECT_GT(angle_to_octant(shaded), 5.9);
  // blend() hands the force to it (they disagree by more than 6 degrees).
  EXPECT_LT(angle_to_octant(EdgeNormal::blend(shaded, a, spring)), 0.5);
  // Edges only (the compound proxy's default): no answer here (three faces are no clean edge).
  EdgeNormalCache edge_cache;
  EXPECT_FALSE(corners.read(sphere, shaded, 0.005, 0.0, {}, edge_cache).feature());
  // With a shaded normal far out of the cone (a fin turning it 40 degrees), the spring still
  // vouches for the faces' orientation; without the spring the corner is not trusted.
  const Eigen::Vector3d fin(-std::sin(40 * M_PI / 180), 0, std::cos(40 * M_PI / 180));
  EdgeNormalCache c2, c3;
  EXPECT_TRUE(corners.read(sphere, fin, 0.005, 0.0, {}, c2, ConvexFeatures::kCorners, spring).corner);
  EXPECT_FALSE(corners.read(sphere, -fin.cwiseAbs(), 0.005, 0.0, {}, c3, ConvexFeatures::kCorners).corner);
}

TEST(EdgeNormal, AnInsideCornerAndABevelledEdgeAreNoCorner) {
  // A 5 mm sphere in the inside corner of three walls, touching all three.
  const CollisionWorld room = octant(true);
  EdgeNormal in_room(room);
  EdgeNormalCache cache;
  const Eigen::Vector3d diagonal = Eigen::Vector3d::Ones().normalized();
  const ToolEllipsoid in_corner = ToolEllipsoid::sphere({0.0052, 0.0052, 0.0052}, 0.005);
  EXPECT_FALSE(in_room.read(in_corner, diagonal, 0.005, 0.0, {}, cache, ConvexFeatures::kCorners, diagonal).feature());
  // ... and resting on one wall of it near the other two.
  EdgeNormalCache c2;
  const ToolEllipsoid on_wall = ToolEllipsoid::sphere({0.006, 0.007, 0.0052}, 0.005);
  EXPECT_FALSE(in_room.read(on_wall, Eigen::Vector3d::UnitZ(), 0.005, 0.0, {}, c2, ConvexFeatures::kCorners,
                            Eigen::Vector3d::UnitZ())
                   .feature());
  // A convex edge (faces y = 0 and z = 0 of the block y, z < 0) with a row of discs along it
  // tilted half way: three groups of discs, all across the edge. No corner.
  const CollisionWorld bevelled = octant(false, true);
  EdgeNormal on_bevel(bevelled);
  EdgeNormalCache c3;
  const Eigen::Vector3d bisector = Eigen::Vector3d(0, 1, 1).normalized();
  const ToolEllipsoid on_edge = ToolEllipsoid::sphere(bisector * 0.0052, 0.005);
  EXPECT_FALSE(on_bevel.read(on_edge, bisector, 0.005, 0.0, {}, c3, ConvexFeatures::kCorners, bisector).feature());
  // The same corner as a block (the convex one) is one: the test above is not vacuous here.
  const CollisionWorld block = octant(false);
  EdgeNormal on_block(block);
  EdgeNormalCache c4;
  const ToolEllipsoid at_tip = ToolEllipsoid::sphere(diagonal * 0.0052, 0.005);
  EXPECT_TRUE(on_block.read(at_tip, diagonal, 0.005, 0.0, {}, c4, ConvexFeatures::kCorners, diagonal).corner);
}

// The normal cones of a clean edge and corner (ConvexFeatures::kEdgeCones and kCorners, the
// proxy's crest hold) and crest_depth() against slow references: at the edge, the angles from a
// direction's part across the edge to the two faces' normals (inside the wedge they add up to
// its opening); at the corner, the angle to the nearest of 200 points along each of the cone's
// three boundary arcs, and inside iff the direction is a non-negative mix of the faces' normals.
TEST(EdgeNormal, AnEdgesAndACornersNormalConeHoldTheDirectionsBetweenTheirFaces) {
  const CollisionWorld block = two_faces({0, 0, 1}, {1, 0, 0}, {1, 0, 0}, {0, 0, 1});
  EdgeNormal edges(block);
  EdgeNormalCache cache;
  const Eigen::Vector3d bisector = Eigen::Vector3d(1, 0, 1).normalized();
  const ToolEllipsoid on_edge = ToolEllipsoid::sphere(bisector * 0.0052, 0.005);
  const EdgeNormalAnswer edge = edges.read(on_edge, bisector, 0.005, 0.0, {}, cache, ConvexFeatures::kEdgeCones);
  ASSERT_TRUE(edge.edge);
  ASSERT_EQ(edge.face_count, 2);
  EXPECT_LT(angle_deg(edge.edge_line.cwiseAbs(), Eigen::Vector3d::UnitY()), 1.0);
  const Eigen::Vector3d& a = edge.faces[0];
  const Eigen::Vector3d& b = edge.faces[1];
  EXPECT_LT(std::min(angle_deg(a, Eigen::Vector3d::UnitX()), angle_deg(a, Eigen::Vector3d::UnitZ())), 1.0);
  EXPECT_NEAR(angle_deg(a, b), 90.0, 1.0);
  // A tool beside the edge on one face only is no edge, so no cone.
  EdgeNormalCache face_cache;
  EXPECT_FALSE(edges.read(ToolEllipsoid::sphere({-0.03, 0, 0.0052}, 0.005), Eigen::Vector3d::UnitZ(), 0.005, 0.0, {},
                          face_cache, ConvexFeatures::kEdgeCones)
                   .feature());
  std::mt19937 rng(5);
  std::normal_distribution<double> g;
  const double opening = angle_deg(a, b);
  int inside = 0, outside = 0;
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector3d d(g(rng), g(rng), g(rng));
    const Eigen::Vector3d across = d - d.dot(edge.edge_line) * edge.edge_line;
    const double to_a = angle_deg(across, a), to_b = angle_deg(across, b);
    const bool in = to_a + to_b <= opening + 1e-9;
    const double depth = EdgeNormal::crest_depth(edge, d) * 180 / M_PI;
    if (in) {
      ++inside;
      EXPECT_NEAR(depth, std::min(to_a, to_b), 1e-6) << d.transpose();
    } else {
      ++outside;
      EXPECT_LT(depth, 0.0) << d.transpose();
    }
  }
  EXPECT_GT(inside, 20);
  EXPECT_GT(outside, 20);

  const CollisionWorld cube = octant(false);
  EdgeNormal corners(cube);
  EdgeNormalCache cc;
  const Eigen::Vector3d diagonal = Eigen::Vector3d::Ones().normalized();
  const EdgeNormalAnswer corner = corners.read(ToolEllipsoid::sphere(diagonal * 0.0052, 0.005), diagonal, 0.005, 0.0,
                                               {}, cc, ConvexFeatures::kEdgeConesAndCorners, diagonal);
  ASSERT_TRUE(corner.corner);
  ASSERT_EQ(corner.face_count, 3);
  Eigen::Matrix3d faces;
  for (int k = 0; k < 3; ++k) {
    faces.col(k) = corner.faces[k];
    EXPECT_GT(corner.faces[k].maxCoeff(), std::cos(2 * M_PI / 180));  // an axis, within its discs' tilts
  }
  inside = outside = 0;
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector3d d = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    const Eigen::Vector3d mix = faces.inverse() * d;
    const bool in = mix.minCoeff() >= 0;
    double nearest = 180;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& p = corner.faces[(k + 1) % 3];
      const Eigen::Vector3d& q = corner.faces[(k + 2) % 3];
      for (int j = 0; j <= 200; ++j) {
        const double t = j / 200.0;
        nearest = std::min(nearest, angle_deg(d, ((1 - t) * p + t * q).normalized()));
      }
    }
    const double depth = EdgeNormal::crest_depth(corner, d) * 180 / M_PI;
    if (in) {
      ++inside;
      EXPECT_NEAR(depth, nearest, 0.3) << d.transpose();
    } else {
      ++outside;
      EXPECT_LT(depth, 0.0) << d.transpose();
    }
  }
  EXPECT_GT(inside, 20);
  EXPECT_GT(outside, 200);
  // No feature, no cone.
  EXPECT_LT(EdgeNormal::crest_depth(EdgeNormalAnswer{}, diagonal), 0.0);
}

}  // namespace
}  // namespace gshaptics
