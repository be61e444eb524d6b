// `gshaptics query`: one collision query (or one per line of a pose file), printed as JSON.
// The output is a contract other tools rely on (issue "core pipeline", "Query contract").

#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/session/query_session.h"

namespace gshaptics::cli {

void register_query(CLI::App& app) {
  auto o = std::make_shared<QueryCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "query",
      "Find the Gaussians overlapping a tool ellipsoid and print them as JSON: "
      "{\"candidates\": n, \"prefiltered\": n, \"contacts\": [{\"index\", \"k_min\", \"opacity\", "
      "\"center\"}...], \"query_us\": t}. Contacts are sorted by index into the original file; "
      "centres are in the world frame (the scene's own frame without --registration).");
  cmd->add_option("scene", o->scene.scene, "Scene file (any format gshaptics reads: INRIA PLY, compressed PLY, .splat, SPZ)")->required();
  cmd->add_option("--tool-center", o->center, "Tool centre X,Y,Z (world frame)");
  cmd->add_option("--tool-axes", o->axes, "Tool semi-axes A,B,C (world units, > 0)");
  cmd->add_option("--tool-rotation", o->rotation, "Tool rotation quaternion W,X,Y,Z")
      ->capture_default_str();
  cmd->add_option("--poses", o->poses,
                  "File with one pose per line: cx cy cz ax ay az qw qx qy qz ('#' comments); "
                  "prints one JSON object per line (JSON Lines)");
  cmd->add_option("--minimiser", o->minimiser, "K_min search: newton (default) or golden (paper)")
      ->check(CLI::IsMember({"newton", "golden"}))->capture_default_str();
  cmd->add_option("--golden-iterations", o->golden_iterations,
                  "Iterations of the golden-section search")->capture_default_str()
      ->check(CLI::Range(1, 200));
  add_world_options(*cmd, o->scene);
  add_world_cache_option(*cmd, o->scene);
  cmd->callback([o] { run_query_command(*o); });
}

}  // namespace gshaptics::cli
