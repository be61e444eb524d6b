#pragma once
/// @file
/// Loading trained 3DGS scenes from disk, with the format detected from the file's content.

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "gshaptics/io/gaussian_scene.h"

namespace gshaptics {

/// Scene file formats gshaptics reads (layouts in ../shared/data/scenes/SOURCES.md).
enum class SceneFormat {
  kInriaPly,            ///< INRIA 3DGS binary little-endian PLY (x y z ... opacity scale_* rot_*)
  kSplat,               ///< antimatter15 .splat, 32 bytes per Gaussian
  kCompressedPly,       ///< PlayCanvas compressed PLY (chunk + packed vertex elements)
  kAsciiPly,            ///< INRIA PLY, ASCII encoding
  kBigEndianPly,        ///< INRIA PLY, binary big-endian encoding
  kSpz,                 ///< Niantic SPZ (v4 "NGSP" header with zstd streams, or gzip-wrapped v2/v3)
  kUnknown,
};

[[nodiscard]] std::string_view to_string(SceneFormat format);

/// What a loader did with a file: how many Gaussians it found, kept and skipped, and why.
/// A skipped Gaussian is never dropped silently: it is counted in exactly one `skipped_*` field
/// (checked in this order: non-finite value, zero quaternion, non-positive scale).
struct LoadReport {
  std::string path;
  SceneFormat format = SceneFormat::kUnknown;
  SceneFrame frame = SceneFrame::kRdf;       ///< convention of the stored coordinates
  int version = 0;                           ///< format version where the format has one (SPZ)
  std::uint64_t in_file = 0;                 ///< Gaussians the file declares
  std::uint64_t loaded = 0;                  ///< Gaussians kept in the scene
  std::uint64_t skipped_non_finite = 0;      ///< any NaN/Inf in position, scale, rotation, opacity
  std::uint64_t skipped_zero_quaternion = 0; ///< rotation of (near-)zero norm
  std::uint64_t skipped_bad_scale = 0;       ///< linear scale <= 0 (log-scale of -inf)
  int sh_degree = 0;                         ///< spherical-harmonics degree found (read, not kept)
  std::vector<std::string> ignored_properties;  ///< properties present but unused (PLY)

  [[nodiscard]] std::uint64_t skipped() const {
    return skipped_non_finite + skipped_zero_quaternion + skipped_bad_scale;
  }
};

/// A scene as loaded, with its report.
struct LoadedScene {
  GaussianScene scene;
  LoadReport report;
};

/// Progress callback: fraction done in [0, 1]. May be empty.
using ProgressFn = std::function<void(double)>;

/// How to load: what to keep besides the geometry, and whom to tell about progress.
struct LoadOptions {
  /// Keep colour (f_dc) and higher SH bands, for conversion and rendering. Collision does not
  /// need them, and an SH3 scene's colour is ~3x its geometry, so the default leaves them out.
  bool keep_color = false;
  /// Called with the fraction done, in [0, 1], as the reader goes; may be empty. Runs on the
  /// loading thread.
  ProgressFn progress;
};

/// Guesses the format from the bytes (magic numbers, PLY header), falling back on the
/// extension of `path` only to choose between "looks like .splat" and "unknown".
[[nodiscard]] SceneFormat detect_scene_format(std::span<const std::uint8_t> bytes,
                                              std::string_view path);

/// Loads a scene file of any supported format.
/// Throws InputError naming the file and the problem for a missing, empty, truncated,
/// malformed or unsupported file. Never returns an empty scene without saying why: a file
/// whose every Gaussian is invalid is an error too.
[[nodiscard]] LoadedScene load_scene(const std::string& path, const LoadOptions& options = {});

/// Reads an INRIA 3DGS PLY from memory (`path` is used in messages only). See load_scene.
[[nodiscard]] LoadedScene read_inria_ply(std::span<const std::uint8_t> bytes,
                                         const std::string& path,
    const LoadOptions& options = {});

/// Reads a PlayCanvas compressed PLY from memory (chunks of 256 with min/max; 11-10-11 packed
/// positions and log-scales, 2+3x10-bit quaternions, RGBA with opacity). See load_scene.
[[nodiscard]] LoadedScene read_compressed_ply(std::span<const std::uint8_t> bytes,
                                              const std::string& path,
    const LoadOptions& options = {});

/// Reads a Niantic SPZ file from memory: v2/v3 (one gzip stream) or v4 ("NGSP" header, table of
/// contents, zstd streams). Coordinates stay in SPZ's RUB frame (report.frame). See load_scene.
[[nodiscard]] LoadedScene read_spz(std::span<const std::uint8_t> bytes, const std::string& path,
    const LoadOptions& options = {});

/// Reads an antimatter15 .splat from memory (`path` is used in messages only). See load_scene.
[[nodiscard]] LoadedScene read_splat(std::span<const std::uint8_t> bytes, const std::string& path,
    const LoadOptions& options = {});

/// An SPZ file in the form every SPZ reader knows (Niantic's v2/v3: one gzip stream), for
/// viewers that read only that one (Spark 2.2): a v4 file (NGSP header + zstd streams) is
/// re-packed as version 3 -- the same header fields and the same attribute bytes in the same
/// order, gzip-compressed -- so nothing is re-quantised. A v2/v3 file is returned as it is.
/// Throws InputError naming `path` for a file that is not valid SPZ.
[[nodiscard]] std::vector<std::uint8_t> spz_as_gzip(std::span<const std::uint8_t> bytes,
                                                   const std::string& path);

}  // namespace gshaptics
