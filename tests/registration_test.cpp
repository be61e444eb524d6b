#include "gshaptics/scene/registration.h"

#include <gtest/gtest.h>

#include "gshaptics/error.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

std::string error_of(const std::string& json) {
  try {
    (void)parse_registration_json(json, "reg.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Registration, AllKeysOptional) {
  const SimilarityTransform t = parse_registration_json("{}", "x");
  EXPECT_TRUE(t.is_identity());
  EXPECT_EQ(t.apply(Eigen::Vector3d(1, 2, 3)), Eigen::Vector3d(1, 2, 3));
}

TEST(Registration, QuaternionIsNormalisedAndApplied) {
  // 90 deg about z, given unnormalised; scale 2; translation.
  const SimilarityTransform t = parse_registration_json(
      R"({"scale": 2, "rotation": [2, 0, 0, 2], "translation": [1, 0, 0]})", "x");
  EXPECT_NEAR((t.apply(Eigen::Vector3d(1, 0, 0)) - Eigen::Vector3d(1, 2, 0)).norm(), 0, 1e-12);
}

TEST(Registration, MatrixNestedOrFlat) {
  const char* nested = R"({"matrix": [[1,0,0],[0,0,-1],[0,1,0]]})";
  const char* flat = R"({"matrix": [1,0,0, 0,0,-1, 0,1,0]})";
  for (const char* j : {nested, flat}) {
    const SimilarityTransform t = parse_registration_json(j, "x");
    EXPECT_NEAR((t.apply(Eigen::Vector3d(0, 1, 0)) - Eigen::Vector3d(0, 0, 1)).norm(), 0, 1e-12) << j;
  }
}

TEST(Registration, BadInputNamesTheFieldAndSource) {
  EXPECT_NE(error_of("{").find("reg.json: not valid JSON"), std::string::npos);
  // A number beyond double: nlohmann throws out_of_range, not parse_error (found by fuzz/run.sh registration).
  EXPECT_NE(error_of(R"({"scale": 1e400})").find("reg.json: not valid JSON"), std::string::npos);
  EXPECT_NE(error_of(R"({"scale": -1})").find("'scale' must be > 0"), std::string::npos);
  EXPECT_NE(error_of(R"({"scale": "big"})").find("'scale' must be a number"), std::string::npos);
  EXPECT_NE(error_of(R"({"rotation": [0,0,0,0]})").find("zero norm"), std::string::npos);
  EXPECT_NE(error_of(R"({"rotation": [1,0,0]})").find("[w, x, y, z]"), std::string::npos);
  EXPECT_NE(error_of(R"({"matrix": [[2,0,0],[0,2,0],[0,0,2]]})").find("not orthonormal"), std::string::npos);
  EXPECT_NE(error_of(R"({"matrix": [[-1,0,0],[0,1,0],[0,0,1]]})").find("reflection"), std::string::npos);
  EXPECT_NE(error_of(R"({"rotation": [1,0,0,0], "matrix": [1,0,0,0,1,0,0,0,1]})").find("not both"), std::string::npos);
  EXPECT_NE(error_of(R"({"translaton": [1,2,3]})").find("unknown key 'translaton'"), std::string::npos);
}

TEST(Registration, BundledTruckRegistrationPutsGroundNearZero) {
  const SimilarityTransform t = load_registration_file(test::data_path("truck.registration.json"));
  EXPECT_DOUBLE_EQ(t.scale, 3.0);
  // Scene y points down: a point below the origin in scene (+y) is below in world (-z).
  const Eigen::Vector3d down = t.apply(Eigen::Vector3d(0, 1, 0)) - t.apply(Eigen::Vector3d::Zero());
  EXPECT_NEAR((down - Eigen::Vector3d(0, 0, -3)).norm(), 0, 1e-12);
}

TEST(Registration, JsonRoundTrip) {
  SimilarityTransform t;
  t.scale = 0.25;
  t.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  t.translation = {1e4, -2, 3.5};
  const SimilarityTransform u = parse_registration_json(t.to_json(), "x");
  EXPECT_DOUBLE_EQ(u.scale, t.scale);
  EXPECT_TRUE(u.rotation.isApprox(t.rotation, 1e-15));
  EXPECT_EQ(u.translation, t.translation);
}

}  // namespace
}  // namespace gshaptics
