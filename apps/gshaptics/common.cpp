#include "common.h"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <sstream>

#include "gshaptics/error.h"

namespace gshaptics::cli {

void add_world_options(CLI::App& app, SceneOptions& o) {
  app.add_option("--min-opacity", o.min_opacity,
                 "Keep Gaussians with opacity > T (paper Sec. III-A: 0.1..0.3)")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  app.add_option("--sigma", o.sigma, "Collision ellipsoid at K sigma (semi-axes K * scale)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--registration", o.registration_file,
                 "JSON similarity transform scene->world: {\"scale\": s, \"rotation\": [w,x,y,z] "
                 "or \"matrix\": 3x3, \"translation\": [x,y,z]} (paper eq. 3)");
  app.add_option("--reg-scale", o.reg_scale, "Registration scale s (overrides the file)");
  app.add_option("--reg-rotation", o.reg_rotation, "Registration rotation W,X,Y,Z (overrides)");
  app.add_option("--reg-translation", o.reg_translation, "Registration translation X,Y,Z (overrides)");
  app.add_option("--up", o.up,
                 "Turn the scene's up axis to world +z before the registration: none, auto (from "
                 "the file's convention: -y for PLY/.splat, +y for SPZ), y-down, y-up, z-up, "
                 "z-down, x-up, x-down")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "auto", "y-down", "y-up", "z-up", "z-down", "x-up", "x-down"}));
}

std::string data_file(const std::string& name) {
  for (const std::string& dir : {std::string(GSHAPTICS_SOURCE_DIR) + "/data",
                                std::string(GSHAPTICS_INSTALL_DATADIR)}) {
    const std::string p = dir + "/" + name;
    if (std::filesystem::exists(p)) return p;
  }
  return "";
}

std::string bundled_scene() { return data_file("truck.splat"); }
std::string bundled_registration() { return data_file("truck.registration.json"); }

SimilarityTransform registration_from(const SceneOptions& o) {
  SimilarityTransform t;
  if (!o.registration_file.empty()) t = load_registration_file(o.registration_file);
  if (!o.reg_scale.empty()) {
    try {
      t.scale = std::stod(o.reg_scale);
    } catch (...) {
      throw InputError("--reg-scale: expected a number, got '" + o.reg_scale + "'");
    }
    if (!(t.scale > 0)) throw InputError("--reg-scale: must be > 0");
  }
  if (!o.reg_rotation.empty()) {
    const Eigen::Vector4d q = parse_vec4(o.reg_rotation, "--reg-rotation");
    if (q.norm() < 1e-9) throw InputError("--reg-rotation: zero quaternion");
    t.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
  }
  if (!o.reg_translation.empty()) t.translation = parse_vec3(o.reg_translation, "--reg-translation");
  return t;
}

WorldConfig world_config_from(const SceneOptions& o) {
  WorldConfig cfg;
  cfg.min_opacity = o.min_opacity;
  cfg.sigma = o.sigma;
  cfg.up = parse_up_axis(o.up, "--up");
  cfg.registration = registration_from(o);
  return cfg;
}

LoadedScene load_with_progress(const std::string& path, bool quiet, bool keep_color) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  Progress bar("loading " + std::filesystem::path(path).filename().string(),
               !quiet && !ec && size > (8u << 20));
  LoadOptions options;
  options.keep_color = keep_color;
  options.progress = [&](double f) { bar(f); };
  LoadedScene s = load_scene(path, options);
  bar.done();
  return s;
}

namespace {
std::vector<double> parse_list(const std::string& text, const std::string& option, std::size_t n) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size() && item.find_first_not_of(" \t", used) != std::string::npos) throw 0;
    } catch (...) {
      throw InputError(option + ": '" + item + "' is not a number (expected " + std::to_string(n) +
                       " comma-separated numbers)");
    }
  }
  if (v.size() != n)
    throw InputError(option + ": expected " + std::to_string(n) + " comma-separated numbers, got '" +
                     text + "'");
  for (double x : v)
    if (!std::isfinite(x)) throw InputError(option + ": values must be finite");
  return v;
}
}  // namespace

Eigen::Vector3d parse_vec3(const std::string& text, const std::string& option) {
  const auto v = parse_list(text, option, 3);
  return {v[0], v[1], v[2]};
}

Eigen::Vector4d parse_vec4(const std::string& text, const std::string& option) {
  const auto v = parse_list(text, option, 4);
  return {v[0], v[1], v[2], v[3]};
}

Progress::Progress(std::string label, bool enabled) : label_(std::move(label)), enabled_(enabled) {}

void Progress::operator()(double fraction) {
  if (!enabled_) return;
  const int pct = int(fraction * 100);
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  // On a terminal redraw every percent; in a log (CI) print every 25% only.
  if (pct == last_ || (!tty && pct / 25 == last_ / 25 && last_ >= 0)) return;
  last_ = pct;
  const int filled = pct / 5;
  std::fprintf(stderr, "%s%s [%.*s%*s] %3d%%%s", tty ? "\r" : "", label_.c_str(), filled,
               "####################", 20 - filled, "", pct, tty ? "" : "\n");
  std::fflush(stderr);
}

void Progress::done() {
  if (!enabled_ || last_ < 0) return;
  if (::isatty(STDERR_FILENO) != 0) std::fprintf(stderr, "\n");
  last_ = -1;
}

}  // namespace gshaptics::cli
