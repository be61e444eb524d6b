// INRIA 3DGS binary little-endian PLY reader. Properties are found by name, so any SH degree,
// optional normals, extra properties and float/double storage all work (SOURCES.md conventions:
// opacity is a logit, scale_* are log-scales, rot_0..3 is w,x,y,z and not normalised).

#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "detail/accept_gaussian.h"
#include "gshaptics/io/error.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics {
namespace {

enum class PlyType { kI8, kU8, kI16, kU16, kI32, kU32, kF32, kF64 };

std::optional<PlyType> parse_type(const std::string& s) {
  if (s == "char" || s == "int8") return PlyType::kI8;
  if (s == "uchar" || s == "uint8") return PlyType::kU8;
  if (s == "short" || s == "int16") return PlyType::kI16;
  if (s == "ushort" || s == "uint16") return PlyType::kU16;
  if (s == "int" || s == "int32") return PlyType::kI32;
  if (s == "uint" || s == "uint32") return PlyType::kU32;
  if (s == "float" || s == "float32") return PlyType::kF32;
  if (s == "double" || s == "float64") return PlyType::kF64;
  return std::nullopt;
}

std::size_t type_size(PlyType t) {
  switch (t) {
    case PlyType::kI8: case PlyType::kU8: return 1;
    case PlyType::kI16: case PlyType::kU16: return 2;
    case PlyType::kI32: case PlyType::kU32: case PlyType::kF32: return 4;
    case PlyType::kF64: return 8;
  }
  return 0;
}

template <typename T>
T load_le(const std::uint8_t* p) {
  static_assert(std::endian::native == std::endian::little, "big-endian hosts are not supported");
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

float read_as_float(const std::uint8_t* p, PlyType t) {
  switch (t) {
    case PlyType::kI8: return float(load_le<std::int8_t>(p));
    case PlyType::kU8: return float(load_le<std::uint8_t>(p));
    case PlyType::kI16: return float(load_le<std::int16_t>(p));
    case PlyType::kU16: return float(load_le<std::uint16_t>(p));
    case PlyType::kI32: return float(load_le<std::int32_t>(p));
    case PlyType::kU32: return float(load_le<std::uint32_t>(p));
    case PlyType::kF32: return load_le<float>(p);
    case PlyType::kF64: return float(load_le<double>(p));
  }
  return std::numeric_limits<float>::quiet_NaN();
}

struct Property {
  std::string name;
  PlyType type = PlyType::kF32;
  bool is_list = false;
  std::size_t offset = 0;  // within the element's record (fixed-size elements only)
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
  [[nodiscard]] bool has_list() const {
    for (const auto& p : properties) if (p.is_list) return true;
    return false;
  }
  [[nodiscard]] std::size_t stride() const {
    std::size_t s = 0;
    for (const auto& p : properties) s += type_size(p.type);
    return s;
  }
  [[nodiscard]] const Property* find(const std::string& n) const {
    for (const auto& p : properties) if (p.name == n) return &p;
    return nullptr;
  }
};

struct Header {
  std::string format;
  std::vector<Element> elements;
  std::size_t data_offset = 0;  // first byte after "end_header\n"
};

constexpr std::size_t kMaxHeaderBytes = 1 << 20;

// Parses the header; `format` is left as written so the caller can name what is unsupported.
Header parse_header(std::span<const std::uint8_t> bytes, const std::string& path) {
  if (bytes.empty()) throw file_error(path, "file is empty");
  const std::size_t limit = std::min(bytes.size(), kMaxHeaderBytes);
  const auto* text = reinterpret_cast<const char*>(bytes.data());
  const std::string_view view(text, limit);
  const std::size_t end = view.find("end_header");
  if (view.substr(0, 3) != "ply") throw file_error(path, "not a PLY file (no 'ply' magic)");
  if (end == std::string_view::npos)
    throw file_error(path, "PLY header has no 'end_header' line within the first " +
                               std::to_string(limit) + " bytes (truncated or not a PLY file)");
  std::size_t after = end + std::strlen("end_header");
  if (after < bytes.size() && text[after] == '\r') ++after;
  if (after >= bytes.size() || text[after] != '\n')
    throw file_error(path, "PLY header: 'end_header' is not followed by a newline");
  Header h;
  h.data_offset = after + 1;

  std::istringstream in{std::string(view.substr(0, end))};
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (kw.empty() || kw == "ply" || kw == "comment" || kw == "obj_info") continue;
    const auto bad = [&](const std::string& what) {
      return file_error(path, "PLY header line " + std::to_string(line_no) + " ('" + line +
                                  "'): " + what);
    };
    if (kw == "format") {
      ls >> h.format;
      if (h.format.empty()) throw bad("missing format name");
    } else if (kw == "element") {
      Element e;
      std::string count;
      ls >> e.name >> count;
      const auto* b = count.data();
      const auto r = std::from_chars(b, b + count.size(), e.count);
      if (e.name.empty() || r.ec != std::errc() || r.ptr != b + count.size())
        throw bad("expected 'element <name> <count>'");
      h.elements.push_back(std::move(e));
    } else if (kw == "property") {
      if (h.elements.empty()) throw bad("property before any element");
      Property p;
      std::string type;
      ls >> type;
      if (type == "list") {
        std::string count_type, item_type;
        ls >> count_type >> item_type >> p.name;
        if (!parse_type(count_type) || !parse_type(item_type) || p.name.empty())
          throw bad("malformed list property");
        p.is_list = true;
      } else {
        const auto t = parse_type(type);
        if (!t) throw bad("unknown property type '" + type + "'");
        p.type = *t;
        ls >> p.name;
        if (p.name.empty()) throw bad("property has no name");
      }
      auto& props = h.elements.back().properties;
      p.offset = 0;
      for (const auto& q : props) p.offset += type_size(q.type);
      props.push_back(std::move(p));
    } else {
      throw bad("unknown keyword '" + kw + "'");
    }
  }
  if (h.format.empty()) throw file_error(path, "PLY header has no 'format' line");
  return h;
}

bool is_known_unused(const std::string& n) {
  return n == "nx" || n == "ny" || n == "nz" || n.rfind("f_dc_", 0) == 0 ||
         n.rfind("f_rest_", 0) == 0;
}

}  // namespace

SceneFormat detect_ply_variant(std::span<const std::uint8_t> bytes) {
  const std::size_t n = std::min<std::size_t>(bytes.size(), 4096);
  const std::string_view head(reinterpret_cast<const char*>(bytes.data()), n);
  if (head.find("format ascii") != std::string_view::npos) return SceneFormat::kAsciiPly;
  if (head.find("format binary_big_endian") != std::string_view::npos)
    return SceneFormat::kBigEndianPly;
  if (head.find("element chunk") != std::string_view::npos ||
      head.find("packed_position") != std::string_view::npos)
    return SceneFormat::kCompressedPly;
  return SceneFormat::kInriaPly;
}

LoadedScene read_inria_ply(std::span<const std::uint8_t> bytes, const std::string& path,
                           const ProgressFn& progress) {
  const Header h = parse_header(bytes, path);
  if (h.format == "ascii")
    throw file_error(path, "ASCII PLY is not supported yet (only binary_little_endian)");
  if (h.format == "binary_big_endian")
    throw file_error(path, "big-endian binary PLY is not supported yet (only binary_little_endian)");
  if (h.format != "binary_little_endian")
    throw file_error(path, "unknown PLY format '" + h.format + "'");

  std::uint64_t offset = h.data_offset;
  const Element* vertex = nullptr;
  for (const auto& e : h.elements) {
    if (e.name == "chunk")
      throw file_error(path,
                       "PlayCanvas compressed PLY (element 'chunk') is not supported yet; "
                       "decompress it to an INRIA PLY first");
    if (e.name == "vertex") {
      vertex = &e;
      break;
    }
    if (e.has_list())
      throw file_error(path, "element '" + e.name +
                                 "' before 'vertex' has list properties; not supported");
    const std::uint64_t stride = e.stride();
    if (stride != 0 && e.count > (bytes.size() - std::min<std::uint64_t>(offset, bytes.size())) / stride)
      throw file_error_at(path, offset, "truncated: element '" + e.name + "' declares " +
                                            std::to_string(e.count) + " records that do not fit");
    offset += e.count * stride;
  }
  if (vertex == nullptr) throw file_error(path, "PLY has no 'vertex' element");
  if (vertex->has_list()) throw file_error(path, "'vertex' element has list properties");

  static constexpr std::array<const char*, 11> kRequired = {
      "x", "y", "z", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"};
  std::array<const Property*, 11> prop{};
  for (std::size_t i = 0; i < kRequired.size(); ++i) {
    prop[i] = vertex->find(kRequired[i]);
    if (prop[i] == nullptr) {
      if (vertex->find("packed_position") != nullptr)
        throw file_error(path, "PlayCanvas compressed PLY is not supported yet");
      throw file_error(path, std::string("'vertex' element lacks required property '") +
                                 kRequired[i] + "' (not a 3DGS PLY?)");
    }
  }

  LoadedScene out;
  out.report.path = path;
  out.report.format = SceneFormat::kInriaPly;
  out.report.in_file = vertex->count;
  int n_rest = 0;
  for (const auto& p : vertex->properties) {
    if (p.name.rfind("f_rest_", 0) == 0) ++n_rest;
    bool used = false;
    for (const char* r : kRequired) used = used || p.name == r;
    if (!used && !is_known_unused(p.name)) out.report.ignored_properties.push_back(p.name);
  }
  const int coeffs = n_rest / 3;  // per colour channel
  out.report.sh_degree = coeffs >= 15 ? 3 : coeffs >= 8 ? 2 : coeffs >= 3 ? 1 : 0;

  const std::uint64_t stride = vertex->stride();
  const std::uint64_t available = bytes.size() - std::min<std::uint64_t>(offset, bytes.size());
  if (stride == 0) throw file_error(path, "'vertex' element has no properties");
  if (vertex->count > available / stride)
    throw file_error_at(path, offset,
                        "truncated: header declares " + std::to_string(vertex->count) +
                            " vertices of " + std::to_string(stride) + " bytes (" +
                            std::to_string(vertex->count * stride) + " bytes) but only " +
                            std::to_string(available) + " bytes follow the header");
  if (vertex->count > std::numeric_limits<std::uint32_t>::max())
    throw file_error(path, "more than 2^32 vertices are not supported");
  if (vertex->count == 0) throw file_error(path, "PLY declares 0 vertices");

  out.scene.reserve(vertex->count);
  const std::uint8_t* base = bytes.data() + offset;
  const std::uint64_t step = std::max<std::uint64_t>(1, vertex->count / 50);
  for (std::uint64_t i = 0; i < vertex->count; ++i) {
    const std::uint8_t* rec = base + i * stride;
    const auto get = [&](int k) { return read_as_float(rec + prop[k]->offset, prop[k]->type); };
    const float pos[3] = {get(0), get(1), get(2)};
    const float logit = get(3);
    const float log_scale[3] = {get(4), get(5), get(6)};
    const float quat[4] = {get(7), get(8), get(9), get(10)};
    const bool raw_finite = std::isfinite(logit) && std::isfinite(log_scale[0]) &&
                            std::isfinite(log_scale[1]) && std::isfinite(log_scale[2]);
    const float scale[3] = {std::exp(log_scale[0]), std::exp(log_scale[1]), std::exp(log_scale[2])};
    detail::accept_gaussian(pos, scale, quat, detail::sigmoid(logit), std::uint32_t(i), out.scene,
                            out.report, raw_finite);
    if (progress && i % step == 0) progress(double(i) / double(vertex->count));
  }
  if (progress) progress(1.0);
  if (out.scene.empty())
    throw file_error(path, "no valid Gaussian among " + std::to_string(vertex->count) +
                               " (all had NaN/Inf, zero quaternions or bad scales)");
  return out;
}

}  // namespace gshaptics
