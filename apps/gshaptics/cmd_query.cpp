// `gshaptics query`: one collision query (or one per line of a pose file), printed as JSON.
// The output is a contract other tools rely on (issue "core pipeline", "Query contract").

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.h"
#include "options.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/error.h"
#include "gshaptics/session/query_session.h"

namespace gshaptics::cli {

namespace {

struct QueryCliOptions {
  SceneOptions scene;
  std::string center, axes, rotation = "1,0,0,0", poses;
  std::string minimiser = "newton";
  int golden_iterations = 30;
};


}  // namespace

void register_query(CLI::App& app) {
  auto o = std::make_shared<QueryCliOptions>();
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
  cmd->callback([o] {
    if (o->poses.empty() && (o->center.empty() || o->axes.empty()))
      throw InputError("query: give --tool-center and --tool-axes, or --poses FILE");
    if (!o->poses.empty() && !o->center.empty())
      throw InputError("query: --poses and --tool-center are exclusive");
    if (!o->poses.empty() && std::filesystem::is_directory(o->poses))
      throw InputError(o->poses + ": is a folder, expected a pose file");
    if (!o->poses.empty() && !std::filesystem::exists(o->poses))
      throw InputError(o->poses + ": no such pose file");
    // stdout is the JSON; what the load did goes to stderr.
    const PreparedWorld pw = prepare_world(o->scene, false, stderr);
    const CollisionWorld& world = pw.world;
    QueryOptions qo;
    if (o->minimiser == "golden") {
      qo.narrow_phase.minimiser = Minimiser::kGoldenSection;
      qo.narrow_phase.golden_iterations = o->golden_iterations;
    }
    ContactQuery query(world, qo);
    if (o->poses.empty()) {
      const ToolEllipsoid tool =
          make_tool(parse_vec3(o->center, "--tool-center"), parse_vec3(o->axes, "--tool-axes"),
                    parse_vec4(o->rotation, "--tool-rotation"), "query");
      std::printf("%s\n", query_answer_json(query, tool).c_str());
      return;
    }
    std::ifstream in(o->poses);
    if (!in) throw InputError(o->poses + ": cannot open pose file");
    std::string line;
    int line_no = 0;
    while (std::getline(in, line)) {
      ++line_no;
      for (const std::string& m : frame_mismatches(line, o->scene))
        std::fprintf(stderr, "gshaptics: warning: %s: the poses are in another world frame: %s\n",
                     o->poses.c_str(), m.c_str());
      const auto hash = line.find('#');
      if (hash != std::string::npos) line.erase(hash);
      std::istringstream ls(line);
      std::vector<double> v;
      double x;
      while (ls >> x) v.push_back(x);
      if (!ls.eof()) throw InputError(o->poses + ": line " + std::to_string(line_no) + ": not a number");
      if (v.empty()) continue;
      const std::string where = o->poses + ": line " + std::to_string(line_no);
      if (v.size() != 10)
        throw InputError(where + ": expected 10 numbers (cx cy cz ax ay az qw qx qy qz), got " +
                         std::to_string(v.size()));
      for (double y : v)
        if (!std::isfinite(y)) throw InputError(where + ": values must be finite");
      const ToolEllipsoid tool = make_tool({v[0], v[1], v[2]}, {v[3], v[4], v[5]},
                                           {v[6], v[7], v[8], v[9]}, where);
      std::printf("%s\n", query_answer_json(query, tool).c_str());
    }
  });
}

}  // namespace gshaptics::cli
