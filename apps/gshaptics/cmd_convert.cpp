// `gshaptics convert IN OUT`: save a (filtered, registered) scene once, load it fast later.

#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "common.h"
#include "gshaptics/io/scene_writer.h"
#include "gshaptics/scene/opacity_filter.h"
#include "gshaptics/scene/registration.h"

namespace gshaptics::cli {

void register_convert(CLI::App& app) {
  auto o = std::make_shared<SceneOptions>();
  auto out = std::make_shared<std::string>();
  auto min_opacity = std::make_shared<float>(-1.f);
  CLI::App* cmd = app.add_subcommand(
      "convert",
      "Convert a scene (any format gshaptics reads) to INRIA PLY (.ply) or .splat, optionally "
      "dropping Gaussians with opacity <= T and applying --up / a registration. Colour and SH "
      "are kept where the output format has room (.splat keeps band 0 only). SPZ output is not "
      "supported (no SPZ encoder in Debian).");
  cmd->add_option("input", o->scene, "Scene file to read")->required();
  cmd->add_option("output", *out, "File to write (.ply or .splat), written atomically")->required();
  cmd->add_option("--min-opacity", *min_opacity, "Keep Gaussians with opacity > T (default: keep all)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--registration", o->registration_file, "JSON similarity transform to apply (eq. 3)");
  cmd->add_option("--up", o->up, "Turn the scene's up axis to +z first (none, auto, y-down, y-up, ...)")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "auto", "y-down", "y-up", "z-up", "z-down", "x-up", "x-down"}));
  cmd->callback([o, out, min_opacity] {
    const LoadedScene s = load_with_progress(o->scene, false, /*keep_color=*/true);
    GaussianScene scene = s.scene;
    if (*min_opacity >= 0.f) {
      OpacityFilterReport rep;
      scene = filter_by_opacity(scene, *min_opacity, &rep);
      fmt::print("filter     opacity > {:.2f}: kept {} of {}\n", *min_opacity, rep.after, rep.before);
    }
    const WorldConfig cfg = world_config_from(*o);
    const SimilarityTransform to_world = with_up_axis(cfg.registration, cfg.up, scene.frame);
    if (!to_world.is_identity()) {
      scene = transform_scene(scene, to_world);
      if (scene.sh_rest_count > 0 && !to_world.rotation.isApprox(Eigen::Quaterniond::Identity()))
        fmt::print(stderr, "warning: SH bands above 0 are not rotated with the scene\n");
    }
    write_scene(*out, scene);
    fmt::print("wrote      {} ({} Gaussians{})\n", *out, scene.size(),
               scene.colors_dc.empty() ? ", no colour" : "");
  });
}

}  // namespace gshaptics::cli
