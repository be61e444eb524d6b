// `gshaptics info SCENE`: what a scene file holds and what the opacity filter would keep.

#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/scene/scene_stats.h"

namespace gshaptics::cli {

namespace {
int g_exit_code = 0;
}
std::vector<std::string>& ros_arguments() {
  static std::vector<std::string> args;
  return args;
}
int exit_code() { return g_exit_code; }
void set_exit_code(int code) { g_exit_code = code; }

void register_info(CLI::App& app) {
  auto opts = std::make_shared<SceneOptions>();
  auto quiet = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "info", "Print a scene's format, counts, load report, bounds, opacity and scale percentiles "
              "and the opacity filter's reduction; then preview the world that --up and a "
              "registration make of it (bounds, size, up axis) and suggest --up, --reg-scale and "
              "a tool radius for a desktop device and for room scale");
  cmd->add_option("scene", opts->scene, "Scene file (.ply, .compressed.ply, .splat or .spz)")->required();
  add_world_options(*cmd, *opts);
  cmd->add_flag("--quiet", *quiet, "No progress bar");
  cmd->callback([opts, quiet] {
    const LoadedScene s = load_with_progress(opts->scene, *quiet);
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
    const auto v3 = [](const Eigen::Vector3d& v) { return fmt::format("[{:.4f}, {:.4f}, {:.4f}]", v.x(), v.y(), v.z()); };
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
    const WorldConfig cfg = world_config_from(*opts);
    const SimilarityTransform to_world = with_up_axis(cfg.registration, cfg.up, s.scene.frame);
    const Eigen::Vector3d up = world_up(cfg.registration, cfg.up, s.scene.frame);
    const WorldPreview w = preview_world(s.scene, cfg.min_opacity, to_world, up);
    const double kept_share = double(w.kept) / double(std::max<std::size_t>(1, s.scene.size()));
    fmt::print("filter     opacity > {:.2f} keeps {} of {} ({:.1f}%)\n", cfg.min_opacity, w.kept,
               s.scene.size(), 100.0 * kept_share);
    if (kept_share < 0.5)
      fmt::print("warning    the filter keeps only {:.0f}%: thin or semi-transparent parts may not be "
                 "touchable; a lower --min-opacity (0.1) keeps more\n", 100 * kept_share);
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
  });
}

}  // namespace gshaptics::cli
