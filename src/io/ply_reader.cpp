// INRIA 3DGS binary little-endian PLY reader. Properties are found by name, so any SH degree,
// optional normals, extra properties and float/double storage all work (SOURCES.md conventions:
// opacity is a logit, scale_* are log-scales, rot_0..3 is w,x,y,z and not normalised).

#include <algorithm>
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
#include "detail/ply_header.h"
#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics {
namespace {

using namespace detail;

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

namespace {

// The 3DGS properties every vertex must have, in the order accept() reads them.
constexpr std::array<const char*, 11> kRequired = {
    "x", "y", "z", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"};

// Where a Gaussian's values sit in a vertex record: the 'vertex' element, the required
// properties, and the colour properties kept for conversion (f_dc_0..2 and f_rest_0..K-1).
struct VertexLayout {
  const Element* vertex = nullptr;
  std::size_t element = 0;  // its index among the header's elements
  std::array<std::size_t, 11> prop{};
  std::vector<std::size_t> color_props;
  bool has_dc = false;
  int rest = 0;
};

// The layout of `h`'s vertex element; fills the report's ignored properties and SH degree.
// Throws InputError naming `path` when the element or a required property is missing.
VertexLayout vertex_layout(const Header& h, const std::string& path, bool keep_color, LoadReport& report) {
  VertexLayout L;
  for (std::size_t k = 0; k < h.elements.size(); ++k)
    if (h.elements[k].name == "vertex") {
      L.vertex = &h.elements[k];
      L.element = k;
      break;
    }
  if (L.vertex == nullptr) throw file_error(path, "PLY has no 'vertex' element");
  const Element& vertex = *L.vertex;
  if (vertex.has_list()) throw file_error(path, "'vertex' element has list properties");
  for (std::size_t i = 0; i < kRequired.size(); ++i) {
    const Property* pr = vertex.find(kRequired[i]);
    if (pr == nullptr)
      throw file_error(path, std::string("'vertex' element lacks required property '") + kRequired[i] +
                                 "' (not a 3DGS PLY?)");
    L.prop[i] = std::size_t(pr - vertex.properties.data());
  }
  int n_rest = 0;
  for (const auto& pr : vertex.properties) {
    if (pr.name.rfind("f_rest_", 0) == 0) ++n_rest;
    bool used = false;
    for (const char* r : kRequired) used = used || pr.name == r;
    if (!used && !is_known_unused(pr.name)) report.ignored_properties.push_back(pr.name);
  }
  const int coeffs = n_rest / 3;  // per colour channel
  report.sh_degree = coeffs >= 15 ? 3 : coeffs >= 8 ? 2 : coeffs >= 3 ? 1 : 0;
  // Colour for conversion: f_dc_0..2 and f_rest_0..K-1 (by name, in index order).
  for (const char* c : {"f_dc_0", "f_dc_1", "f_dc_2"})
    if (const Property* pr = vertex.find(c)) L.color_props.push_back(std::size_t(pr - vertex.properties.data()));
  L.has_dc = keep_color && L.color_props.size() == 3;
  if (!L.has_dc) L.color_props.clear();
  while (const Property* pr = vertex.find("f_rest_" + std::to_string(L.rest))) {
    L.color_props.push_back(std::size_t(pr - vertex.properties.data()));
    ++L.rest;
  }
  if (!L.has_dc) {
    L.rest = 0;
    L.color_props.clear();
  }
  return L;
}

void check_vertex_count(std::uint64_t n, const std::string& path) {  // after the truncation checks, which name the sizes
  if (n > std::numeric_limits<std::uint32_t>::max())
    throw file_error(path, "header declares " + std::to_string(n) + " vertices; more than 2^32 are not supported");
}

// The binary records (little- or big-endian): accept(i, values, colours) for each vertex.
template <class Accept>
void read_binary_vertices(std::span<const std::uint8_t> bytes, const Header& h, const VertexLayout& L, bool big,
                          const std::string& path, LoadedScene& out, std::vector<float>& color_values,
                          const Accept& accept) {
  const Element& vertex = *L.vertex;
  const std::uint64_t n = vertex.count;
  std::uint64_t offset = h.data_offset;
  for (std::size_t k = 0; k < L.element; ++k) {
    const Element& e = h.elements[k];
    if (e.has_list())
      throw file_error(path, "element '" + e.name + "' before 'vertex' has list properties; not supported in binary PLY");
    const std::uint64_t stride = e.stride();
    if (stride != 0 && e.count > (bytes.size() - std::min<std::uint64_t>(offset, bytes.size())) / stride)
      throw file_error_at(path, offset, "truncated: element '" + e.name + "' declares " +
                                            std::to_string(e.count) + " records that do not fit");
    offset += e.count * stride;
  }
  const std::uint64_t stride = vertex.stride();
  const std::uint64_t available = bytes.size() - std::min<std::uint64_t>(offset, bytes.size());
  if (stride == 0) throw file_error(path, "'vertex' element has no properties");
  if (n > available / stride)
    throw file_error_at(path, offset,
                        "truncated: header declares " + std::to_string(n) + " vertices of " +
                            std::to_string(stride) + " bytes (" + std::to_string(n * stride) +
                            " bytes) but only " + std::to_string(available) + " bytes follow the header");
  check_vertex_count(n, path);
  out.scene.reserve(n);
  if (L.has_dc) {
    out.scene.colors_dc.reserve(n);
    out.scene.sh_rest.reserve(n * std::size_t(L.rest));
  }
  const std::uint8_t* base = bytes.data() + offset;
  float v[11];
  for (std::uint64_t i = 0; i < n; ++i) {
    const std::uint8_t* rec = base + i * stride;
    for (std::size_t k = 0; k < 11; ++k) {
      const Property& pr = vertex.properties[L.prop[k]];
      v[k] = big ? read_as_float_be(rec + pr.offset, pr.type) : read_as_float(rec + pr.offset, pr.type);
    }
    for (std::size_t k = 0; k < L.color_props.size(); ++k) {
      const Property& pr = vertex.properties[L.color_props[k]];
      color_values[k] = big ? read_as_float_be(rec + pr.offset, pr.type) : read_as_float(rec + pr.offset, pr.type);
    }
    accept(i, v);
  }
}

// The values of one ASCII record into `values` (an out-of-range number reads as infinity).
void parse_ascii_record(std::string_view line, std::vector<float>& values, std::uint64_t i, std::uint64_t line_no,
                        const std::string& path) {
  const std::size_t n_props = values.size();
  const char* p = line.data();
  const char* e = line.data() + line.size();
  for (std::size_t k = 0; k < n_props; ++k) {
    while (p < e && (*p == ' ' || *p == '\t' || *p == '\r')) ++p;
    const auto r = std::from_chars(p, e, values[k]);
    if (r.ec == std::errc::result_out_of_range) {
      values[k] = std::numeric_limits<float>::infinity();
      const char* q = p;
      while (q < e && *q != ' ' && *q != '\t' && *q != '\r') ++q;
      p = q;
    } else if (r.ec != std::errc()) {
      throw file_error(path, "ASCII vertex " + std::to_string(i) + " (data line " + std::to_string(line_no) +
                                 "): value " + std::to_string(k + 1) + " of " + std::to_string(n_props) +
                                 " is not a number");
    } else {
      p = r.ptr;
    }
  }
}

// The ASCII records, one per line: accept(i, values) for each vertex.
template <class Accept>
void read_ascii_vertices(std::span<const std::uint8_t> bytes, const Header& h, const VertexLayout& L,
                         const std::string& path, LoadedScene& out, std::vector<float>& color_values,
                         const Accept& accept) {
  const Element& vertex = *L.vertex;
  const std::uint64_t n = vertex.count;
  const char* cur = reinterpret_cast<const char*>(bytes.data()) + h.data_offset;
  const char* end = reinterpret_cast<const char*>(bytes.data()) + bytes.size();
  std::uint64_t line_no = 0;
  const auto next_line = [&](std::string_view& line) {
    while (cur < end && (*cur == '\n' || *cur == '\r')) ++cur;
    if (cur >= end) return false;
    const char* nl = static_cast<const char*>(std::memchr(cur, '\n', std::size_t(end - cur)));
    const char* stop = nl ? nl : end;
    line = std::string_view(cur, std::size_t(stop - cur));
    cur = stop;
    ++line_no;
    return true;
  };
  std::string_view line;
  for (std::size_t k = 0; k < L.element; ++k)
    for (std::uint64_t r = 0; r < h.elements[k].count; ++r)
      if (!next_line(line))
        throw file_error(path, "truncated: ASCII element '" + h.elements[k].name + "' ends after " +
                                   std::to_string(r) + " of " + std::to_string(h.elements[k].count) + " records");
  const std::size_t n_props = vertex.properties.size();
  if (n > std::uint64_t(end - cur) / (2 * n_props) + 1)
    throw file_error(path, "truncated: header declares " + std::to_string(n) + " ASCII vertices but only " +
                               std::to_string(end - cur) + " bytes follow the header");
  check_vertex_count(n, path);
  out.scene.reserve(n);
  std::vector<float> values(n_props);
  float v[11];
  for (std::uint64_t i = 0; i < n; ++i) {
    if (!next_line(line))
      throw file_error(path, "truncated: ASCII vertex data ends after " + std::to_string(i) + " of " +
                                 std::to_string(n) + " vertices");
    parse_ascii_record(line, values, i, line_no, path);
    for (std::size_t k = 0; k < 11; ++k) v[k] = values[L.prop[k]];
    for (std::size_t k = 0; k < L.color_props.size(); ++k) color_values[k] = values[L.color_props[k]];
    accept(i, v);
  }
}

}  // namespace

LoadedScene read_inria_ply(std::span<const std::uint8_t> bytes, const std::string& path,
    const LoadOptions& options) {
  const ProgressFn& progress = options.progress;
  const Header h = parse_header(bytes, path);
  const bool ascii = h.format == "ascii";
  const bool big = h.format == "binary_big_endian";
  if (!ascii && !big && h.format != "binary_little_endian")
    throw file_error(path, "unknown PLY format '" + h.format +
                               "' (expected ascii, binary_little_endian or binary_big_endian)");

  for (const auto& e : h.elements)
    if (e.name == "chunk" || e.find("packed_position") != nullptr) return read_compressed_ply(bytes, path, options);

  LoadedScene out;
  const VertexLayout L = vertex_layout(h, path, options.keep_color, out.report);
  out.report.path = path;
  out.report.format = ascii ? SceneFormat::kAsciiPly : big ? SceneFormat::kBigEndianPly : SceneFormat::kInriaPly;
  out.report.frame = out.scene.frame = SceneFrame::kRdf;
  out.report.in_file = L.vertex->count;
  out.scene.sh_rest_count = L.rest;
  std::vector<float> color_values(L.color_props.size());
  if (L.vertex->count == 0) throw file_error(path, "PLY declares 0 vertices");

  const std::uint64_t n = L.vertex->count;
  const std::uint64_t step = std::max<std::uint64_t>(1, n / 50);
  const auto accept = [&](std::uint64_t i, const float* v) {
    const float pos[3] = {v[0], v[1], v[2]};
    const float logit = v[3];
    const float log_scale[3] = {v[4], v[5], v[6]};
    const float quat[4] = {v[7], v[8], v[9], v[10]};
    const bool raw_finite = std::isfinite(logit) && std::isfinite(log_scale[0]) &&
                            std::isfinite(log_scale[1]) && std::isfinite(log_scale[2]);
    const float scale[3] = {std::exp(log_scale[0]), std::exp(log_scale[1]), std::exp(log_scale[2])};
    if (detail::accept_gaussian(pos, scale, quat, detail::sigmoid(logit), std::uint32_t(i), out.scene,
                                out.report, raw_finite) &&
        L.has_dc) {
      out.scene.colors_dc.emplace_back(color_values[0], color_values[1], color_values[2]);
      out.scene.sh_rest.insert(out.scene.sh_rest.end(), color_values.begin() + 3, color_values.end());
    }
    if (progress && i % step == 0) progress(double(i) / double(n));
  };
  if (ascii)
    read_ascii_vertices(bytes, h, L, path, out, color_values, accept);
  else
    read_binary_vertices(bytes, h, L, big, path, out, color_values, accept);
  detail::finish_load(out, path, n, progress);
  return out;
}

}  // namespace gshaptics
