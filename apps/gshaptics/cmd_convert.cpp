// `gshaptics convert IN OUT`: save a (filtered, registered) scene once, load it fast later.

#include <fmt/format.h>

#include <cctype>
#include <filesystem>
#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/io/scene_writer.h"
#include "gshaptics/session/query_session.h"
#include "gshaptics/scene/opacity_filter.h"
#include "gshaptics/scene/registration.h"

namespace gshaptics::cli {

namespace {
std::string to_lower_ext(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  for (char& ch : e) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  return e;
}
}  // namespace

void register_convert(CLI::App& app) {
  auto o = std::make_shared<SceneOptions>();
  auto out = std::make_shared<std::string>();
  auto min_opacity = std::make_shared<float>(-1.f);
  CLI::App* cmd = app.add_subcommand(
      "convert",
      "Convert a scene (any format gshaptics reads) to INRIA PLY (.ply) or .splat, optionally "
      "dropping Gaussians with opacity <= T and applying --up / a registration. Colour and SH "
      "are kept where the output format has room (.splat keeps band 0 only). SPZ output is not "
      "supported (no SPZ encoder in Debian). The output is written in its format's coordinate "
      "convention (RDF, y down, for .ply and .splat): converting an SPZ (RUB) turns it, so that "
      "source and output give the same world under --up auto. .splat is lossy: it keeps each "
      "rotation in 4 bytes and the opacity in 1 byte, which moves Gaussians' orientations by up to "
      "about a degree and changes the contacts of some tool poses; convert measures how many "
      "(200 poses) and warns. Use .ply to keep the scene exact.");
  cmd->add_option("input", o->scene, "Scene file to read")->required();
  cmd->add_option("output", *out, "File to write (.ply or .splat), written atomically")->required();
  cmd->add_option("--min-opacity", *min_opacity, "Keep Gaussians with opacity > T (default: keep all)")
      ->check(check::range(0.0, 1.0));
  cmd->add_option("--registration", o->registration_file, "JSON similarity transform to apply (eq. 3)");
  cmd->add_option("--up", o->up, "Turn the scene's up axis to +z first (none, auto, y-down, y-up, ...)")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "auto", "y-down", "y-up", "z-up", "z-down", "x-up", "x-down"}));
  auto quiet = std::make_shared<bool>(false);
  cmd->add_flag("--quiet", *quiet, "No progress bar");
  cmd->callback([o, out, min_opacity, quiet] {
    const SceneFrame to = output_frame(*out);  // checks the extension before the load
    const LoadedScene s = load_with_progress(o->scene, *quiet, /*keep_color=*/true);
    GaussianScene scene = s.scene;
    if (*min_opacity >= 0.f) {
      OpacityFilterReport rep;
      scene = filter_by_opacity(scene, *min_opacity, &rep);
      fmt::print("filter     opacity > {:.2f}: kept {} of {}\n", *min_opacity, rep.after, rep.before);
    }
    const WorldConfig cfg = world_config_from(*o);
    if (rotates_twice(cfg.registration, cfg.up))
      fmt::print(stderr, "warning: --up {} and the registration's rotation both turn the scene\n",
                 to_string(cfg.up));
    // The written file is in its format's own convention, so that it gives the same world under
    // --up auto as the source does under these options.
    const SimilarityTransform t = conversion_transform(cfg.registration, cfg.up, scene.frame, to);
    if (!t.is_identity()) scene = transform_scene(scene, t);
    scene.frame = to;
    write_scene(*out, scene);
    if (to_lower_ext(*out) == ".splat") {
      // Measure what the bytes cost: the contacts of seeded tool poses, source against output.
      const LoadedScene back = load_scene(*out);
      const CollisionWorld a = CollisionWorld::build(scene, WorldConfig{});
      const CollisionWorld b = CollisionWorld::build(back.scene, WorldConfig{});
      const session::ContactChange c = session::compare_contacts(a, b);
      fmt::print(stderr,
                 "warning: .splat is lossy (rotations in 4 bytes, opacity in 1): the contacts changed for {} "
                 "of {} tool poses near the surface; convert to .ply to keep them exact\n",
                 c.changed, c.poses);
    }
    fmt::print("wrote      {} ({} Gaussians{}), in {}'s convention ({}): `--up auto` on it gives the "
               "world the source gives{}\n",
               *out, scene.size(), scene.colors_dc.empty() ? ", no colour" : "",
               std::filesystem::path(*out).extension().string(), to_string(to),
               cfg.up == UpAxis::kNone && cfg.registration.is_identity() ? " with --up auto"
                                                                          : " with these options");
  });
}

}  // namespace gshaptics::cli
