#include "gshaptics/force/material.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "gshaptics/error.h"
#include "gshaptics/force/friction_cone.h"
#include "gshaptics/force/virtual_coupling.h"

namespace gshaptics {

namespace {

constexpr std::size_t kMaxMaterials = MaterialField::kMaxIds - 1;  // ids 1..254 in a byte; 0 is the proxy's own
constexpr int kMaxClusters = 64;         // a colour selector's k-means clusters, at most
constexpr int kClusterIterations = 50;   // Lloyd's iterations, at most


using nlohmann::json;

InputError map_error(const std::string& source, const std::string& what) { return file_error(source, what); }

void check_keys(const json& j, const std::set<std::string>& known, const std::string& source, const std::string& at) {
  for (auto it = j.begin(); it != j.end(); ++it)
    if (!known.count(it.key())) throw map_error(source, at + ": unknown key \"" + it.key() + "\"");
}

double number(const json& j, const std::string& key, const std::string& source, const std::string& at, double lo,
              bool lo_open = false) {
  const json& v = j.at(key);
  if (!v.is_number()) throw map_error(source, at + ": \"" + key + "\" must be a number");
  const double x = v.get<double>();
  if (!std::isfinite(x) || x < lo || (lo_open && x == lo))
    throw map_error(source, at + ": \"" + key + "\" must be " + (lo_open ? "> " : ">= ") + std::to_string(int(lo)));
  return x;
}

Eigen::Vector3d vec3(const json& j, const std::string& source, const std::string& at) {
  if (!j.is_array() || j.size() != 3) throw map_error(source, at + " must be an array of 3 numbers");
  Eigen::Vector3d v;
  for (int k = 0; k < 3; ++k) {
    if (!j[std::size_t(k)].is_number()) throw map_error(source, at + " must be an array of 3 numbers");
    v[k] = j[std::size_t(k)].get<double>();
  }
  if (!v.allFinite()) throw map_error(source, at + " must be finite");
  return v;
}

// {"grating": {"wavelength", "amplitude", "direction"}} or {"noise": {"amplitude", "wavelength_min",
// "wavelength_max", "seed"}}.
ProceduralTexture parse_texture(const json& j, const std::string& source, const std::string& at) {
  if (!j.is_object() || j.size() != 1 || !(j.contains("grating") || j.contains("noise")))
    throw map_error(source, at + " must be {\"grating\": {...}} or {\"noise\": {...}}");
  ProceduralTexture t;
  if (j.contains("grating")) {
    const json& g = j["grating"];
    const std::string here = at + ".grating";
    if (!g.is_object() || !g.contains("wavelength") || !g.contains("amplitude"))
      throw map_error(source, here + " needs \"wavelength\" and \"amplitude\" (m)");
    check_keys(g, {"wavelength", "amplitude", "direction"}, source, here);
    t.kind = ProceduralTexture::Kind::kGrating;
    t.wavelength = number(g, "wavelength", source, here, 0, true);
    t.amplitude = number(g, "amplitude", source, here, 0);
    if (g.contains("direction")) t.direction = vec3(g["direction"], source, here + ".direction");
    if (!(t.direction.norm() > 0)) throw map_error(source, here + ".direction must not be zero");
    t.direction.normalize();
  } else {
    const json& n = j["noise"];
    const std::string here = at + ".noise";
    if (!n.is_object() || !n.contains("amplitude") || !n.contains("wavelength_min") || !n.contains("wavelength_max"))
      throw map_error(source, here + " needs \"amplitude\", \"wavelength_min\" and \"wavelength_max\" (m)");
    check_keys(n, {"amplitude", "wavelength_min", "wavelength_max", "seed"}, source, here);
    t.kind = ProceduralTexture::Kind::kNoise;
    t.amplitude = number(n, "amplitude", source, here, 0);
    t.wavelength = number(n, "wavelength_min", source, here, 0, true);
    t.wavelength_max = number(n, "wavelength_max", source, here, 0, true);
    if (t.wavelength_max < t.wavelength) throw map_error(source, here + ": wavelength_max is below wavelength_min");
    if (n.contains("seed")) t.seed = std::uint64_t(number(n, "seed", source, here, 0));
  }
  t.prepare();
  return t;
}

Material parse_material(const json& j, const std::string& source, const std::string& at) {
  if (!j.is_object()) throw map_error(source, at + " must be an object");
  check_keys(j, {"name", "stiffness", "damping", "mu_s", "mu_k", "viscosity", "texture_gain", "vibration", "texture"}, source,
             at);
  Material m;
  if (!j.contains("name") || !j["name"].is_string() || j["name"].get<std::string>().empty())
    throw map_error(source, at + ": needs a \"name\"");
  m.name = j["name"].get<std::string>();
  for (char c : m.name)
    if (c == '"' || c == '\\' || static_cast<unsigned char>(c) < 0x20)
      throw map_error(source, at + ": the name may not hold quotes, backslashes or control characters");
  if (j.contains("stiffness")) m.stiffness = number(j, "stiffness", source, at, 0, true);
  if (j.contains("damping")) m.damping = number(j, "damping", source, at, 0);
  if (j.contains("mu_s")) m.mu_s = number(j, "mu_s", source, at, 0);
  if (j.contains("mu_k")) m.mu_k = number(j, "mu_k", source, at, 0);
  if (j.contains("viscosity")) m.viscosity = number(j, "viscosity", source, at, 0);
  if (j.contains("texture_gain")) m.texture_gain = number(j, "texture_gain", source, at, 0);
  if (j.contains("vibration")) {
    m.vibration = number(j, "vibration", source, at, 0);
    if (m.vibration > 1) throw map_error(source, at + ": \"vibration\" is a level in [0, 1]");
  }
  if (j.contains("texture")) m.texture = parse_texture(j["texture"], source, at + ".texture");
  return m;
}

ColourSelector parse_colour(const json& j, const std::string& source, const std::string& at);

MaterialRegion parse_region(const json& j, const std::map<std::string, std::size_t>& ids, const std::string& source,
                            const std::string& at) {
  if (!j.is_object()) throw map_error(source, at + " must be an object");
  check_keys(j, {"material", "box", "sphere", "indices", "colour", "color"}, source, at);
  if (!j.contains("material") || !j["material"].is_string()) throw map_error(source, at + ": needs a \"material\" name");
  const auto id = ids.find(j["material"].get<std::string>());
  if (id == ids.end()) throw map_error(source, at + ": no material named \"" + j["material"].get<std::string>() + "\"");
  MaterialRegion r;
  r.material = id->second;
  if (j.contains("colour") && j.contains("color")) throw map_error(source, at + ": \"colour\" and \"color\" both given");
  if (j.contains("colour") || j.contains("color")) r.colour = parse_colour(j.contains("colour") ? j["colour"] : j["color"], source, at + ".colour");
  const int shapes = int(j.contains("box")) + int(j.contains("sphere")) + int(j.contains("indices"));
  if (shapes > 1 || (shapes == 0 && !r.colour) || (r.colour && j.contains("indices")))
    throw map_error(source, at + ": needs exactly one of \"box\", \"sphere\", \"indices\", \"colour\" (a colour may come "
                                 "with a box or a sphere)");
  if (shapes == 0) {
    r.kind = MaterialRegion::Kind::kColour;
  } else if (j.contains("box")) {
    const json& b = j["box"];
    if (!b.is_object() || !b.contains("min") || !b.contains("max"))
      throw map_error(source, at + ".box needs \"min\" and \"max\"");
    r.kind = MaterialRegion::Kind::kBox;
    r.lo = vec3(b["min"], source, at + ".box.min");
    r.hi = vec3(b["max"], source, at + ".box.max");
    if (!(r.lo.array() < r.hi.array()).all()) throw map_error(source, at + ".box: min must be below max on every axis");
  } else if (j.contains("sphere")) {
    const json& s = j["sphere"];
    if (!s.is_object() || !s.contains("center") || !s.contains("radius"))
      throw map_error(source, at + ".sphere needs \"center\" and \"radius\"");
    r.kind = MaterialRegion::Kind::kSphere;
    r.center = vec3(s["center"], source, at + ".sphere.center");
    r.radius = number(s, "radius", source, at + ".sphere", 0, true);
  } else {
    const json& ix = j["indices"];
    if (!ix.is_array()) throw map_error(source, at + ".indices must be an array of Gaussian indices");
    r.kind = MaterialRegion::Kind::kIndices;
    for (const json& i : ix) {
      if (!i.is_number_unsigned() || i.get<std::uint64_t>() > 0xffffffffull)
        throw map_error(source, at + ".indices must hold non-negative integers below 2^32");
      r.indices.push_back(i.get<std::uint32_t>());
    }
    std::sort(r.indices.begin(), r.indices.end());
  }
  return r;
}

ColourSelector parse_colour(const json& j, const std::string& source, const std::string& at) {
  if (!j.is_object() || !j.contains("rgb")) throw map_error(source, at + " needs \"rgb\" (3 numbers in [0, 1])");
  check_keys(j, {"rgb", "tolerance", "clusters"}, source, at);
  ColourSelector c;
  c.rgb = vec3(j["rgb"], source, at + ".rgb");
  if (!((c.rgb.array() >= 0).all() && (c.rgb.array() <= 1).all())) throw map_error(source, at + ".rgb must lie in [0, 1]");
  if (j.contains("tolerance") && j.contains("clusters"))
    throw map_error(source, at + ": \"tolerance\" or \"clusters\", not both");
  if (j.contains("tolerance")) c.tolerance = number(j, "tolerance", source, at, 0, true);
  if (j.contains("clusters")) {
    const double k = number(j, "clusters", source, at, 2);
    if (k != std::floor(k) || k > kMaxClusters)
      throw map_error(source, at + ": \"clusters\" must be a whole number from 2 to " + std::to_string(kMaxClusters));
    c.clusters = int(k);
  }
  return c;
}

bool region_holds(const MaterialRegion& r, const Eigen::Vector3d& x, std::uint32_t index) {
  const auto listed = [&] { return std::binary_search(r.indices.begin(), r.indices.end(), index); };
  switch (r.kind) {
    case MaterialRegion::Kind::kBox:
      return (x.array() >= r.lo.array()).all() && (x.array() <= r.hi.array()).all() && (!r.colour || listed());
    case MaterialRegion::Kind::kSphere:
      return (x - r.center).squaredNorm() <= r.radius * r.radius && (!r.colour || listed());
    case MaterialRegion::Kind::kIndices:
    case MaterialRegion::Kind::kColour: return listed();
  }
  return false;
}

// The base colour a viewer shows head-on (SH band 0), clamped to [0, 1].
Eigen::Vector3d base_colour(const Eigen::Vector3f& f_dc) {
  constexpr double kShC0 = 0.28209479177387814;
  return (0.5 + kShC0 * f_dc.cast<double>().array()).cwiseMax(0.0).cwiseMin(1.0).matrix();
}

// k-means of `colours` weighted by `weights` into k clusters (Lloyd's iterations from a
// farthest-point start: the heaviest colour, then each time the colour farthest from the centres
// chosen): the cluster of each colour.
std::vector<int> colour_clusters(const std::vector<Eigen::Vector3d>& colours, const std::vector<double>& weights, int k,
                                 std::vector<Eigen::Vector3d>& centres) {
  const std::size_t n = colours.size();
  std::vector<int> of(n, 0);
  centres.clear();
  if (n == 0) return of;
  std::size_t first = std::size_t(std::max_element(weights.begin(), weights.end()) - weights.begin());
  centres.push_back(colours[first]);
  std::vector<double> d2(n, std::numeric_limits<double>::infinity());
  while (int(centres.size()) < k) {
    std::size_t far = 0;
    for (std::size_t i = 0; i < n; ++i) {
      d2[i] = std::min(d2[i], (colours[i] - centres.back()).squaredNorm());
      if (d2[i] > d2[far]) far = i;
    }
    if (!(d2[far] > 0)) break;  // fewer distinct colours than clusters
    centres.push_back(colours[far]);
  }
  for (int iteration = 0; iteration < kClusterIterations; ++iteration) {
    bool moved = false;
    for (std::size_t i = 0; i < n; ++i) {
      int best = 0;
      for (int c = 1; c < int(centres.size()); ++c)
        if ((colours[i] - centres[std::size_t(c)]).squaredNorm() < (colours[i] - centres[std::size_t(best)]).squaredNorm()) best = c;
      moved = moved || best != of[i];
      of[i] = best;
    }
    if (!moved && iteration > 0) break;
    std::vector<Eigen::Vector3d> sum(centres.size(), Eigen::Vector3d::Zero());
    std::vector<double> w(centres.size(), 0);
    for (std::size_t i = 0; i < n; ++i) {
      sum[std::size_t(of[i])] += weights[i] * colours[i];
      w[std::size_t(of[i])] += weights[i];
    }
    for (std::size_t c = 0; c < centres.size(); ++c)
      if (w[c] > 0) centres[c] = sum[c] / w[c];
  }
  return of;
}

}  // namespace

MaterialMap MaterialMap::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw file_error(path, "cannot open the material map");
  std::stringstream ss;
  ss << in.rdbuf();
  const json j = json::parse(ss.str(), nullptr, false);
  if (j.is_discarded()) throw file_error(path, "not valid JSON");
  return parse(j, path);
}

MaterialMap MaterialMap::parse(const json& j, const std::string& source) {
  if (!j.is_object()) throw map_error(source, "a material map must be a JSON object");
  check_keys(j, {"frame", "materials", "regions"}, source, "the map");
  MaterialMap m;
  m.source = source;
  if (j.contains("frame")) {
    const std::string f = j["frame"].is_string() ? j["frame"].get<std::string>() : "";
    if (f != "scene" && f != "world") throw map_error(source, "\"frame\" must be \"scene\" or \"world\"");
    m.frame = f == "world" ? Frame::kWorld : Frame::kScene;
  }
  if (!j.contains("materials") || !j["materials"].is_array() || j["materials"].empty())
    throw map_error(source, "needs a non-empty array \"materials\"");
  if (j["materials"].size() > kMaxMaterials)
    throw map_error(source, std::to_string(j["materials"].size()) + " materials; at most " + std::to_string(kMaxMaterials));
  std::map<std::string, std::size_t> ids;
  for (std::size_t i = 0; i < j["materials"].size(); ++i) {
    Material mat = parse_material(j["materials"][i], source, "materials[" + std::to_string(i) + "]");
    if (!ids.emplace(mat.name, i).second) throw map_error(source, "two materials named \"" + mat.name + "\"");
    m.materials.push_back(std::move(mat));
  }
  if (!j.contains("regions") || !j["regions"].is_array()) throw map_error(source, "needs an array \"regions\"");
  for (std::size_t i = 0; i < j["regions"].size(); ++i)
    m.regions.push_back(parse_region(j["regions"][i], ids, source, "regions[" + std::to_string(i) + "]"));
  return m;
}

bool MaterialMap::needs_colours() const noexcept {
  return std::any_of(regions.begin(), regions.end(), [](const MaterialRegion& r) { return r.colour && !r.colour_resolved; });
}

SceneColours SceneColours::of(const GaussianScene& scene) {
  SceneColours c;
  if (scene.colors_dc.size() != scene.size()) return c;
  c.f_dc = scene.colors_dc;
  c.opacity = scene.opacities;
  c.source_index = scene.source_index;
  return c;
}

MaterialMap resolve_colour_regions(const MaterialMap& map, const GaussianScene& scene, std::vector<std::size_t>* selected) {
  return resolve_colour_regions(map, SceneColours::of(scene), selected);
}

MaterialMap resolve_colour_regions(const MaterialMap& map, const SceneColours& scene, std::vector<std::size_t>* selected) {
  MaterialMap out = map;
  if (selected) selected->assign(map.regions.size(), 0);
  if (!map.needs_colours()) return out;
  const std::size_t n = scene.f_dc.size();
  if (n == 0 || scene.opacity.size() != n || scene.source_index.size() != n)
    throw map_error(map.source, "a region selects by colour, and the scene has no colour (f_dc) to select by");
  std::vector<Eigen::Vector3d> colours(n);
  std::vector<double> weights(n);
  for (std::size_t i = 0; i < n; ++i) {
    colours[i] = base_colour(scene.f_dc[i]);
    weights[i] = std::max(double(scene.opacity[i]), 1e-6);
  }
  std::map<int, std::pair<std::vector<int>, std::vector<Eigen::Vector3d>>> by_k;  // k-means runs, one per K
  for (std::size_t r = 0; r < out.regions.size(); ++r) {
    MaterialRegion& region = out.regions[r];
    if (!region.colour || region.colour_resolved) continue;
    const ColourSelector& c = *region.colour;
    region.indices.clear();
    if (c.clusters > 0) {
      auto it = by_k.find(c.clusters);
      if (it == by_k.end()) {
        std::vector<Eigen::Vector3d> centres;
        std::vector<int> of = colour_clusters(colours, weights, c.clusters, centres);
        it = by_k.emplace(c.clusters, std::make_pair(std::move(of), std::move(centres))).first;
      }
      const auto& [of, centres] = it->second;
      int nearest = 0;
      for (int k = 1; k < int(centres.size()); ++k)
        if ((centres[std::size_t(k)] - c.rgb).squaredNorm() < (centres[std::size_t(nearest)] - c.rgb).squaredNorm()) nearest = k;
      for (std::size_t i = 0; i < n; ++i)
        if (of[i] == nearest) region.indices.push_back(scene.source_index[i]);
    } else {
      for (std::size_t i = 0; i < n; ++i)
        if ((colours[i] - c.rgb).norm() <= c.tolerance) region.indices.push_back(scene.source_index[i]);
    }
    std::sort(region.indices.begin(), region.indices.end());
    region.colour_resolved = true;
    if (selected) (*selected)[r] = region.indices.size();
  }
  return out;
}

std::shared_ptr<const MaterialField> MaterialField::resolve(const MaterialMap& map, const CollisionWorld& world,
                                                            const ProxyParams& base) {
  for (std::size_t r = 0; r < map.regions.size(); ++r)
    if (map.regions[r].colour && !map.regions[r].colour_resolved)
      throw map_error(map.source, "regions[" + std::to_string(r) + "] selects by colour, which needs the scene's colours: "
                                  "resolve it on the scene first (resolve_colour_regions; the commands do this with "
                                  "the scene they load)");
  auto f = std::make_shared<MaterialField>();
  f->names_.push_back("default");
  f->props_.push_back({{base.stiffness, base.damping, base.mu_s, base.mu_k, 0, 0, 0}});
  f->textures_.emplace_back();
  for (const Material& m : map.materials) {
    Props p{{m.stiffness.value_or(base.stiffness), m.damping.value_or(base.damping), m.mu_s.value_or(base.mu_s),
             m.mu_k.value_or(base.mu_k), m.viscosity, m.texture_gain, m.vibration}};
    if (p.v[3] > p.v[2])
      throw map_error(map.source, "material \"" + m.name + "\": mu_k " + std::to_string(p.v[3]) + " exceeds mu_s " +
                                      std::to_string(p.v[2]) + " (a property it leaves out is the proxy's own)");
    f->props_.push_back(p);
    f->names_.push_back(m.name);
    f->textures_.push_back(m.texture);
    f->textured_ = f->textured_ || m.texture_gain > 0;
  }
  // The file's frame: the world's records hold c = s R x + t (SimilarityTransform::apply).
  const SimilarityTransform& t = world.scene_to_world();
  const Eigen::Quaterniond inverse = t.rotation.conjugate();
  f->slot_material_.assign(world.size(), 0);
  f->counts_.assign(f->props_.size(), 0);
  const std::span<const CollisionGaussian> g = world.gaussians();
  for (std::size_t k = 0; k < g.size(); ++k) {
    const Eigen::Vector3d c(g[k].center[0], g[k].center[1], g[k].center[2]);
    const Eigen::Vector3d x = map.frame == MaterialMap::Frame::kWorld ? c : Eigen::Vector3d(inverse * (c - t.translation) / t.scale);
    for (std::size_t r = map.regions.size(); r-- > 0;)
      if (region_holds(map.regions[r], x, g[k].source_index)) {
        f->slot_material_[k] = std::uint8_t(map.regions[r].material + 1);
        break;
      }
    ++f->counts_[f->slot_material_[k]];
  }
  f->build_moments(world);
  return f;
}

void MaterialField::build_moments(const CollisionWorld& world) {
  // Bottom-up over the preorder nodes: a node's children come after it.
  const std::span<const BvhNode> nodes = world.bvh().nodes();
  const std::span<const CollisionGaussian> g = world.gaussians();
  moments_.assign(nodes.size(), {});
  for (std::size_t i = nodes.size(); i-- > 0;) {
    NodeMoments& m = moments_[i];
    const BvhNode& n = nodes[i];
    if (n.count > 0) {
      m.material = slot_material_[n.first];
      for (std::uint32_t k = n.first; k < n.first + n.count; ++k) {
        const double a = g[k].opacity;
        const Eigen::Vector3d c(g[k].center[0], g[k].center[1], g[k].center[2]);
        m.alpha += a;
        for (int j = 0; j < 3; ++j) m.alpha_c[j] += a * c[j];
        m.alpha_c2 += a * c.squaredNorm();
        if (slot_material_[k] != m.material) m.material = -1;
      }
      continue;
    }
    const NodeMoments &l = moments_[i + 1], &r = moments_[n.first];
    m.alpha = l.alpha + r.alpha;
    for (int j = 0; j < 3; ++j) m.alpha_c[j] = l.alpha_c[j] + r.alpha_c[j];
    m.alpha_c2 = l.alpha_c2 + r.alpha_c2;
    m.material = l.material == r.material ? l.material : -1;
  }
}

MaterialBlend MaterialField::at(const CollisionWorld& world, const Eigen::Vector3d& center, double radius,
                                const Eigen::Vector3d& contact) const noexcept {
  // Weights per material id (at most 255 ids; summed on the stack): sum alpha (1 - d^2 / rho^2).
  Weights w{};
  const double rho2 = kKernel * kKernel * radius * radius;
  const std::span<const BvhNode> nodes = world.bvh().nodes();
  const std::span<const CollisionGaussian> g = world.gaussians();
  std::uint32_t stack[64];
  int top = 0;
  if (!nodes.empty()) stack[top++] = 0;
  while (top > 0) {
    const std::uint32_t i = stack[--top];
    const BvhNode& n = nodes[i];
    double near2 = 0, far2 = 0;  // the box's nearest and farthest points from the centre
    for (int k = 0; k < 3; ++k) {
      const double lo = double(n.lo[k]) - center[k], hi = double(n.hi[k]) - center[k];
      const double nearest = lo > 0 ? lo : hi < 0 ? -hi : 0.0;
      near2 += nearest * nearest;
      far2 += std::max(lo * lo, hi * hi);
    }
    if (near2 > rho2) continue;
    const NodeMoments& m = moments_[i];
    if (m.material >= 0 && far2 <= rho2) {  // one material, wholly inside: from its moments
      const double pc = center.x() * m.alpha_c[0] + center.y() * m.alpha_c[1] + center.z() * m.alpha_c[2];
      w[std::size_t(m.material)] += m.alpha - (m.alpha_c2 - 2 * pc + center.squaredNorm() * m.alpha) / rho2;
      continue;
    }
    if (n.count == 0) {
      if (top + 2 > 64) continue;  // (deeper than any BVH this world builds)
      stack[top++] = n.first;
      stack[top++] = i + 1;
      continue;
    }
    for (std::uint32_t k = n.first; k < n.first + n.count; ++k) {
      const double d2 = (Eigen::Vector3d(g[k].center[0], g[k].center[1], g[k].center[2]) - center).squaredNorm();
      if (d2 < rho2) w[slot_material_[k]] += double(g[k].opacity) * (1 - d2 / rho2);
    }
  }
  return blend(w, contact);
}

MaterialBlend MaterialField::blend(const Weights& w, const Eigen::Vector3d& contact) const noexcept {
  MaterialBlend b;
  double total = 0, best = 0;
  double v[7] = {0, 0, 0, 0, 0, 0, 0};
  for (std::size_t id = 0; id < props_.size(); ++id) {
    if (!(w[id] > 0)) continue;
    total += w[id];
    for (int p = 0; p < 7; ++p) v[p] += w[id] * props_[id].v[p];
    if (textures_[id].kind != ProceduralTexture::Kind::kNone && contact.allFinite())
      b.procedural += w[id] * textures_[id].height(contact);
    if (w[id] > best) best = w[id], b.dominant = int(id);
  }
  if (!(total > 0)) {
    for (int p = 0; p < 7; ++p) v[p] = props_[0].v[p];
    total = 1;
  }
  b.stiffness = v[0] / total;
  b.damping = v[1] / total;
  b.mu_s = v[2] / total;
  b.mu_k = std::min(v[3] / total, b.mu_s);
  b.viscosity = v[4] / total;
  b.texture_gain = v[5] / total;
  b.vibration = v[6] / total;
  b.procedural /= total;
  return b;
}

int MaterialField::dominant(std::span<const std::uint32_t> slots, const CollisionWorld& world) const noexcept {
  Weights w{};
  for (std::uint32_t s : slots)
    if (s < slot_material_.size()) w[slot_material_[s]] += double(world.gaussians()[s].opacity);
  int best = 0;
  for (std::size_t id = 1; id < props_.size(); ++id)
    if (w[id] > w[std::size_t(best)]) best = int(id);
  return best;
}

json regions_in_world(const MaterialMap& map, const CollisionWorld& world) {
  const SimilarityTransform& t = world.scene_to_world();
  const bool scene = map.frame == MaterialMap::Frame::kScene;
  const auto place = [&](const Eigen::Vector3d& x) { return scene ? t.apply(x) : x; };
  json out = json::array();
  for (const MaterialRegion& r : map.regions) {
    json j{{"material", map.materials[r.material].name}};
    if (r.kind == MaterialRegion::Kind::kBox) {
      json corners = json::array();
      for (int c = 0; c < 8; ++c) {
        const Eigen::Vector3d x = place(Eigen::Vector3d(c & 1 ? r.hi.x() : r.lo.x(), c & 2 ? r.hi.y() : r.lo.y(),
                                                        c & 4 ? r.hi.z() : r.lo.z()));
        corners.push_back({x.x(), x.y(), x.z()});
      }
      j["box"] = {{"corners", corners}};
    } else if (r.kind == MaterialRegion::Kind::kSphere) {
      const Eigen::Vector3d c = place(r.center);
      j["sphere"] = {{"center", {c.x(), c.y(), c.z()}}, {"radius", r.radius * (scene ? t.scale : 1.0)}};
    } else if (r.kind == MaterialRegion::Kind::kIndices) {
      j["indices"] = r.indices.size();
    }
    if (r.colour) {
      j["colour"] = {{"rgb", {r.colour->rgb.x(), r.colour->rgb.y(), r.colour->rgb.z()}}};
      if (r.colour_resolved) j["colour"]["selected"] = r.indices.size();
    }
    out.push_back(std::move(j));
  }
  return out;
}

bool MaterialField::contact_shares(std::span<const Contact> contacts, Weights& shares) const noexcept {
  return weighted_shares(
      [&](auto&& add) {
        for (const Contact& c : contacts) add(c.slot, double(c.opacity));
      },
      shares);
}

MaterialFollower::MaterialFollower(std::shared_ptr<const MaterialField> field, const ProxyParams& base)
    : field_(std::move(field)) {
  blend_.stiffness = base.stiffness;
  blend_.damping = base.damping;
  blend_.mu_s = base.mu_s;
  blend_.mu_k = base.mu_k;
}

void MaterialFollower::release() noexcept {
  started_ = false;
  texture_ms_ = 0;
  texture_.release();
}

const MaterialBlend& MaterialFollower::update(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double radius,
                                              const Eigen::Vector3d& contact, std::span<const Contact> blockers) noexcept {
  MaterialField::Weights target;  // (only the first material_count() entries are read)
  const bool held = field_->contact_shares(blockers, target);
  return follow(p, n, radius, contact, held ? &target : nullptr);
}

const MaterialBlend& MaterialFollower::follow(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double radius,
                                              const Eigen::Vector3d& contact,
                                              const MaterialField::Weights* target) noexcept {
  const std::size_t count = field_->material_count();
  double held = 0;  // how much of the shares a material holds (0: none yet)
  for (std::size_t id = 0; id < count; ++id) held += shares_[id];
  if (target != nullptr) {
    if (!started_ || !(held > 0)) {
      for (std::size_t id = 0; id < count; ++id) shares_[id] = (*target)[id];
    } else {
      // Followed along the path: a slide of ds moves the shares 1 - exp(-ds / R) of the way.
      const Eigen::Vector3d step = p - at_;
      const double a = 1 - std::exp(-(step - step.dot(n) * n).norm() / radius);
      for (std::size_t id = 0; id < count; ++id) shares_[id] += a * ((*target)[id] - shares_[id]);
    }
  } else if (!started_) {
    for (std::size_t id = 0; id < count; ++id) shares_[id] = 0;  // the proxy's own until a Gaussian holds it
  }
  started_ = true;
  at_ = p;
  blend_ = field_->blend(shares_, contact);
  return blend_;
}

Eigen::Vector3d MaterialFollower::add_forces(const CollisionWorld& world, Eigen::Vector3d f, const Eigen::Vector3d& contact,
                                             const Eigen::Vector3d& n, const Eigen::Vector3d& velocity, double radius,
                                             double f_max, double dt) noexcept {
  const double tip = needs_tip() ? tip_height(world, contact, n, TextureState::tip_reach(radius)) : 0.0;
  return add_forces_at_tip(tip, f, contact, n, velocity, radius, f_max, dt);
}

Eigen::Vector3d MaterialFollower::add_forces_at_tip(double tip, Eigen::Vector3d f, const Eigen::Vector3d& contact,
                                                    const Eigen::Vector3d& n, const Eigen::Vector3d& velocity,
                                                    double radius, double f_max, double dt) noexcept {
  const Eigen::Vector3d v_t = velocity - velocity.dot(n) * n;  // the device's slide
  if (blend_.viscosity > 0) f -= blend_.viscosity * v_t;
  Eigen::Vector3d texture = Eigen::Vector3d::Zero();
  if (blend_.texture_gain > 0) {
    texture = texture_.force(tip, contact, n, radius, blend_.stiffness, blend_.texture_gain, blend_.procedural);
    // Coulomb's law on the relief's normal force: friction follows it while sliding (a bump
    // pushes up and resists more, a groove less), faded in below kSlideSpeed so that a tool at
    // rest feels no tangential buzz. It opposes the slide; with the normal force kept >= 0
    // below, the sum of friction stays opposed to it.
    const double slide = v_t.norm();
    if (slide > 0 && blend_.mu_k > 0) texture -= blend_.mu_k * texture.dot(n) * v_t / std::max(slide, kSlideSpeed);
    f += texture;
    const double fn = f.dot(n);
    if (fn < 0) f -= fn * n;  // the relief never pulls the tool in
  } else {
    texture_.release();
  }
  if (f.norm() > f_max) f *= f_max / f.norm();
  // The texture's vibration envelope: its mean square force over kVibrationWindow.
  const double a = dt > 0 ? -std::expm1(-dt / kVibrationWindow) : 1.0;
  texture_ms_ += (texture.squaredNorm() - texture_ms_) * a;
  return f;
}

std::string_view MaterialField::name(int id) const noexcept {
  return id >= 0 && std::size_t(id) < names_.size() ? std::string_view(names_[std::size_t(id)]) : std::string_view("?");
}

void apply_blend(const MaterialBlend& blend, VirtualCoupling& coupling, FrictionCone& friction) noexcept {
  coupling.set_gains(blend.stiffness, blend.damping);
  friction.set_coefficients(blend.mu_s, blend.mu_k);
}

}  // namespace gshaptics
