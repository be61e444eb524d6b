#include "gshaptics/session/world_session.h"
#ifdef GSHAPTICS_HAVE_OBJECTS
#include "gshaptics/session/object_session.h"
#endif

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <optional>
#include <cstdlib>
#include <cstdio>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <functional>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "gshaptics/collision/world_cache.h"
#include "gshaptics/error.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/scene/scene_stats.h"

namespace gshaptics::session {

std::string world_cache_dir(const SceneOptions& o) {
  if (o.world_cache.empty() || o.world_cache == "off") return "";
  if (o.world_cache != "auto") return o.world_cache;
  const char* xdg = std::getenv("XDG_CACHE_HOME");
  const char* home = std::getenv("HOME");
  const std::string base = xdg != nullptr && *xdg ? std::string(xdg)
                           : home != nullptr && *home ? std::string(home) + "/.cache"
                                                      : std::string("/tmp");
  return base + "/gshaptics/worlds";
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
    std::size_t used = 0;
    try {
      t.scale = std::stod(o.reg_scale, &used);
    } catch (...) {
      used = 0;
    }
    if (used == 0 || used != o.reg_scale.size() || !std::isfinite(t.scale))
      throw InputError("--reg-scale: expected a finite number, got '" + o.reg_scale + "'");
    if (!(t.scale > 0)) throw InputError("--reg-scale: must be > 0, got '" + o.reg_scale + "'");
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
  cfg.min_opacity = o.min_opacity >= 0 ? o.min_opacity : kDefaultMinOpacity;
  cfg.sigma = o.sigma;
  cfg.up = parse_up_axis(o.up, "--up");
  cfg.registration = registration_from(o);
  return cfg;
}

Eigen::Vector3d for_print(const Eigen::Vector3d& v, int decimals) {
  const double f = std::pow(10.0, decimals);
  Eigen::Vector3d r;
  for (int k = 0; k < 3; ++k) r[k] = std::round(v[k] * f) / f + 0.0;  // -0.0 + 0.0 == +0.0
  return r;
}

std::string default_out_dir(const std::string& scene) {
  const std::filesystem::path p(scene);
  std::string ext = p.extension().string();
  if (!ext.empty()) ext = fmt::format("-{}", ext.substr(1));
  return fmt::format("runs/{}{}", p.stem().string(), ext);
}

std::string prepare_out_dir(const std::string& dir, const std::string& scene,
                            const std::vector<std::string>& owned, const std::string& option) {
  namespace fs = std::filesystem;
  const std::string out = dir.empty() ? default_out_dir(scene) : dir;
  std::error_code ec;
  if (fs::exists(out, ec) && !fs::is_directory(out, ec))
    throw InputError(option + " " + out + ": exists and is not a folder");
  // The folder, or the nearest existing one above it (where it will be created), is writable.
  fs::path probe = fs::absolute(out, ec);
  while (!probe.empty() && !fs::exists(probe, ec) && probe.has_parent_path() && probe.parent_path() != probe)
    probe = probe.parent_path();
  if (!fs::is_directory(probe, ec))
    throw InputError(option + " " + out + ": " + probe.string() + " is not a folder");
  if (::access(probe.c_str(), W_OK | X_OK) != 0)
    throw InputError(option + " " + out + ": " + (probe == fs::absolute(out, ec) ? std::string("the folder") : probe.string()) +
                     " is not writable");
  for (const std::string& name : owned) {
    const fs::path f = fs::path(out) / name;
    if (fs::is_directory(f, ec))
      throw InputError(option + " " + out + ": '" + name + "' is a folder where this run writes a file");
  }
  return out;
}

OutputStage::OutputStage(std::string final_dir, std::vector<std::string> owned)
    : final_(std::move(final_dir)), owned_(std::move(owned)) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::string pattern = (fs::temp_directory_path(ec) / "gshaptics-run-XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr)
    throw InputError("cannot create a temporary folder for the outputs (" + std::string(std::strerror(errno)) + ")");
  stage_ = pattern;
}

OutputStage::~OutputStage() {
  std::error_code ec;
  std::filesystem::remove_all(stage_, ec);
}

void OutputStage::commit() {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(final_, ec);
  if (ec) throw InputError(final_ + ": cannot create the output folder (" + ec.message() + ")");
  for (const std::string& name : owned_) {
    const fs::path from = fs::path(stage_) / name, to = fs::path(final_) / name;
    if (!fs::exists(from, ec)) {
      fs::remove(to, ec);  // this run did not write it: no stale file of another run stays
      continue;
    }
    fs::rename(from, to, ec);
    if (ec) {  // another file system: copy beside the target, then rename over it
      const fs::path tmp = fs::path(final_) / ("." + name + ".tmp");
      ec.clear();
      fs::copy_file(from, tmp, fs::copy_options::overwrite_existing, ec);
      if (!ec) fs::rename(tmp, to, ec);
      if (ec) {
        const std::string why = ec.message();
        fs::remove(tmp, ec);
        throw InputError(to.string() + ": cannot be written (" + why + ")");
      }
    }
  }
}

namespace {
// The warning for an --up that stands the scene on its head (turns_upside_down).
std::string upside_down_warning(UpAxis up, SceneFrame frame) {
  return fmt::format("--up {} points against the file's own up ({}), so the scene stands upside down and a probe "
                     "from above meets its underside; --up auto takes the file's convention",
                     to_string(up), to_string(frame));
}

std::vector<std::pair<std::string, std::string>> frame_items(const SceneOptions& o) {
  return {{"up", o.up},
          {"registration", o.registration_file},
          {"reg-scale", o.reg_scale},
          {"reg-rotation", o.reg_rotation},
          {"reg-translation", o.reg_translation}};
}
}  // namespace

std::string frame_comment(const SceneOptions& o) {
  std::string s = "# frame:";
  for (const auto& [k, v] : frame_items(o)) s += " " + k + "=" + v;
  return s;
}

std::vector<std::string> frame_mismatches(const std::string& line, const SceneOptions& o) {
  std::vector<std::string> out;
  if (line.rfind("# frame:", 0) != 0) return out;
  std::istringstream ss(line.substr(8));
  std::string item;
  std::vector<std::pair<std::string, std::string>> file;
  while (ss >> item) {
    const auto eq = item.find('=');
    if (eq != std::string::npos) file.emplace_back(item.substr(0, eq), item.substr(eq + 1));
  }
  for (const auto& [k, here] : frame_items(o))
    for (const auto& [fk, fv] : file)
      if (fk == k && fv != here)
        out.push_back("--" + k + ": poses made with '" + fv + "', this query has '" + here + "'");
  return out;
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

Eigen::Vector2d parse_vec2(const std::string& text, const std::string& option) {
  const auto v = parse_list(text, option, 2);
  return {v[0], v[1]};
}

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

namespace {

std::string v3(const Eigen::Vector3d& v) { return fmt::format("[{:.4f}, {:.4f}, {:.4f}]", v.x(), v.y(), v.z()); }

// The file: format, counts, load report, bounds, opacity and scale percentiles.
void print_scene_report(const LoadedScene& s) {
  const LoadReport& r = s.report;
  const SceneStats st = compute_scene_stats(s.scene);
  fmt::print("scene      {}\n", r.path);
  fmt::print("format     {}{}\n", to_string(r.format), r.version ? fmt::format(" (version {})", r.version) : "");
  fmt::print("frame      {}\n", to_string(r.frame));
  fmt::print("Gaussians  {} in file, {} loaded, {} skipped (non-finite {}, zero quaternion {}, "
             "bad scale {})\n",
             r.in_file, r.loaded, r.skipped(), r.skipped_non_finite, r.skipped_zero_quaternion,
             r.skipped_bad_scale);
  if (r.format == SceneFormat::kInriaPly) {
    fmt::print("SH degree  {}\n", r.sh_degree);
    if (!r.ignored_properties.empty())
      fmt::print("ignored    {}\n", fmt::join(r.ignored_properties, " "));
  }
  fmt::print("bounds     min {} max {} extent {}\n", v3(st.bbox_min), v3(st.bbox_max),
             v3(st.bbox_max - st.bbox_min));
  fmt::print("1-99 pct   {} .. {}\n", v3(st.p01), v3(st.p99));
  fmt::print("opacity    pct 1/10/25/50/75: {:.4f} / {:.4f} / {:.4f} / {:.4f} / {:.4f}\n",
             st.opacity_pct[0], st.opacity_pct[1], st.opacity_pct[2], st.opacity_pct[3],
             st.opacity_pct[4]);
  fmt::print("           fraction > 0.1 / 0.2 / 0.3: {:.4f} / {:.4f} / {:.4f}\n",
             st.opacity_above[0], st.opacity_above[1], st.opacity_above[2]);
  fmt::print("scale      all axes pct 1/50/99/99.9: {:.4g} / {:.4g} / {:.4g} / {:.4g}\n",
             st.scale_pct[0], st.scale_pct[1], st.scale_pct[2], st.scale_pct[3]);
  fmt::print("           largest axis pct 1/50/99/99.9: {:.4g} / {:.4g} / {:.4g} / {:.4g}\n",
             st.max_scale_pct[0], st.max_scale_pct[1], st.max_scale_pct[2], st.max_scale_pct[3]);
  fmt::print("           middle axis median, drawn Gaussians: {:.4g} (--surface seen reads its normal on a ring "
             "of at least 1.5 times this, scaled by the registration)\n", st.drawn_middle_scale);
}

// The opacity filter's lines: the world a run makes (the default force model's filter unless
// --min-opacity is given) and, when the filter is left to the model, what the 0.2 filter of
// --surface ellipsoids and --force-model paper keeps, with a warning when that is little.
void print_filter_lines(const GaussianScene& scene, std::size_t kept, float min_opacity, bool filter_left) {
  const double total = double(std::max<std::size_t>(1, scene.size()));
  fmt::print("filter     opacity > {:.2g} keeps {} of {} ({:.1f}%){}\n", min_opacity, kept, scene.size(),
             100.0 * double(kept) / total, filter_left ? ": the world of run, simulate and serve (the seen solid)" : "");
  // What a viewer draws (alpha >= 1/255), of it what is faint (opacity <= 0.2), and the rest.
  std::size_t drawn = 0, faint = 0, kept_paper = 0;
  for (float o : scene.opacities) {
    drawn += o > kSeenMinOpacity ? 1 : 0;
    faint += o > kSeenMinOpacity && o <= kDefaultMinOpacity ? 1 : 0;
    kept_paper += o > kDefaultMinOpacity ? 1 : 0;
  }
  double share = double(kept) / total;
  if (filter_left) {
    share = double(kept_paper) / total;
    fmt::print("           opacity > {:.2g} keeps {} ({:.1f}%): the world of --surface ellipsoids and --force-model paper\n",
               kDefaultMinOpacity, kept_paper, 100.0 * share);
  }
  fmt::print("faint      {} of {} Gaussians a viewer draws ({:.1f}%) have opacity <= {:.1f}: layers of them "
             "composite to surfaces the ellipsoids miss; the seen solid (the default) keeps and composites all {}\n",
             faint, drawn, 100.0 * double(faint) / double(std::max<std::size_t>(1, drawn)), kDefaultMinOpacity, drawn);
  if (share < 0.5)
    fmt::print("warning    the {}filter keeps only {:.0f}%: thin or semi-transparent parts may not be "
               "touchable with --surface ellipsoids or --force-model paper; a lower --min-opacity (0.1) keeps more, "
               "and the seen solid (the default) keeps every Gaussian a viewer draws\n",
               filter_left ? "0.2 " : "", 100 * share);
}

// The world the options make of it (filter, --up, registration) and the suggested options. With
// the filter left to the model, the world is the default force model's (the seen solid keeps every
// Gaussian a viewer draws), so the suggestions are those a default run would make.
void print_world_preview(const LoadedScene& s, const SceneOptions& so) {
  const bool filter_left = so.min_opacity < 0;
  WorldConfig cfg = world_config_from(so);
  if (filter_left) cfg.min_opacity = default_min_opacity(RendererSpec{});
  const SimilarityTransform to_world = with_up_axis(cfg.registration, cfg.up, s.scene.frame);
  const Eigen::Vector3d up = world_up(cfg.registration, cfg.up, s.scene.frame);
  const WorldPreview w = preview_world(s.scene, cfg.min_opacity, to_world, up);
  print_filter_lines(s.scene, w.kept, cfg.min_opacity, filter_left);
  if (w.kept == 0) return;
  const bool transformed = cfg.up != UpAxis::kNone || !cfg.registration.is_identity();
  fmt::print("\nworld      {} (kept Gaussians' centres, world frame)\n",
             transformed ? fmt::format("after --up {}{}", to_string(cfg.up),
                                       cfg.registration.is_identity() ? "" : " and the registration")
                         : std::string("= the file's own axes (no --up, no registration)"));
  const Eigen::Vector3d upp = for_print(up);
  fmt::print("up         [{:.2f}, {:.2f}, {:.2f}]{}\n", upp.x(), upp.y(), upp.z(),
             cfg.up == UpAxis::kNone ? fmt::format(" (the file's convention, {})", to_string(s.scene.frame))
                                     : std::string());
  fmt::print("bounds     min {} max {}\n", v3(w.bbox_min), v3(w.bbox_max));
  fmt::print("1-99 pct   {} .. {}, size {:.4g} units{}\n", v3(w.p01), v3(w.p99), w.robust_size,
             cfg.registration.is_identity() ? fmt::format(" (if the units are metres: {:.2f} m)", w.robust_size)
                                            : std::string(" (metres, if the registration is metric)"));
  if (rotates_twice(cfg.registration, cfg.up))
    fmt::print("warning    --up {} and the registration's rotation both turn the scene; a registration "
               "that already turns it upright wants --up none\n", to_string(cfg.up));
  if (turns_upside_down(cfg.up, s.scene.frame)) fmt::print("warning    {}\n", upside_down_warning(cfg.up, s.scene.frame));
  fmt::print("\nsuggest\n");
  if (cfg.up == UpAxis::kNone && cfg.registration.is_identity())
    fmt::print("  --up auto            the file's convention ({}) turned to +z, so a probe comes from above\n",
               s.scene.frame == SceneFrame::kRub ? "SPZ: y up" : "PLY/.splat: y down");
  const ScaleAdvice desk = desktop_scale_advice(w.robust_size);
  const ScaleAdvice room = room_scale_advice(w.robust_size);
  const double s0 = cfg.registration.scale;
  fmt::print("  desktop device       --reg-scale {:.4g} --tool-radius {:.4g} --device-profile desktop: {}\n",
             s0 * desk.reg_scale, desk.tool_radius, desk.reason);
  fmt::print("  room scale           --reg-scale {:.4g} --tool-radius {:.4g}: {}\n", s0 * room.reg_scale,
             room.tool_radius, room.reason);
}

}  // namespace

void run_info_command(const SceneOptions& so, bool quiet) {
  const LoadedScene s = load_with_progress(so.scene, quiet);
  print_scene_report(s);
  print_world_preview(s, so);
}

SceneOptions with_bundled_defaults(SceneOptions so, const std::string& command, const RendererSpec& renderer) {
  if (so.min_opacity < 0) so.min_opacity = default_min_opacity(renderer);
  if (so.scene.empty()) {
    so.scene = bundled_scene();
    if (so.scene.empty()) throw InputError(command + ": bundled scene data/truck.splat not found; give SCENE");
    if (so.registration_file.empty()) so.registration_file = bundled_registration();
  }
  return so;
}

bool is_scaled(const SceneOptions& so) {
  return !so.registration_file.empty() || !so.reg_rotation.empty() || !so.reg_scale.empty() ||
         !so.reg_translation.empty();
}

PreparedWorld prepare_world(const SceneOptions& so, bool quiet, std::FILE* report) {
  const WorldConfig cfg = world_config_from(so);
  const std::string cache_dir = so.objects.empty() ? world_cache_dir(so) : std::string();
  if (!so.objects.empty() && !world_cache_dir(so).empty())
    fmt::print(stderr, "note: --world-cache is not used with --object (the static part is cut each time)\n");
  WorldCacheKey key;
  std::string cache_file;
  if (!cache_dir.empty()) {
    const auto t0 = std::chrono::steady_clock::now();
    key = world_cache_key(so.scene, cfg);
    cache_file = world_cache_file(cache_dir, so.scene, key);
    std::string why;
    std::optional<CachedWorld> hit = open_world_cache(cache_file, key, &why);
    const double ms = 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (hit) {
      LoadedScene s;
      s.report = hit->source;
      s.report.path = so.scene;
      WorldBuildReport br;
      br.filter = {cfg.min_opacity, std::size_t(s.report.loaded), hit->world.size()};
      br.memory_bytes = hit->world.memory_bytes();
      const Eigen::Vector3d up = hit->world.up();
      fmt::print(report, "scene      {} ({}, {} Gaussians, {} skipped)\n", so.scene, to_string(s.report.format),
                 s.report.loaded, s.report.skipped());
      fmt::print(report, "world      {} Gaussians from the world cache {} (hashed and mapped in {:.0f} ms), up [{:.2f}, "
                 "{:.2f}, {:.2f}]\n", hit->world.size(), cache_file, ms, up.x(), up.y(), up.z());
      return {std::move(s), cfg, br, std::move(hit->world), {}, {}};
    }
    if (why != "no cache file") fmt::print(stderr, "warning: world cache {}: {}; rebuilding\n", cache_file, why);
  }
  LoadedScene s = load_with_progress(so.scene, quiet);
  WorldBuildReport br;
  std::vector<GaussianScene> objects;
  if (!so.objects.empty()) {  // the objects leave the static world (scene/scene_cut.h)
    SceneCut cut = cut_objects(s.scene, with_up_axis(cfg.registration, cfg.up, s.scene.frame), so.objects,
                               cfg.min_opacity);
    load_file_objects(cut, so.objects, cfg.up, cfg.min_opacity);
    for (std::size_t i = 0; i < cut.objects.size(); ++i)
      fmt::print(report, "object     {}: {} Gaussians {} ({})\n", i, cut.objects[i].size(),
                 so.objects[i].cut == ObjectSpec::Cut::kFile ? "from " + so.objects[i].file : std::string("cut from the scene"),
                 so.objects[i].text);
    s.scene = std::move(cut.rest);
    objects = std::move(cut.objects);
  }
  std::vector<GaussianScene> supports;
  if (!so.supports.empty()) {  // copies of static parts, for MuJoCo
    if (so.objects.empty()) throw InputError("--support: give the objects that stand on it (--object)");
    supports = select_supports(s.scene, with_up_axis(cfg.registration, cfg.up, s.scene.frame), so.supports, cfg.min_opacity);
    for (std::size_t i = 0; i < supports.size(); ++i)
      fmt::print(report, "support    {}: {} Gaussians of the scene ({})\n", i, supports[i].size(), so.supports[i].text);
  }
  // The Gaussians are not needed after the build (a cached world has none either): consuming
  // them lowers the peak memory of a large scene's build.
  CollisionWorld world = CollisionWorld::build(std::move(s.scene), cfg, &br);
  if (!cache_file.empty()) {
    try {
      std::error_code ec;
      std::filesystem::create_directories(cache_dir, ec);
      write_world_cache(world, key, cache_file, s.report);
      fmt::print(report, "cache      world written to {}\n", cache_file);
    } catch (const InputError& e) {
      fmt::print(stderr, "warning: {} (the world is rebuilt each time)\n", e.what());
    }
  }
  fmt::print(report, "scene      {} ({}, {} Gaussians, {} skipped)\n", so.scene, to_string(s.report.format),
             s.report.loaded, s.report.skipped());
  fmt::print(report, "filter     opacity > {:.2g}: kept {} ({:.1f}%)\n", cfg.min_opacity, br.filter.after,
             100 * br.filter.kept_fraction());
  const Eigen::Vector3d up = for_print(world.up());
  fmt::print(report, "world      {} Gaussians, BVH built in {:.0f} ms, {:.1f} MB, up [{:.2f}, {:.2f}, {:.2f}]{}\n",
             world.size(), br.build_seconds * 1e3, double(br.memory_bytes) / 1e6, up.x(), up.y(),
             up.z(), so.registration_file.empty() ? "" : ", registration " + so.registration_file);
  if (rotates_twice(cfg.registration, cfg.up))
    fmt::print(stderr,
               "warning: --up {} and the registration's rotation both turn the scene, so the world's "
               "up ends at [{:.2f}, {:.2f}, {:.2f}]. A registration that already turns the scene "
               "upright (like the bundled Truck's) wants --up none.\n",
               to_string(cfg.up), up.x(), up.y(), up.z());
  if (turns_upside_down(cfg.up, s.scene.frame))
    fmt::print(stderr, "warning: {}\n", upside_down_warning(cfg.up, s.scene.frame));
  return {std::move(s), cfg, br, std::move(world), std::move(objects), std::move(supports)};
}

nlohmann::json objects_json(const SceneOptions& so, const PreparedWorld& pw, const SceneObjects* objects) {
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t i = 0; i < so.objects.size(); ++i) {
    list.push_back({{"spec", so.objects[i].text},
                    {"mass_kg", so.objects[i].mass},
                    {"friction", so.objects[i].friction},
                    {"gaussians_cut", i < pw.objects.size() ? pw.objects[i].size() : 0}});
    if (objects != nullptr && i < objects->untouched_moved.size()) {
      list.back()["untouched_moved_m"] = objects->untouched_moved[i];
      list.back()["untouched_turned_rad"] = objects->untouched_turned[i];
    }
  }
  return list;
}

SceneObjects scene_objects(const PreparedWorld& pw, const SceneOptions& so, double rate_hz, std::FILE* report) {
  if (pw.objects.empty()) return {};
#ifdef GSHAPTICS_HAVE_OBJECTS
  return object_scene(pw, so, rate_hz, report);
#else
  (void)so;
  (void)rate_hz;
  (void)report;
  throw InputError("--object: this build has no rigid objects (libmujoco-dev was missing when it was built)");
#endif
}

std::shared_ptr<const MaterialMap> with_scene_colours(std::shared_ptr<const MaterialMap> map,
                                                      const std::string& scene_path, std::FILE* report) {
  if (!map || !map->needs_colours()) return map;
  LoadOptions lo;
  lo.keep_color = true;
  const LoadedScene s = load_scene(scene_path, lo);
  std::vector<std::size_t> selected;
  auto out = std::make_shared<const MaterialMap>(resolve_colour_regions(*map, s.scene, &selected));
  for (std::size_t r = 0; r < out->regions.size(); ++r) {
    const MaterialRegion& region = out->regions[r];
    if (!region.colour) continue;
    const Eigen::Vector3d& c = region.colour->rgb;
    fmt::print(report, "materials  regions[{}] ({}): colour [{:.2f}, {:.2f}, {:.2f}] {} selects {} of {} Gaussians\n", r,
               out->materials[region.material].name, c.x(), c.y(), c.z(),
               region.colour->clusters > 0 ? fmt::format("(nearest of {} k-means clusters)", region.colour->clusters)
                                           : fmt::format("(within {:.2f})", region.colour->tolerance),
               selected[r], s.scene.size());
  }
  return out;
}

}  // namespace gshaptics::session
