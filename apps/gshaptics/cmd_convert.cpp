// `gshaptics convert IN OUT`: save a (filtered, registered) scene once, load it fast later.

#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/session/query_session.h"

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
    session::ConvertCommandOptions c;
    c.scene = *o;
    c.out = *out;
    c.min_opacity = *min_opacity;
    c.quiet = *quiet;
    session::run_convert_command(c);
  });
}

}  // namespace gshaptics::cli
