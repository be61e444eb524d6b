#pragma once
// PLY header parsing and typed value access, shared by the INRIA and PlayCanvas compressed PLY
// readers. Not part of the public API.

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "gshaptics/error.h"

namespace gshaptics::detail {


enum class PlyType { kI8, kU8, kI16, kU16, kI32, kU32, kF32, kF64 };

inline std::optional<PlyType> parse_type(const std::string& s) {
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

inline std::size_t type_size(PlyType t) {
  switch (t) {
    case PlyType::kI8: case PlyType::kU8: return 1;
    case PlyType::kI16: case PlyType::kU16: return 2;
    case PlyType::kI32: case PlyType::kU32: case PlyType::kF32: return 4;
    case PlyType::kF64: return 8;
  }
  return 0;
}

template <typename T>
inline T load_le(const std::uint8_t* p) {
  static_assert(std::endian::native == std::endian::little, "big-endian hosts are not supported");
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

inline float read_as_float(const std::uint8_t* p, PlyType t) {
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

inline constexpr std::size_t kMaxHeaderBytes = 1 << 20;

// Parses the header; `format` is left as written so the caller can name what is unsupported.
inline Header parse_header(std::span<const std::uint8_t> bytes, const std::string& path) {
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


// Big-endian counterpart of read_as_float.
inline float read_as_float_be(const std::uint8_t* p, PlyType t) {
  std::uint8_t tmp[8];
  const std::size_t n = type_size(t);
  for (std::size_t i = 0; i < n; ++i) tmp[i] = p[n - 1 - i];
  return read_as_float(tmp, t);
}

}  // namespace gshaptics::detail
