#include "gshaptics/scene/registration.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "gshaptics/error.h"
#include "gshaptics/io/mapped_file.h"
#include "gshaptics/scene/sh_rotation.h"

namespace gshaptics {

bool SimilarityTransform::is_identity() const {
  return scale == 1.0 && translation.isZero(0) && rotation.x() == 0 && rotation.y() == 0 &&
         rotation.z() == 0;
}

std::string SimilarityTransform::to_json() const {
  nlohmann::json j;
  j["scale"] = scale;
  j["rotation"] = {rotation.w(), rotation.x(), rotation.y(), rotation.z()};
  j["translation"] = {translation.x(), translation.y(), translation.z()};
  return j.dump(2);
}

namespace {

double number_at(const nlohmann::json& v, const std::string& source, const std::string& field) {
  if (!v.is_number()) throw InputError(source + ": field '" + field + "' must be a number");
  const double x = v.get<double>();
  if (!std::isfinite(x)) throw InputError(source + ": field '" + field + "' is not finite");
  return x;
}

}  // namespace

SimilarityTransform parse_registration_json(const std::string& text, const std::string& source) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // parse_error, or out_of_range for a number too large
    throw InputError(source + ": not valid JSON: " + e.what());
  }
  if (!j.is_object()) throw InputError(source + ": expected a JSON object");
  static const char* kKnown[] = {"scale", "rotation", "matrix", "translation", "comment"};
  for (const auto& [key, value] : j.items()) {
    bool known = false;
    for (const char* k : kKnown) known = known || key == k;
    if (!known)
      throw InputError(source + ": unknown key '" + key +
                       "' (expected scale, rotation, matrix, translation, comment)");
  }
  SimilarityTransform t;
  if (j.contains("scale")) {
    t.scale = number_at(j["scale"], source, "scale");
    if (!(t.scale > 0)) throw InputError(source + ": 'scale' must be > 0");
  }
  if (j.contains("rotation") && j.contains("matrix"))
    throw InputError(source + ": give either 'rotation' or 'matrix', not both");
  if (j.contains("rotation")) {
    const auto& r = j["rotation"];
    if (!r.is_array() || r.size() != 4)
      throw InputError(source + ": 'rotation' must be [w, x, y, z]");
    Eigen::Quaterniond q(number_at(r[0], source, "rotation[0]"), number_at(r[1], source, "rotation[1]"),
                         number_at(r[2], source, "rotation[2]"), number_at(r[3], source, "rotation[3]"));
    if (q.norm() < 1e-9) throw InputError(source + ": 'rotation' quaternion has zero norm");
    t.rotation = q.normalized();
  }
  if (j.contains("matrix")) {
    const auto& m = j["matrix"];
    std::vector<double> flat;
    if (m.is_array() && m.size() == 3 && m[0].is_array()) {
      for (std::size_t r = 0; r < 3; ++r) {
        if (!m[r].is_array() || m[r].size() != 3)
          throw InputError(source + ": 'matrix' must be 3x3 (row " + std::to_string(r) + ")");
        for (std::size_t c = 0; c < 3; ++c)
          flat.push_back(number_at(m[r][c], source, "matrix[" + std::to_string(r) + "][" + std::to_string(c) + "]"));
      }
    } else if (m.is_array() && m.size() == 9) {
      for (std::size_t i = 0; i < 9; ++i) flat.push_back(number_at(m[i], source, "matrix[" + std::to_string(i) + "]"));
    } else {
      throw InputError(source + ": 'matrix' must be 3x3 row-major (nested or 9 numbers)");
    }
    Eigen::Matrix3d R;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R(r, c) = flat[std::size_t(3 * r + c)];
    if ((R * R.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6)
      throw InputError(source + ": 'matrix' is not orthonormal (R R^T != I within 1e-6); "
                                "put uniform scale in 'scale'");
    if (R.determinant() < 0)
      throw InputError(source + ": 'matrix' has determinant -1 (a reflection), not a rotation");
    t.rotation = Eigen::Quaterniond(R).normalized();
  }
  if (j.contains("translation")) {
    const auto& v = j["translation"];
    if (!v.is_array() || v.size() != 3)
      throw InputError(source + ": 'translation' must be [x, y, z]");
    for (int k = 0; k < 3; ++k)
      t.translation[k] = number_at(v[std::size_t(k)], source, "translation[" + std::to_string(k) + "]");
  }
  return t;
}

GaussianScene transform_scene(const GaussianScene& scene, const SimilarityTransform& t) {
  GaussianScene out = scene;
  SimilarityTransform unit = t;
  unit.rotation.normalize();
  const int k = out.sh_rest_count / 3;
  const bool rotate_sh = out.sh_rest_count > 0 && out.sh_rest.size() == out.size() * std::size_t(out.sh_rest_count) &&
                         unit.rotation.angularDistance(Eigen::Quaterniond::Identity()) > 0;
  const ShRotation sh(unit.rotation);
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (rotate_sh) sh.apply(out.sh_rest.data() + i * std::size_t(out.sh_rest_count), k);
    out.means[i] = unit.apply(scene.means[i].cast<double>()).cast<float>();
    out.scales[i] = (unit.scale * scene.scales[i].cast<double>()).cast<float>();
    const Eigen::Quaterniond w = unit.apply_rotation(scene.rotations[i]);
    out.rotations[i] = Eigen::Vector4f(float(w.w()), float(w.x()), float(w.y()), float(w.z()));
  }
  return out;
}

UpAxis parse_up_axis(std::string_view text, const std::string& source) {
  static constexpr UpAxis kAll[] = {UpAxis::kNone, UpAxis::kAuto, UpAxis::kYDown, UpAxis::kYUp,
                                    UpAxis::kZUp,  UpAxis::kZDown, UpAxis::kXUp,  UpAxis::kXDown};
  for (UpAxis u : kAll)
    if (to_string(u) == text) return u;
  throw InputError(source + ": unknown up axis '" + std::string(text) +
                   "' (expected none, auto, y-down, y-up, z-up, z-down, x-up or x-down)");
}

std::string_view to_string(UpAxis up) {
  switch (up) {
    case UpAxis::kNone: return "none";
    case UpAxis::kAuto: return "auto";
    case UpAxis::kYDown: return "y-down";
    case UpAxis::kYUp: return "y-up";
    case UpAxis::kZUp: return "z-up";
    case UpAxis::kZDown: return "z-down";
    case UpAxis::kXUp: return "x-up";
    case UpAxis::kXDown: return "x-down";
  }
  return "none";
}

Eigen::Vector3d up_vector(UpAxis up, SceneFrame frame) {
  switch (up) {
    case UpAxis::kNone: return Eigen::Vector3d::Zero();
    case UpAxis::kAuto: return up_of(frame);
    case UpAxis::kYDown: return -Eigen::Vector3d::UnitY();
    case UpAxis::kYUp: return Eigen::Vector3d::UnitY();
    case UpAxis::kZUp: return Eigen::Vector3d::UnitZ();
    case UpAxis::kZDown: return -Eigen::Vector3d::UnitZ();
    case UpAxis::kXUp: return Eigen::Vector3d::UnitX();
    case UpAxis::kXDown: return -Eigen::Vector3d::UnitX();
  }
  return Eigen::Vector3d::Zero();
}

SimilarityTransform with_up_axis(const SimilarityTransform& registration, UpAxis up, SceneFrame frame) {
  SimilarityTransform t = registration;
  const Eigen::Vector3d u = up_vector(up, frame);
  if (u.squaredNorm() == 0) return t;
  const Eigen::Quaterniond r_up = Eigen::Quaterniond::FromTwoVectors(u, Eigen::Vector3d::UnitZ());
  t.rotation = (t.rotation * r_up).normalized();
  return t;
}

Eigen::Vector3d world_up(const SimilarityTransform& registration, UpAxis up, SceneFrame frame) {
  const Eigen::Vector3d scene_up = up == UpAxis::kNone ? up_of(frame) : up_vector(up, frame);
  const SimilarityTransform t = with_up_axis(registration, up, frame);
  return (t.rotation.normalized() * scene_up).normalized();
}

bool rotates_twice(const SimilarityTransform& registration, UpAxis up) {
  if (up == UpAxis::kNone) return false;
  return registration.rotation.normalized().angularDistance(Eigen::Quaterniond::Identity()) > 1e-6;
}

bool turns_upside_down(UpAxis up, SceneFrame frame) {
  if (up == UpAxis::kNone || up == UpAxis::kAuto) return false;
  return up_vector(up, frame).dot(up_of(frame)) < -0.5;
}

SimilarityTransform conversion_transform(const SimilarityTransform& registration, UpAxis up,
                                         SceneFrame from, SceneFrame to) {
  SimilarityTransform t = with_up_axis(registration, up, from);
  const Eigen::Vector3d u = world_up(registration, up, from);
  const Eigen::Quaterniond align = Eigen::Quaterniond::FromTwoVectors(u, Eigen::Vector3d::UnitZ());
  const Eigen::Quaterniond back = frame_to_z_up(to).conjugate();
  t.rotation = (back * align * t.rotation).normalized();
  t.translation = back * (align * t.translation);
  // Snap the rotation to exact axis permutations when it is one (within float noise), so that
  // converting between conventions moves no coordinate by a rounding error.
  Eigen::Matrix3d m = t.rotation.toRotationMatrix();
  if ((m.array().abs() - m.array().abs().round()).abs().maxCoeff() < 1e-9) {
    m = m.array().round().matrix();
    t.rotation = Eigen::Quaterniond(m).normalized();
  }
  return t;
}

SimilarityTransform load_registration_file(const std::string& path) {
  require_regular_file(path);
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open registration file");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_registration_json(ss.str(), path);
}

}  // namespace gshaptics
