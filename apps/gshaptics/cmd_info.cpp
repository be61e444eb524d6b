// `gshaptics info SCENE`: what a scene file holds and what the opacity filter would keep.

#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "common.h"
#include "gshaptics/scene/scene_stats.h"

namespace gshaptics::cli {

namespace {
int g_exit_code = 0;
}
int exit_code() { return g_exit_code; }
void set_exit_code(int code) { g_exit_code = code; }

void register_info(CLI::App& app) {
  auto opts = std::make_shared<SceneOptions>();
  CLI::App* cmd = app.add_subcommand(
      "info", "Print a scene's format, counts, load report, bounds, opacity and scale percentiles "
              "and the opacity filter's reduction");
  cmd->add_option("scene", opts->scene, "Scene file (.ply or .splat)")->required();
  cmd->add_option("--min-opacity", opts->min_opacity, "Filter threshold to report")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  cmd->callback([opts] {
    const LoadedScene s = load_with_progress(opts->scene);
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
    std::size_t kept = 0;
    for (float a : s.scene.opacities) kept += a > opts->min_opacity ? 1 : 0;
    fmt::print("filter     opacity > {:.2f} keeps {} of {} ({:.1f}%)\n", opts->min_opacity, kept,
               s.scene.size(), 100.0 * double(kept) / double(s.scene.size()));
  });
}

}  // namespace gshaptics::cli
