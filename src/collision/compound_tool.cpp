#include "gshaptics/collision/compound_tool.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "gshaptics/error.h"

namespace gshaptics {

CompoundTool CompoundTool::single(const Eigen::Vector3d& semi_axes, const Eigen::Quaterniond& rotation) {
  CompoundTool t;
  t.count = 1;
  t.parts[0].semi_axes = semi_axes;
  t.parts[0].rotation = rotation;
  return t;
}

int CompoundTool::posed(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                        std::span<ToolEllipsoid> out) const noexcept {
  const int n = std::min<int>(count, int(out.size()));
  for (int i = 0; i < n; ++i) {
    const ToolPart& p = parts[std::size_t(i)];
    out[std::size_t(i)].center = position + orientation * p.offset;
    out[std::size_t(i)].rotation = orientation * p.rotation;
    out[std::size_t(i)].semi_axes = p.semi_axes;
  }
  return n;
}

double CompoundTool::reach() const noexcept {
  double r = 0;
  for (const ToolPart& p : view()) r = std::max(r, p.offset.norm() + p.semi_axes.maxCoeff());
  return r;
}

double CompoundTool::largest_semi_axis() const noexcept {
  double r = 0;
  for (const ToolPart& p : view()) r = std::max(r, p.semi_axes.maxCoeff());
  return r;
}

void CompoundTool::validate(const std::string& what) const {
  if (count < 1) throw InputError(what + ": a tool needs at least one part");
  if (count > kMaxToolParts)
    throw InputError(what + ": " + std::to_string(count) + " parts; at most " + std::to_string(kMaxToolParts));
  for (int i = 0; i < count; ++i) {
    const ToolPart& p = parts[std::size_t(i)];
    const std::string at = what + ": part " + std::to_string(i);
    if (!p.offset.allFinite() || !p.semi_axes.allFinite() || !p.rotation.coeffs().allFinite())
      throw InputError(at + " is not finite");
    if (!(p.semi_axes.minCoeff() > 0)) throw InputError(at + ": semi-axes must be > 0 m");
    if (!(p.rotation.norm() > 1e-9)) throw InputError(at + ": rotation quaternion is zero");
  }
}

namespace {

std::vector<double> numbers(std::string_view spec, std::string_view args, std::size_t want) {
  std::vector<double> v;
  std::size_t start = 0;
  while (start <= args.size()) {
    const std::size_t comma = std::min(args.find(',', start), args.size());
    const std::string field(args.substr(start, comma - start));
    char* end = nullptr;
    const double x = std::strtod(field.c_str(), &end);
    if (field.empty() || end != field.c_str() + field.size() || !std::isfinite(x) || !(x > 0))
      throw InputError("--tool " + std::string(spec) + ": '" + field + "' is not a positive number (metres)");
    v.push_back(x);
    start = comma + 1;
  }
  if (v.size() != want)
    throw InputError("--tool " + std::string(spec) + ": expected " + std::to_string(want) + " numbers, got " +
                     std::to_string(v.size()));
  return v;
}

Eigen::Vector3d vec3(const nlohmann::json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 3) throw InputError(what + " must be an array of 3 numbers");
  Eigen::Vector3d v;
  for (int k = 0; k < 3; ++k) {
    if (!j[std::size_t(k)].is_number()) throw InputError(what + " must be an array of 3 numbers");
    v[k] = j[std::size_t(k)].get<double>();
  }
  return v;
}

CompoundTool from_json_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw file_error(path, "cannot open the tool file");
  std::stringstream ss;
  ss << in.rdbuf();
  const nlohmann::json j = nlohmann::json::parse(ss.str(), nullptr, false);
  if (j.is_discarded()) throw file_error(path, "not valid JSON");
  if (!j.is_object() || !j.contains("parts") || !j["parts"].is_array())
    throw file_error(path, "expected an object with an array \"parts\"");
  const auto& parts = j["parts"];
  if (parts.empty()) throw file_error(path, "\"parts\" is empty");
  if (parts.size() > std::size_t(kMaxToolParts))
    throw file_error(path, std::to_string(parts.size()) + " parts; at most " + std::to_string(kMaxToolParts));
  CompoundTool t;
  t.count = int(parts.size());
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const auto& p = parts[i];
    const std::string at = path + ": parts[" + std::to_string(i) + "]";
    if (!p.is_object()) throw InputError(at + " must be an object");
    if (!p.contains("semi_axes")) throw InputError(at + " has no \"semi_axes\"");
    ToolPart& out = t.parts[i];
    out.semi_axes = vec3(p["semi_axes"], at + ".semi_axes");
    if (p.contains("center")) out.offset = vec3(p["center"], at + ".center");
    if (p.contains("rotation")) {
      const auto& q = p["rotation"];
      if (!q.is_array() || q.size() != 4 || !std::all_of(q.begin(), q.end(), [](const auto& x) { return x.is_number(); }))
        throw InputError(at + ".rotation must be a quaternion [w, x, y, z]");
      out.rotation = Eigen::Quaterniond(q[0].get<double>(), q[1].get<double>(), q[2].get<double>(), q[3].get<double>());
      if (!(out.rotation.norm() > 1e-9) || !out.rotation.coeffs().allFinite())
        throw InputError(at + ".rotation is zero or not finite");
      out.rotation.normalize();
    }
  }
  t.validate(path);
  return t;
}

}  // namespace

CompoundTool parse_tool_spec(std::string_view spec) {
  if (spec.size() > 5 && spec.substr(spec.size() - 5) == ".json") return from_json_file(std::string(spec));
  const std::size_t colon = spec.find(':');
  if (colon == std::string_view::npos)
    throw InputError("--tool " + std::string(spec) +
                     ": expected sphere:R, ellipsoid:A,B,C, stylus:LENGTH,RADIUS, disc:RADIUS,THICKNESS or FILE.json");
  const std::string_view kind = spec.substr(0, colon), args = spec.substr(colon + 1);
  CompoundTool t;
  if (kind == "sphere") {
    const auto v = numbers(spec, args, 1);
    t = CompoundTool::single(Eigen::Vector3d::Constant(v[0]));
  } else if (kind == "ellipsoid") {
    const auto v = numbers(spec, args, 3);
    t = CompoundTool::single(Eigen::Vector3d(v[0], v[1], v[2]));
  } else if (kind == "stylus") {
    const auto v = numbers(spec, args, 2);
    const double length = v[0], radius = v[1];
    if (!(length > 2 * radius))
      throw InputError("--tool " + std::string(spec) + ": a stylus must be longer than its diameter");
    t.count = 4;
    for (int i = 0; i < 4; ++i) {
      t.parts[std::size_t(i)].offset = Eigen::Vector3d(0, 0, length / 6.0 + i * 2.0 * length / 9.0);
      t.parts[std::size_t(i)].semi_axes = Eigen::Vector3d(radius, radius, length / 6.0);
    }
  } else if (kind == "disc") {
    const auto v = numbers(spec, args, 2);
    t = CompoundTool::single(Eigen::Vector3d(v[0], v[0], v[1] / 2));
  } else {
    throw InputError("--tool " + std::string(spec) + ": unknown tool '" + std::string(kind) +
                     "' (sphere, ellipsoid, stylus, disc, or a .json file)");
  }
  t.validate("--tool " + std::string(spec));
  return t;
}

std::string describe(const CompoundTool& tool) {
  std::ostringstream s;
  s << tool.count << (tool.count == 1 ? " part" : " parts") << ", reach " << tool.reach() << " m";
  return s.str();
}

}  // namespace gshaptics
