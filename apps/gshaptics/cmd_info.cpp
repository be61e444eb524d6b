// `gshaptics info SCENE`: what a scene file holds and what the opacity filter would keep.

#include <memory>

#include "commands.h"
#include "options.h"

namespace gshaptics::cli {

void register_info(CLI::App& app) {
  auto opts = std::make_shared<SceneOptions>();
  auto quiet = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "info", "Print a scene's format, counts, load report, bounds, opacity and scale percentiles "
              "(and the drawn Gaussians' median middle axis, --surface seen's least normal ring) "
              "and the opacity filter's reduction (a default run's, 1/255, and --surface ellipsoids' "
              "and --force-model paper's, 0.2); then preview the world that a default run, --up and a "
              "registration make of it (bounds, size, up axis) and suggest --up, --reg-scale and "
              "a tool radius for a desktop device and for room scale");
  cmd->add_option("scene", opts->scene, "Scene file (.ply, .compressed.ply, .splat or .spz)")->required();
  add_world_options(*cmd, *opts);
  cmd->add_flag("--quiet", *quiet, "No progress bar");
  cmd->callback([opts, quiet] { run_info_command(*opts, *quiet); });
}

}  // namespace gshaptics::cli
