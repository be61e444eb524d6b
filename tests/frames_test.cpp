// The frame model: the world's up from the actual transform, conversion between file
// conventions, SH rotation with the scene, the info advice and the device profiles.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "gshaptics/error.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/scene/scene_stats.h"
#include "gshaptics/scene/sh_rotation.h"
#include "gshaptics/device/device_profile.h"

namespace gshaptics {
namespace {

constexpr double kEps = 1e-12;

TEST(WorldUp, FileConventionWithoutAnyTransform) {
  const SimilarityTransform none;
  EXPECT_TRUE(world_up(none, UpAxis::kNone, SceneFrame::kRdf).isApprox(Eigen::Vector3d(0, -1, 0), kEps));
  EXPECT_TRUE(world_up(none, UpAxis::kNone, SceneFrame::kRub).isApprox(Eigen::Vector3d(0, 1, 0), kEps));
}

TEST(WorldUp, ScaleAndTranslationRotateNothing) {
  SimilarityTransform t;
  t.scale = 0.25;
  t.translation = Eigen::Vector3d(1, 2, 3);
  EXPECT_TRUE(world_up(t, UpAxis::kNone, SceneFrame::kRdf).isApprox(Eigen::Vector3d(0, -1, 0), kEps));
}

TEST(WorldUp, UpAxisAloneAndARotatingRegistrationBothGivePlusZ) {
  const SimilarityTransform none;
  for (UpAxis u : {UpAxis::kAuto, UpAxis::kYUp, UpAxis::kZDown, UpAxis::kXUp})
    EXPECT_TRUE(world_up(none, u, SceneFrame::kRdf).isApprox(Eigen::Vector3d::UnitZ(), 1e-9)) << to_string(u);
  SimilarityTransform truck;  // -90 deg about x, like data/truck.registration.json
  truck.rotation = Eigen::Quaterniond(std::sqrt(0.5), -std::sqrt(0.5), 0, 0);
  EXPECT_TRUE(world_up(truck, UpAxis::kNone, SceneFrame::kRdf).isApprox(Eigen::Vector3d::UnitZ(), 1e-9));
  EXPECT_FALSE(rotates_twice(truck, UpAxis::kNone));
  EXPECT_TRUE(rotates_twice(truck, UpAxis::kAuto));
  // Both applied: the scene turns twice and its up ends horizontal, not at +z.
  EXPECT_LT(std::abs(world_up(truck, UpAxis::kAuto, SceneFrame::kRdf).z()), 1e-9);
  SimilarityTransform scaled;
  scaled.scale = 2;
  EXPECT_FALSE(rotates_twice(scaled, UpAxis::kAuto));
}

TEST(WorldUp, AnAxisAgainstTheFilesOwnUpStandsTheSceneOnItsHead) {
  // PLY/.splat (RDF): y down is the file's down, so y-up is upside down; SPZ (RUB) the other way.
  EXPECT_TRUE(turns_upside_down(UpAxis::kYUp, SceneFrame::kRdf));
  EXPECT_FALSE(turns_upside_down(UpAxis::kYDown, SceneFrame::kRdf));
  EXPECT_TRUE(turns_upside_down(UpAxis::kYDown, SceneFrame::kRub));
  EXPECT_FALSE(turns_upside_down(UpAxis::kYUp, SceneFrame::kRub));
  // On its side is not on its head; none and auto take the file's own up.
  for (UpAxis u : {UpAxis::kNone, UpAxis::kAuto, UpAxis::kZUp, UpAxis::kZDown, UpAxis::kXUp, UpAxis::kXDown})
    EXPECT_FALSE(turns_upside_down(u, SceneFrame::kRdf)) << to_string(u);
}

TEST(ConversionTransform, RubToRdfIsTheHalfTurnAboutX) {
  const SimilarityTransform t = conversion_transform({}, UpAxis::kNone, SceneFrame::kRub, SceneFrame::kRdf);
  const Eigen::Matrix3d expect = Eigen::Vector3d(1, -1, -1).asDiagonal();
  EXPECT_EQ(t.rotation.toRotationMatrix(), expect);  // exact: snapped to the axis permutation
  EXPECT_EQ(t.scale, 1.0);
  EXPECT_TRUE(t.translation.isZero(0));
  // The same convention: nothing moves.
  EXPECT_TRUE(conversion_transform({}, UpAxis::kNone, SceneFrame::kRdf, SceneFrame::kRdf).is_identity());
  EXPECT_TRUE(conversion_transform({}, UpAxis::kAuto, SceneFrame::kRdf, SceneFrame::kRdf).is_identity());
}

TEST(ConversionTransform, ReadBackUnderUpAutoGivesTheSourceWorld) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n;
  for (int trial = 0; trial < 50; ++trial) {
    SimilarityTransform reg;
    reg.scale = 0.5 + std::abs(n(rng));
    reg.translation = Eigen::Vector3d(n(rng), n(rng), n(rng));
    // A registration that only spins about the world's up (keeps the world upright).
    reg.rotation = Eigen::AngleAxisd(n(rng), Eigen::Vector3d::UnitZ());
    const SceneFrame from = trial % 2 ? SceneFrame::kRub : SceneFrame::kRdf;
    const UpAxis up = UpAxis::kAuto;
    const SimilarityTransform src = with_up_axis(reg, up, from);
    const SimilarityTransform conv = conversion_transform(reg, up, from, SceneFrame::kRdf);
    const SimilarityTransform read = with_up_axis({}, UpAxis::kAuto, SceneFrame::kRdf);
    const Eigen::Vector3d p(n(rng), n(rng), n(rng));
    EXPECT_TRUE(read.apply(conv.apply(p)).isApprox(src.apply(p), 1e-9)) << trial;
  }
}

// Colour of one channel along direction d from band 1-3 coefficients c (15 values).
double sh_colour(const float* c, const Eigen::Vector3d& d) {
  const auto y = sh_basis_bands_1_to_3(d);
  double s = 0;
  for (int k = 0; k < 15; ++k) s += double(c[k]) * y[std::size_t(k)];
  return s;
}

TEST(ShRotation, ColourSeenAlongTheTurnedDirectionIsUnchanged) {
  std::mt19937 rng(11);
  std::normal_distribution<double> n;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Quaterniond q = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
    float rest[45], turned[45];
    for (float& v : rest) v = float(n(rng));
    std::copy(rest, rest + 45, turned);
    ASSERT_TRUE(ShRotation(q).apply(turned, 15));
    for (int j = 0; j < 10; ++j) {
      const Eigen::Vector3d d = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_NEAR(sh_colour(turned + 15 * ch, q * d), sh_colour(rest + 15 * ch, d), 2e-5);
    }
  }
}

TEST(ShRotation, HalfTurnAboutXFlipsTheOddInYZTerms) {
  // (x, y, z) -> (x, -y, -z): a basis function changes sign when its polynomial has an odd
  // total degree in y and z together.
  const ShRotation r(Eigen::Quaterniond(0, 1, 0, 0));
  const double band1[3] = {-1, -1, 1};           // y, z, x
  const double band2[5] = {-1, 1, 1, -1, 1};     // xy, yz, zz, xz, xx-yy
  const double band3[7] = {-1, 1, -1, -1, 1, -1, 1};
  EXPECT_TRUE(r.band1().isApprox(Eigen::Matrix3d(Eigen::Vector3d(band1[0], band1[1], band1[2]).asDiagonal()), 1e-9));
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(r.band2()(k, k), band2[k], 1e-9);
  for (int k = 0; k < 7; ++k) EXPECT_NEAR(r.band3()(k, k), band3[k], 1e-9);
  EXPECT_NEAR(r.band3().cwiseAbs().sum(), 7.0, 1e-9);  // nothing off the diagonal
}

TEST(ShRotation, LowerDegreesAndUnknownCounts) {
  const ShRotation r(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())));
  float rest[9] = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  ASSERT_TRUE(r.apply(rest, 3));  // band 1 only: each channel's norm is kept (orthogonal basis)
  EXPECT_NEAR(Eigen::Vector3f(rest[0], rest[1], rest[2]).norm(), Eigen::Vector3f(1, 2, 3).norm(), 1e-5);
  float odd[12] = {};
  EXPECT_FALSE(r.apply(odd, 4));
}

TEST(TransformScene, RotatesTheShWithTheScene) {
  GaussianScene s;
  s.push_back(Eigen::Vector3f(1, 2, 3), Eigen::Vector3f(0.1f, 0.1f, 0.1f), Eigen::Vector4f(1, 0, 0, 0), 0.9f, 0);
  s.colors_dc.emplace_back(0.1f, 0.2f, 0.3f);
  s.sh_rest_count = 9;
  s.sh_rest = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  SimilarityTransform t;
  t.rotation = Eigen::Quaterniond(0, 1, 0, 0);
  const GaussianScene out = transform_scene(s, t);
  EXPECT_FLOAT_EQ(out.sh_rest[0], -1.f);  // y-term of red flips
  EXPECT_FLOAT_EQ(out.sh_rest[4], -1.f);  // z-term of green flips
  EXPECT_FLOAT_EQ(out.sh_rest[8], 1.f);   // x-term of blue stays
  EXPECT_TRUE(out.means[0].isApprox(Eigen::Vector3f(1, -2, -3)));
}

TEST(ScaleAdvice, DesktopFitsAndRoomGuessesTheUnit) {
  EXPECT_NEAR(desktop_scale_advice(2.4).reg_scale * 2.4, 0.12, 1e-12);
  EXPECT_EQ(room_scale_advice(2.4).reg_scale, 1.0);
  EXPECT_NEAR(room_scale_advice(343).reg_scale, 0.01, 1e-15);
  EXPECT_NE(room_scale_advice(343).reason.find("centimetres"), std::string::npos);
  EXPECT_NEAR(room_scale_advice(1500).reg_scale, 0.001, 1e-15);
  EXPECT_NEAR(room_scale_advice(0.01).reg_scale, 100, 1e-9);
  EXPECT_NEAR(room_scale_advice(343).tool_radius, 0.0343, 1e-9);
}

TEST(WorldPreview, BoundsAfterTheTransformAndTheFilter) {
  GaussianScene s;
  for (int i = 0; i <= 100; ++i)
    s.push_back(Eigen::Vector3f(float(i), 0, 0), Eigen::Vector3f::Constant(0.1f), Eigen::Vector4f(1, 0, 0, 0),
                i % 2 ? 0.9f : 0.05f, std::uint32_t(i));
  SimilarityTransform t;
  t.scale = 0.01;
  t.rotation = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
  const WorldPreview w = preview_world(s, 0.2f, t, Eigen::Vector3d::UnitZ());
  EXPECT_EQ(w.kept, 50u);
  EXPECT_NEAR(w.bbox_min.y(), 0.01, 1e-6);  // x turned to y, scaled, odd i only
  EXPECT_NEAR(w.bbox_max.y(), 0.99, 1e-6);
  EXPECT_NEAR(w.bbox_max.x(), 0.0, 1e-6);
  EXPECT_GT(w.robust_size, 0.9);
}

TEST(DeviceProfile, KnownProfilesAndErrors) {
  const DeviceProfile& d = device_profile("desktop", "--device-profile");
  EXPECT_EQ(d.f_max, 3.3);
  EXPECT_TRUE(fits_workspace(d, 0.12));
  EXPECT_FALSE(fits_workspace(d, 0.5));
  const DeviceProfile& r = device_profile("room", "--device-profile");
  EXPECT_EQ(r.f_max, ForceParams{}.f_max);
  EXPECT_TRUE(fits_workspace(r, 1e6));
  try {
    (void)device_profile("glove", "--device-profile");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("desktop, room"), std::string::npos);
  }
}

}  // namespace
}  // namespace gshaptics
