#include "gshaptics/io/scene_loader.h"

#include <cmath>
#include <cstring>

#include "gshaptics/error.h"
#include "gshaptics/io/mapped_file.h"

namespace gshaptics {

SceneFormat detect_ply_variant(std::span<const std::uint8_t> bytes);  // ply_reader.cpp

std::string_view to_string(SceneFormat format) {
  switch (format) {
    case SceneFormat::kInriaPly: return "INRIA 3DGS PLY (binary little-endian)";
    case SceneFormat::kSplat: return "antimatter15 .splat";
    case SceneFormat::kCompressedPly: return "PlayCanvas compressed PLY";
    case SceneFormat::kAsciiPly: return "INRIA 3DGS PLY (ASCII)";
    case SceneFormat::kBigEndianPly: return "INRIA 3DGS PLY (binary big-endian)";
    case SceneFormat::kSpz: return "Niantic SPZ";
    case SceneFormat::kUnknown: return "unknown";
  }
  return "unknown";
}

namespace {

bool ends_with(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

// A .splat file has no magic: judge the first records. Real files have quaternion bytes whose
// decoded norm is within a few percent of 1 and finite, non-negative scales.
bool looks_like_splat(std::span<const std::uint8_t> bytes) {
  if (bytes.empty() || bytes.size() % 32 != 0) return false;
  const std::size_t n = std::min<std::size_t>(bytes.size() / 32, 64);
  std::size_t plausible = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* rec = bytes.data() + i * 32;
    float v[6];
    std::memcpy(v, rec, sizeof v);
    bool ok = true;
    for (float f : v) ok = ok && std::isfinite(f) && std::fabs(f) < 1e7f;
    for (int k = 3; k < 6; ++k) ok = ok && v[k] >= 0.f;
    double q2 = 0;
    for (int k = 28; k < 32; ++k) q2 += (rec[k] - 128.0) * (rec[k] - 128.0) / (128.0 * 128.0);
    ok = ok && q2 > 0.8 && q2 < 1.2;
    plausible += ok ? 1 : 0;
  }
  return plausible * 10 >= n * 9;
}

}  // namespace

SceneFormat detect_scene_format(std::span<const std::uint8_t> bytes, std::string_view path) {
  if (bytes.size() >= 4 && std::memcmp(bytes.data(), "ply", 3) == 0 &&
      (bytes[3] == '\n' || bytes[3] == '\r'))
    return detect_ply_variant(bytes);
  if (bytes.size() >= 4 && std::memcmp(bytes.data(), "NGSP", 4) == 0) return SceneFormat::kSpz;
  if (bytes.size() >= 2 && bytes[0] == 0x1f && bytes[1] == 0x8b) return SceneFormat::kSpz;  // gzip: SPZ v2/v3
  if (looks_like_splat(bytes)) return SceneFormat::kSplat;
  if (ends_with(path, ".splat") && !bytes.empty()) return SceneFormat::kSplat;  // reader says why
  return SceneFormat::kUnknown;
}

LoadedScene load_scene(const std::string& path, const LoadOptions& options) {
  const MappedFile file(path);
  const auto bytes = file.bytes();
  if (bytes.empty()) throw file_error(path, "file is empty");
  // Readers go through the file front to back and report progress as they go: drop the pages
  // they are done with (less a 16 MiB margin), so a 1 GB scene does not stay resident twice.
  LoadOptions reading = options;
  reading.progress = [&](double fraction) {
    if (options.progress) options.progress(fraction);
    const double done = fraction * double(bytes.size()) - double(16u << 20);
    if (done > 0 && fraction < 1.0) file.release_before(std::size_t(done));
  };
  switch (detect_scene_format(bytes, path)) {
    case SceneFormat::kInriaPly:
    case SceneFormat::kAsciiPly:
    case SceneFormat::kBigEndianPly:
      return read_inria_ply(bytes, path, reading);
    case SceneFormat::kCompressedPly:
      return read_compressed_ply(bytes, path, reading);
    case SceneFormat::kSplat:
      return read_splat(bytes, path, reading);
    case SceneFormat::kSpz:
      return read_spz(bytes, path, reading);
    case SceneFormat::kUnknown:
      break;
  }
  throw file_error(path,
                   "unrecognised scene format: not a PLY (no 'ply' header), not SPZ, and not a "
                   ".splat (size not a multiple of 32 bytes or implausible records)");
}

}  // namespace gshaptics
