// antimatter15 .splat reader: 32 bytes per Gaussian, position 3 x f32, linear scale 3 x f32,
// RGBA u8 (alpha/255 is opacity after the sigmoid), quaternion 4 x u8 as (b - 128) / 128 in
// w, x, y, z order (SOURCES.md, "Conventions").

#include <cstring>
#include <limits>

#include "detail/accept_gaussian.h"
#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics {

LoadedScene read_splat(std::span<const std::uint8_t> bytes, const std::string& path,
    const LoadOptions& options) {
  const ProgressFn& progress = options.progress;
  constexpr std::size_t kRecord = 32;
  if (bytes.empty()) throw file_error(path, "file is empty");
  if (bytes.size() % kRecord != 0)
    throw file_error(path, "size " + std::to_string(bytes.size()) +
                               " is not a multiple of the 32-byte .splat record (truncated or "
                               "not a .splat file; " +
                               std::to_string(bytes.size() % kRecord) + " trailing bytes)");
  const std::uint64_t n = bytes.size() / kRecord;
  if (n > std::numeric_limits<std::uint32_t>::max())
    throw file_error(path, "more than 2^32 Gaussians are not supported");

  LoadedScene out = detail::start_load(path, SceneFormat::kSplat, SceneFrame::kRdf, n);
  const std::uint64_t step = std::max<std::uint64_t>(1, n / 50);
  for (std::uint64_t i = 0; i < n; ++i) {
    const std::uint8_t* rec = bytes.data() + i * kRecord;
    float pos[3], scale[3];
    std::memcpy(pos, rec, 12);
    std::memcpy(scale, rec + 12, 12);
    const float opacity = float(rec[27]) / 255.f;
    const float quat[4] = {(float(rec[28]) - 128.f) / 128.f, (float(rec[29]) - 128.f) / 128.f,
                           (float(rec[30]) - 128.f) / 128.f, (float(rec[31]) - 128.f) / 128.f};
    if (detail::accept_gaussian(pos, scale, quat, opacity, std::uint32_t(i), out.scene, out.report) &&
        options.keep_color)
      out.scene.colors_dc.emplace_back((float(rec[24]) / 255.f - 0.5f) / detail::kShC0,
                                       (float(rec[25]) / 255.f - 0.5f) / detail::kShC0,
                                       (float(rec[26]) / 255.f - 0.5f) / detail::kShC0);
    if (progress && i % step == 0) progress(double(i) / double(n));
  }
  detail::finish_load(out, path, n, progress);
  return out;
}

}  // namespace gshaptics
