// PlayCanvas compressed PLY (SuperSplat): `element chunk` with per-chunk min/max of position,
// log-scale and colour, then `element vertex` with four packed uint32 per Gaussian, 256 Gaussians
// per chunk (SOURCES.md, "Conventions"). Positions and log-scales are 11/10/11-bit fractions
// lerped between the chunk's min and max; rotations are "largest of four" with 2 bits for the
// index and 3 x 10 bits for the others in [-1/sqrt2, 1/sqrt2]; colour is RGBA 8 bits each with
// A the opacity after the sigmoid.

#include <cmath>

#include "detail/accept_gaussian.h"
#include "detail/ply_header.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics {

using namespace detail;

LoadedScene read_compressed_ply(std::span<const std::uint8_t> bytes, const std::string& path,
    const LoadOptions& options) {
  const ProgressFn& progress = options.progress;
  const Header h = parse_header(bytes, path);
  if (h.format != "binary_little_endian")
    throw file_error(path, "compressed PLY must be binary_little_endian, not '" + h.format + "'");
  const Element* chunk = nullptr;
  const Element* vertex = nullptr;
  std::uint64_t offset = h.data_offset, chunk_offset = 0, vertex_offset = 0;
  for (const auto& e : h.elements) {
    if (e.has_list()) throw file_error(path, "element '" + e.name + "' has list properties");
    const std::uint64_t stride = e.stride();
    if (stride != 0 && e.count > (bytes.size() - std::min<std::uint64_t>(offset, bytes.size())) / stride)
      throw file_error_at(path, offset, "truncated: element '" + e.name + "' declares " +
                                            std::to_string(e.count) + " records of " +
                                            std::to_string(stride) + " bytes that do not fit");
    if (e.name == "chunk") { chunk = &e; chunk_offset = offset; }
    if (e.name == "vertex") { vertex = &e; vertex_offset = offset; }
    offset += e.count * stride;
  }
  if (chunk == nullptr || vertex == nullptr)
    throw file_error(path, "compressed PLY needs 'chunk' and 'vertex' elements");
  static const char* kChunkProps[] = {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
                                      "min_scale_x", "min_scale_y", "min_scale_z",
                                      "max_scale_x", "max_scale_y", "max_scale_z"};
  const Property* cp[12];
  for (int k = 0; k < 12; ++k) {
    cp[k] = chunk->find(kChunkProps[k]);
    if (cp[k] == nullptr) throw file_error(path, std::string("'chunk' element lacks '") + kChunkProps[k] + "'");
  }
  static const char* kColorProps[] = {"min_r", "min_g", "min_b", "max_r", "max_g", "max_b"};
  const Property* colp[6];
  bool has_color = true;
  for (int k = 0; k < 6; ++k) {
    colp[k] = chunk->find(kColorProps[k]);
    has_color = has_color && colp[k] != nullptr;
  }
  static const char* kVertexProps[] = {"packed_position", "packed_rotation", "packed_scale", "packed_color"};
  const Property* vp[4];
  for (int k = 0; k < 4; ++k) {
    vp[k] = vertex->find(kVertexProps[k]);
    if (vp[k] == nullptr) throw file_error(path, std::string("'vertex' element lacks '") + kVertexProps[k] + "'");
    if (vp[k]->type != PlyType::kU32 && vp[k]->type != PlyType::kI32)
      throw file_error(path, std::string("'") + kVertexProps[k] + "' must be a 32-bit integer");
  }
  const std::uint64_t n = vertex->count;
  if (n == 0) throw file_error(path, "compressed PLY declares 0 vertices");
  if (n > std::numeric_limits<std::uint32_t>::max()) throw file_error(path, "more than 2^32 vertices");
  if ((n + 255) / 256 > chunk->count)
    throw file_error(path, std::to_string(n) + " vertices need " + std::to_string((n + 255) / 256) +
                               " chunks of 256, the file has " + std::to_string(chunk->count));

  LoadedScene out = start_load(path, SceneFormat::kCompressedPly, SceneFrame::kRdf, n);
  const std::size_t cstride = chunk->stride(), vstride = vertex->stride();
  const std::uint64_t step = std::max<std::uint64_t>(1, n / 50);
  const auto unorm = [](std::uint32_t v, int bits) { return float(v & ((1u << bits) - 1u)) / float((1u << bits) - 1u); };
  const auto u32 = [](const std::uint8_t* p) { std::uint32_t v; std::memcpy(&v, p, 4); return v; };
  for (std::uint64_t i = 0; i < n; ++i) {
    const std::uint8_t* c = bytes.data() + chunk_offset + (i / 256) * cstride;
    float cv[12];
    for (int k = 0; k < 12; ++k) cv[k] = read_as_float(c + cp[k]->offset, cp[k]->type);
    float color_min[3] = {0, 0, 0}, color_max[3] = {1, 1, 1};
    if (has_color)
      for (int k = 0; k < 3; ++k) {
        color_min[k] = read_as_float(c + colp[k]->offset, colp[k]->type);
        color_max[k] = read_as_float(c + colp[3 + k]->offset, colp[3 + k]->type);
      }
    const std::uint8_t* v = bytes.data() + vertex_offset + i * vstride;
    const std::uint32_t pp = u32(v + vp[0]->offset), pr = u32(v + vp[1]->offset),
                        ps = u32(v + vp[2]->offset), pc = u32(v + vp[3]->offset);
    const float t_pos[3] = {unorm(pp >> 21, 11), unorm(pp >> 11, 10), unorm(pp, 11)};
    const float t_scl[3] = {unorm(ps >> 21, 11), unorm(ps >> 11, 10), unorm(ps, 11)};
    float pos[3], scale[3];
    for (int k = 0; k < 3; ++k) {
      pos[k] = cv[k] + t_pos[k] * (cv[3 + k] - cv[k]);
      scale[k] = std::exp(cv[6 + k] + t_scl[k] * (cv[9 + k] - cv[6 + k]));
    }
    // Largest-of-four quaternion in the file's (w, x, y, z) order.
    constexpr float kNorm = 1.41421356f;  // 1 / (sqrt(2) / 2)
    const float a = (unorm(pr >> 20, 10) - 0.5f) * kNorm, b = (unorm(pr >> 10, 10) - 0.5f) * kNorm,
                d = (unorm(pr, 10) - 0.5f) * kNorm;
    const float m = std::sqrt(std::max(0.f, 1.f - (a * a + b * b + d * d)));
    float q[4];
    switch (pr >> 30) {
      case 0: q[0] = m; q[1] = a; q[2] = b; q[3] = d; break;
      case 1: q[0] = a; q[1] = m; q[2] = b; q[3] = d; break;
      case 2: q[0] = a; q[1] = b; q[2] = m; q[3] = d; break;
      default: q[0] = a; q[1] = b; q[2] = d; q[3] = m; break;
    }
    const float opacity = float(pc & 0xffu) / 255.f;
    const bool raw_finite = std::isfinite(cv[0] + cv[1] + cv[2] + cv[3] + cv[4] + cv[5]) &&
                            std::isfinite(cv[6] + cv[7] + cv[8] + cv[9] + cv[10] + cv[11]);
    if (accept_gaussian(pos, scale, q, opacity, std::uint32_t(i), out.scene, out.report, raw_finite) &&
        options.keep_color) {
      // Colour: 8-bit fractions lerped in the chunk's [min, max] of 0.5 + C0 * f_dc.
      Eigen::Vector3f f;
      for (int k = 0; k < 3; ++k) {
        const float t = float((pc >> (24 - 8 * k)) & 0xffu) / 255.f;
        const float lo = has_color ? color_min[k] : 0.f, hi = has_color ? color_max[k] : 1.f;
        f[k] = (lo + t * (hi - lo) - 0.5f) / kShC0;
      }
      out.scene.colors_dc.push_back(f);
    }
    if (progress && i % step == 0) progress(double(i) / double(n));
  }
  finish_load(out, path, n, progress);
  return out;
}

}  // namespace gshaptics
