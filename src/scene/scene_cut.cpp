#include "gshaptics/scene/scene_cut.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics {
namespace {

std::vector<std::string_view> split(std::string_view text, char sep) {
  std::vector<std::string_view> out;
  for (std::size_t start = 0;;) {
    const std::size_t end = text.find(sep, start);
    out.push_back(text.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start));
    if (end == std::string_view::npos) return out;
    start = end + 1;
  }
}

InputError spec_error(const std::string& source, std::string_view text, const std::string& what) {
  return InputError(source + " '" + std::string(text) + "': " + what +
                    " (expected box:X0,Y0,Z0,X1,Y1,Z1, obox:CX,CY,CZ,HX,HY,HZ,QW,QX,QY,QZ, indices:I,J,... or "
                    "file:PATH[:registration=FILE.json], "
                    "then optional :mass=KG, :friction=MU and :hulls=N)");
}

double parse_number(std::string_view field, const std::string& source, std::string_view text) {
  double v = 0;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), v);
  if (ec != std::errc() || end != field.data() + field.size() || !std::isfinite(v))
    throw spec_error(source, text, "'" + std::string(field) + "' is not a number");
  return v;
}

void parse_box(std::string_view list, ObjectSpec& spec, const std::string& source, std::string_view text) {
  const auto fields = split(list, ',');
  if (fields.size() != 6) throw spec_error(source, text, "a box takes six numbers");
  for (int k = 0; k < 3; ++k) {
    const double a = parse_number(fields[k], source, text), b = parse_number(fields[3 + k], source, text);
    spec.box_lo[k] = std::min(a, b);
    spec.box_hi[k] = std::max(a, b);
    if (!(b > a || a > b)) throw spec_error(source, text, "the box is empty along axis " + std::to_string(k));
  }
}

// An oriented box: in the box's frame (box_rotation^-1 c) it is [R^-1 centre - half, R^-1
// centre + half]. Returns what is wrong (empty: nothing).
std::string set_oriented_box(ObjectSpec& spec, const Eigen::Vector3d& centre, const Eigen::Vector3d& half,
                             const Eigen::Quaterniond& q) {
  if (!(half.minCoeff() > 0)) return "the half extents must be > 0";
  if (!(q.norm() > 1e-9)) return "the rotation is a zero quaternion";
  spec.box_rotation = q.normalized();
  const Eigen::Vector3d c = spec.box_rotation.conjugate() * centre;
  spec.box_lo = c - half;
  spec.box_hi = c + half;
  return {};
}

// obox:CX,CY,CZ,HX,HY,HZ,QW,QX,QY,QZ
void parse_oriented_box(std::string_view list, ObjectSpec& spec, const std::string& source, std::string_view text) {
  const auto fields = split(list, ',');
  if (fields.size() != 10) throw spec_error(source, text, "an oriented box takes ten numbers (centre, half extents, w x y z)");
  double v[10];
  for (int k = 0; k < 10; ++k) v[k] = parse_number(fields[std::size_t(k)], source, text);
  const std::string wrong = set_oriented_box(spec, Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5]),
                                             Eigen::Quaterniond(v[6], v[7], v[8], v[9]));
  if (!wrong.empty()) throw spec_error(source, text, wrong);
}

void parse_indices(std::string_view list, ObjectSpec& spec, const std::string& source, std::string_view text) {
  for (std::string_view f : split(list, ',')) {
    std::uint32_t i = 0;
    const auto [end, ec] = std::from_chars(f.data(), f.data() + f.size(), i);
    if (ec != std::errc() || end != f.data() + f.size())
      throw spec_error(source, text, "'" + std::string(f) + "' is not a Gaussian index");
    spec.indices.push_back(i);
  }
  std::sort(spec.indices.begin(), spec.indices.end());
  spec.indices.erase(std::unique(spec.indices.begin(), spec.indices.end()), spec.indices.end());
}

void parse_property(std::string_view field, ObjectSpec& spec, const std::string& source, std::string_view text) {
  const std::size_t eq = field.find('=');
  const std::string_view key = field.substr(0, eq);
  if (eq == std::string_view::npos) throw spec_error(source, text, "'" + std::string(field) + "' is not KEY=VALUE");
  if (key == "registration") {
    if (spec.cut != ObjectSpec::Cut::kFile) throw spec_error(source, text, "registration= is for file objects");
    spec.registration_file = std::string(field.substr(eq + 1));
    if (spec.registration_file.empty()) throw spec_error(source, text, "registration= names no file");
    return;
  }
  const double v = parse_number(field.substr(eq + 1), source, text);
  if (key == "hulls") {
    if (!(v >= 1 && v <= kMaxObjectHulls && v == std::floor(v)))
      throw spec_error(source, text, "hulls must be a whole number from 1 to " + std::to_string(kMaxObjectHulls));
    spec.hulls = int(v);
  } else if (key == "mass") {
    if (!(v > 0)) throw spec_error(source, text, "mass must be > 0 kg");
    spec.mass = v;
  } else if (key == "friction") {
    if (!(v >= 0)) throw spec_error(source, text, "friction must be >= 0");
    spec.friction = v;
  } else {
    throw spec_error(source, text, "unknown property '" + std::string(key) + "' (mass, friction, hulls, registration)");
  }
}

bool claims(const ObjectSpec& spec, const Eigen::Vector3d& world_center, std::uint32_t source_index) {
  if (spec.cut == ObjectSpec::Cut::kFile) return false;  // its Gaussians come from its own file
  if (spec.cut == ObjectSpec::Cut::kIndices)
    return std::binary_search(spec.indices.begin(), spec.indices.end(), source_index);
  const Eigen::Vector3d c = spec.box_rotation.conjugate() * world_center;  // in the box's frame
  return (c.array() >= spec.box_lo.array()).all() && (c.array() <= spec.box_hi.array()).all();
}

// Appends Gaussian i of `scene` to `out`, moved into the world by `T` (mean, scale, rotation).
void push_registered(GaussianScene& out, const GaussianScene& scene, std::size_t i, const SimilarityTransform& T) {
  const Eigen::Quaterniond q = T.apply_rotation(scene.rotations[i]);
  out.push_back(T.apply(scene.means[i].cast<double>()).cast<float>(), (T.scale * scene.scales[i].cast<double>()).cast<float>(),
                Eigen::Vector4f(float(q.w()), float(q.x()), float(q.y()), float(q.z())), scene.opacities[i],
                scene.source_index[i]);
  // Band 0 of the colour does not turn with the Gaussian; the higher bands would (not kept).
  if (scene.colors_dc.size() == scene.size()) out.colors_dc.push_back(scene.colors_dc[i]);
}

std::string format_number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}

}  // namespace

ObjectSpec parse_object_spec(std::string_view text, const std::string& source) {
  ObjectSpec spec;
  spec.text = std::string(text);
  const auto parts = split(text, ':');
  if (parts.size() < 2) throw spec_error(source, text, "no cut given");
  if (parts[0] == "box") {
    spec.cut = ObjectSpec::Cut::kBox;
    parse_box(parts[1], spec, source, text);
  } else if (parts[0] == "obox") {
    spec.cut = ObjectSpec::Cut::kBox;
    parse_oriented_box(parts[1], spec, source, text);
  } else if (parts[0] == "indices") {
    spec.cut = ObjectSpec::Cut::kIndices;
    parse_indices(parts[1], spec, source, text);
  } else if (parts[0] == "file") {
    spec.cut = ObjectSpec::Cut::kFile;
    spec.file = std::string(parts[1]);
    if (spec.file.empty()) throw spec_error(source, text, "file: names no file");
  } else {
    throw spec_error(source, text, "unknown cut '" + std::string(parts[0]) + "'");
  }
  for (std::size_t k = 2; k < parts.size(); ++k) parse_property(parts[k], spec, source, text);
  return spec;
}

namespace {

// One entry of an objects JSON; `where` names it for messages ("FILE: objects[2]").
ObjectSpec spec_from_json(const nlohmann::json& e, const std::string& where, const std::string& base_dir) {
  if (!e.is_object()) throw InputError(where + ": not an object ({\"box\": ...}, {\"indices\": ...} or {\"file\": ...})");
  const int kinds = int(e.contains("box")) + int(e.contains("obox")) + int(e.contains("indices")) + int(e.contains("file"));
  if (kinds != 1) throw InputError(where + ": give exactly one of \"box\", \"obox\", \"indices\" and \"file\"");
  ObjectSpec spec;
  spec.text = e.dump();
  const auto number = [&where](const nlohmann::json& v, const std::string& field) {
    if (!v.is_number() || !std::isfinite(v.get<double>())) throw InputError(where + ": \"" + field + "\" is not a number");
    return v.get<double>();
  };
  const auto path = [&base_dir](const std::string& p) {
    return p.empty() || p[0] == '/' || base_dir.empty() ? p : base_dir + "/" + p;
  };
  if (e.contains("box")) {
    const nlohmann::json& b = e["box"];
    if (!b.is_array() || b.size() != 6) throw InputError(where + ": \"box\" takes six numbers [X0, Y0, Z0, X1, Y1, Z1]");
    for (int k = 0; k < 3; ++k) {
      const double a = number(b[std::size_t(k)], "box"), c = number(b[std::size_t(k + 3)], "box");
      if (!(a < c || c < a)) throw InputError(where + ": the box is empty along axis " + std::to_string(k));
      spec.box_lo[k] = std::min(a, c);
      spec.box_hi[k] = std::max(a, c);
    }
  } else if (e.contains("obox")) {  // {"center": [3], "half": [3], "rotation": [w, x, y, z]}
    const nlohmann::json& b = e["obox"];
    const auto values = [&](const char* key, std::size_t n) {
      if (!b.is_object() || !b.contains(key) || !b[key].is_array() || b[key].size() != n)
        throw InputError(where + ": \"obox\" takes {\"center\": [x, y, z], \"half\": [a, b, c], \"rotation\": [w, x, y, z]}");
      Eigen::Vector4d v = Eigen::Vector4d::Zero();
      for (std::size_t k = 0; k < n; ++k) v[Eigen::Index(k)] = number(b[key][k], "obox");
      return v;
    };
    const Eigen::Vector4d c = values("center", 3), h = values("half", 3), q = values("rotation", 4);
    const std::string wrong = set_oriented_box(spec, c.head<3>(), h.head<3>(), Eigen::Quaterniond(q[0], q[1], q[2], q[3]));
    if (!wrong.empty()) throw InputError(where + ": " + wrong);
  } else if (e.contains("indices")) {
    spec.cut = ObjectSpec::Cut::kIndices;
    const nlohmann::json& list = e["indices"];
    if (!list.is_array() || list.empty()) throw InputError(where + ": \"indices\" takes a list of Gaussian indices");
    for (const nlohmann::json& i : list) {
      if (!i.is_number_unsigned()) throw InputError(where + ": \"indices\" holds " + i.dump() + ", not an index");
      spec.indices.push_back(i.get<std::uint32_t>());
    }
    std::sort(spec.indices.begin(), spec.indices.end());
    spec.indices.erase(std::unique(spec.indices.begin(), spec.indices.end()), spec.indices.end());
  } else {
    spec.cut = ObjectSpec::Cut::kFile;
    if (!e["file"].is_string() || e["file"].get<std::string>().empty()) throw InputError(where + ": \"file\" names no file");
    spec.file = path(e["file"].get<std::string>());
    if (e.contains("registration")) {
      const nlohmann::json& r = e["registration"];
      if (r.is_string()) spec.registration_file = path(r.get<std::string>());
      else spec.registration = parse_registration_json(r.dump(), where + ": registration");
    }
  }
  if (spec.cut != ObjectSpec::Cut::kFile && e.contains("registration"))
    throw InputError(where + ": \"registration\" is for file objects");
  if (e.contains("mass")) spec.mass = number(e["mass"], "mass");
  if (e.contains("friction")) spec.friction = number(e["friction"], "friction");
  if (e.contains("hulls")) {
    const double h = number(e["hulls"], "hulls");
    if (!(h >= 1 && h <= kMaxObjectHulls && h == std::floor(h)))
      throw InputError(where + ": hulls must be a whole number from 1 to " + std::to_string(kMaxObjectHulls));
    spec.hulls = int(h);
  }
  if (!(spec.mass > 0)) throw InputError(where + ": mass must be > 0 kg");
  if (!(spec.friction >= 0)) throw InputError(where + ": friction must be >= 0");
  return spec;
}

}  // namespace

ObjectSpecList parse_object_specs_json(const std::string& text, const std::string& source, const std::string& base_dir) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded()) throw InputError(source + ": not valid JSON");
  if (!j.is_object() || !j.contains("objects") || !j["objects"].is_array())
    throw InputError(source + ": expected {\"objects\": [...]}");
  const nlohmann::json& list = j["objects"];
  if (list.size() > kMaxObjects)
    throw InputError(source + ": " + std::to_string(list.size()) + " objects, at most " + std::to_string(kMaxObjects));
  ObjectSpecList out;
  for (std::size_t i = 0; i < list.size(); ++i)
    out.objects.push_back(spec_from_json(list[i], source + ": objects[" + std::to_string(i) + "]", base_dir));
  if (j.contains("supports")) {
    if (!j["supports"].is_array()) throw InputError(source + ": \"supports\" is not a list");
    for (std::size_t i = 0; i < j["supports"].size(); ++i) {
      const std::string where = source + ": supports[" + std::to_string(i) + "]";
      ObjectSpec spec = spec_from_json(j["supports"][i], where, base_dir);
      if (spec.cut == ObjectSpec::Cut::kFile) throw InputError(where + ": a support is a part of the scene (box, obox or indices)");
      out.supports.push_back(std::move(spec));
    }
  }
  return out;
}

ObjectSpecList load_object_specs(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the objects file");
  std::ostringstream text;
  text << in.rdbuf();
  const std::string dir = std::filesystem::path(path).parent_path().string();
  return parse_object_specs_json(text.str(), path, dir);
}

SceneCut cut_objects(const GaussianScene& scene, const SimilarityTransform& scene_to_world,
                     std::span<const ObjectSpec> specs, float min_opacity) {
  if (specs.size() > kMaxObjects)
    throw InputError("--object: " + std::to_string(specs.size()) + " objects given, at most " +
                     std::to_string(kMaxObjects));
  SceneCut cut;
  cut.objects.resize(specs.size());
  for (GaussianScene& o : cut.objects) o.frame = scene.frame;
  std::vector<std::size_t> kept(specs.size(), 0);
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const Eigen::Vector3d c = scene_to_world.apply(scene.means[i].cast<double>());
    std::size_t owner = specs.size();
    for (std::size_t k = 0; k < specs.size() && owner == specs.size(); ++k)
      if (claims(specs[k], c, scene.source_index[i])) owner = k;
    if (owner == specs.size()) {
      cut.rest.push_back_from(scene, i);
      continue;
    }
    push_registered(cut.objects[owner], scene, i, scene_to_world);
    if (scene.opacities[i] > min_opacity) ++kept[owner];
  }
  cut.rest.frame = scene.frame;
  for (std::size_t k = 0; k < specs.size(); ++k)
    if (kept[k] == 0 && specs[k].cut != ObjectSpec::Cut::kFile)
      throw InputError("--object '" + specs[k].text + "': no Gaussian with opacity above " +
                       format_number(min_opacity) + " is in this object");
  return cut;
}

GaussianScene object_from_file(const ObjectSpec& spec, UpAxis up, float min_opacity) {
  LoadOptions lo;
  lo.keep_color = true;
  const LoadedScene loaded = load_scene(spec.file, lo);
  const SimilarityTransform reg = spec.registration ? *spec.registration
                                  : spec.registration_file.empty() ? SimilarityTransform{}
                                                                   : load_registration_file(spec.registration_file);
  const SimilarityTransform T = with_up_axis(reg, up, loaded.scene.frame);
  GaussianScene out;
  out.frame = loaded.scene.frame;
  std::size_t kept = 0;
  for (std::size_t i = 0; i < loaded.scene.size(); ++i) {
    push_registered(out, loaded.scene, i, T);
    if (loaded.scene.opacities[i] > min_opacity) ++kept;
  }
  if (kept == 0)
    throw InputError("--object '" + spec.text + "': no Gaussian of " + spec.file + " has opacity above " +
                     format_number(min_opacity));
  return out;
}

std::vector<GaussianScene> select_supports(const GaussianScene& scene, const SimilarityTransform& scene_to_world,
                                           std::span<const ObjectSpec> specs, float min_opacity) {
  std::vector<GaussianScene> out(specs.size());
  std::vector<std::size_t> kept(specs.size(), 0);
  for (const ObjectSpec& spec : specs)
    if (spec.cut == ObjectSpec::Cut::kFile)
      throw InputError("--support '" + spec.text + "': a support is a part of the scene (box, obox or indices)");
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const Eigen::Vector3d c = scene_to_world.apply(scene.means[i].cast<double>());
    for (std::size_t k = 0; k < specs.size(); ++k)
      if (claims(specs[k], c, scene.source_index[i])) {
        push_registered(out[k], scene, i, scene_to_world);
        if (scene.opacities[i] > min_opacity) ++kept[k];
      }
  }
  for (std::size_t k = 0; k < specs.size(); ++k)
    if (kept[k] == 0)
      throw InputError("--support '" + specs[k].text + "': no Gaussian with opacity above " + format_number(min_opacity) +
                       " is in it");
  return out;
}

void load_file_objects(SceneCut& cut, std::span<const ObjectSpec> specs, UpAxis up, float min_opacity) {
  for (std::size_t k = 0; k < specs.size() && k < cut.objects.size(); ++k)
    if (specs[k].cut == ObjectSpec::Cut::kFile) cut.objects[k] = object_from_file(specs[k], up, min_opacity);
}

GaussianScene box_surface_gaussians(const Eigen::Vector3d& center, const Eigen::Vector3d& half, double spacing,
                                    float opacity, std::uint32_t first_index) {
  GaussianScene s;
  std::uint32_t index = first_index;
  for (int axis = 0; axis < 3; ++axis)
    for (int side : {-1, 1}) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const int nu = std::max(1, int(std::round(2 * half[u] / spacing)));
      const int nv = std::max(1, int(std::round(2 * half[v] / spacing)));
      Eigen::Matrix3d R;  // the disc's thin axis (its z) along the face normal
      R.col(0) = Eigen::Vector3d::Unit(u);
      R.col(1) = Eigen::Vector3d::Unit(v);
      R.col(2) = Eigen::Vector3d::Unit(axis);
      if (R.determinant() < 0) R.col(1) = -R.col(1);
      const Eigen::Quaterniond q(R);
      const Eigen::Vector4f wxyz(float(q.w()), float(q.x()), float(q.y()), float(q.z()));
      const Eigen::Vector3f scale(float(1.4 * half[u] / nu), float(1.4 * half[v] / nv), float(0.05 * spacing));
      for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
          Eigen::Vector3d p = center;
          p[axis] += side * half[axis];
          p[u] += -half[u] + (i + 0.5) * 2 * half[u] / nu;
          p[v] += -half[v] + (j + 0.5) * 2 * half[v] / nv;
          s.push_back(p.cast<float>(), scale, wxyz, opacity, index++);
        }
    }
  return s;
}

BoxOnFloor box_on_floor(const Eigen::Vector3d& box_half, const Eigen::Vector2d& floor_half, double spacing) {
  if (!(box_half.minCoeff() > 0) || !(floor_half.minCoeff() > 0) || !(spacing > 0))
    throw InputError("box_on_floor: the sizes and the spacing must be > 0 m");
  GaussianScene box = box_surface_gaussians(Eigen::Vector3d(0, 0, box_half.z()), box_half, spacing);
  const double slab = spacing;
  const GaussianScene floor =
      box_surface_gaussians(Eigen::Vector3d(0, 0, -0.05 * spacing - slab), Eigen::Vector3d(floor_half.x(), floor_half.y(), slab),
                            spacing, 0.9f, std::uint32_t(box.size()));
  // Band-0 colour f_dc for a display colour c in [0, 1]: c = 0.5 + C0 f_dc (the 3DGS convention).
  const auto dc = [](const Eigen::Vector3f& c) -> Eigen::Vector3f { return (c.array() - 0.5f) / 0.28209479f; };
  BoxOnFloor out;
  out.scene = std::move(box);
  out.scene.colors_dc.assign(out.scene.size(), dc(Eigen::Vector3f(0.95f, 0.55f, 0.15f)));
  for (std::size_t i = 0; i < floor.size(); ++i) {
    out.scene.push_back_from(floor, i);
    out.scene.colors_dc.push_back(dc(Eigen::Vector3f(0.6f, 0.6f, 0.62f)));
  }
  // The cut: the box's disc centres lie on its faces, the floor's top ones spacing / 20 lower.
  const double m = 0.02 * spacing;
  char text[160];
  std::snprintf(text, sizeof text, "box:%.4g,%.4g,%.4g,%.4g,%.4g,%.4g", -box_half.x() - m, -box_half.y() - m, -m,
                box_half.x() + m, box_half.y() + m, 2 * box_half.z() + m);
  out.object_spec = text;
  return out;
}

}  // namespace gshaptics
