#include "gshaptics/io/scene_writer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "gshaptics/error.h"
#include "gshaptics/io/atomic_file.h"

namespace gshaptics {

namespace {

constexpr float kShC0 = 0.28209479177387814f;

template <typename T>
void put(std::vector<char>& out, T v) {
  const char* p = reinterpret_cast<const char*>(&v);
  out.insert(out.end(), p, p + sizeof(T));
}

float logit(float a) {
  if (!(a > 0.f)) return -40.f;
  if (!(a < 1.f)) return 40.f;
  return float(std::log(double(a) / (1.0 - double(a))));
}

}  // namespace

void write_inria_ply(const std::string& path, const GaussianScene& s, const std::vector<std::string>& comments) {
  const bool color = s.colors_dc.size() == s.size();
  const int rest = color ? s.sh_rest_count : 0;
  std::string h = "ply\nformat binary_little_endian 1.0\ncomment written by gshaptics\n";
  for (std::string c : comments) {
    std::replace(c.begin(), c.end(), '\n', ' ');
    std::replace(c.begin(), c.end(), '\r', ' ');
    h += "comment " + c + "\n";
  }
  h += "element vertex " + std::to_string(s.size()) + "\n";
  for (const char* p : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"})
    h += std::string("property float ") + p + "\n";
  for (int k = 0; k < rest; ++k) h += "property float f_rest_" + std::to_string(k) + "\n";
  for (const char* p : {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    h += std::string("property float ") + p + "\n";
  h += "end_header\n";
  std::vector<char> body;
  body.reserve(s.size() * std::size_t(4 * (17 + rest)));
  for (std::size_t i = 0; i < s.size(); ++i) {
    for (int k = 0; k < 3; ++k) put(body, s.means[i][k]);
    for (int k = 0; k < 3; ++k) put(body, 0.f);
    for (int k = 0; k < 3; ++k) put(body, color ? s.colors_dc[i][k] : 0.f);
    for (int k = 0; k < rest; ++k) put(body, s.sh_rest[i * std::size_t(rest) + std::size_t(k)]);
    put(body, logit(s.opacities[i]));
    for (int k = 0; k < 3; ++k) put(body, std::log(s.scales[i][k]));
    for (int k = 0; k < 4; ++k) put(body, s.rotations[i][k]);
  }
  write_file_atomically(path, {h, std::string_view(body.data(), body.size())});
}

std::string splat_bytes(const GaussianScene& s) {
  const bool color = s.colors_dc.size() == s.size();
  std::vector<char> body;
  body.reserve(s.size() * 32);
  const auto byte = [](float v) { return std::uint8_t(std::lround(std::clamp(v, 0.f, 255.f))); };
  for (std::size_t i = 0; i < s.size(); ++i) {
    for (int k = 0; k < 3; ++k) put(body, s.means[i][k]);
    for (int k = 0; k < 3; ++k) put(body, s.scales[i][k]);
    for (int k = 0; k < 3; ++k) put(body, byte(((color ? s.colors_dc[i][k] : 0.f) * kShC0 + 0.5f) * 255.f));
    put(body, byte(s.opacities[i] * 255.f));
    for (int k = 0; k < 4; ++k) put(body, byte(s.rotations[i][k] * 128.f + 128.f));
  }
  return std::string(body.data(), body.size());
}

void write_splat(const std::string& path, const GaussianScene& s) { write_file_atomically(path, splat_bytes(s)); }

SceneFrame output_frame(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".ply" || ext == ".splat") return SceneFrame::kRdf;
  if (ext == ".spz")
    throw file_error(path, "writing SPZ is not supported: no SPZ encoder is packaged in Debian; "
                           "write .ply or .splat");
  throw file_error(path, "unknown output extension '" + ext + "' (expected .ply or .splat)");
}

void write_scene(const std::string& path, const GaussianScene& scene) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".ply") return write_inria_ply(path, scene);
  if (ext == ".splat") return write_splat(path, scene);
  if (ext == ".spz")
    throw file_error(path, "writing SPZ is not supported: no SPZ encoder is packaged in Debian; "
                           "write .ply or .splat");
  throw file_error(path, "unknown output extension '" + ext + "' (expected .ply or .splat)");
}

}  // namespace gshaptics
