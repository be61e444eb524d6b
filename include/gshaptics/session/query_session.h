#pragma once
/// @file
/// The session layer (see world_session.h), `gshaptics query`: one collision query as the JSON
/// line other tools rely on (the query contract: docs/usage.md); and `gshaptics convert`, which
/// measures what a lossy output changes with the same queries.

#include <Eigen/Core>
#include <string>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/session/world_session.h"

namespace gshaptics::session {

/// A tool ellipsoid from a centre, semi-axes (> 0) and a quaternion (w, x, y, z; normalised
/// here). Throws InputError naming `where` for non-positive axes or a zero quaternion.
[[nodiscard]] ToolEllipsoid make_tool(const Eigen::Vector3d& center, const Eigen::Vector3d& semi_axes,
                                      const Eigen::Vector4d& wxyz, const std::string& where);

/// Runs `query` for `tool` and answers one JSON object: candidates, prefiltered, the contacts
/// sorted by file index (index, k_min, opacity, center), query_us, and overflow when the
/// contact set overflowed.
[[nodiscard]] std::string query_answer_json(ContactQuery& query, const ToolEllipsoid& tool);

/// How two worlds of the same scene differ where it matters (a lossy conversion, say): of
/// `poses` seeded near-surface tool poses drawn on `a` (sim/pose_sampler.h), those whose contact
/// sets (file indices) differ between `a` and `b`.
struct ContactChange {
  std::size_t poses = 0, changed = 0;
};
[[nodiscard]] ContactChange compare_contacts(const CollisionWorld& a, const CollisionWorld& b, std::size_t poses = 200,
                                             std::uint64_t seed = 1);

/// `gshaptics query`: the options as on the command line.
struct QueryCommandOptions {
  SceneOptions scene;
  std::string center, axes, rotation = "1,0,0,0";  ///< "X,Y,Z", "A,B,C", "W,X,Y,Z" (world frame)
  std::string poses;                                ///< a pose file (one query per line) instead
  std::string minimiser = "newton";                 ///< K_min search: newton or golden (the paper's)
  int golden_iterations = 30;
};

/// The query command: loads the world (reporting on stderr), then prints one query_answer_json()
/// line for the tool, or one per pose of the pose file (cx cy cz ax ay az qw qx qy qz, '#'
/// comments; a pose line in another world frame is warned about). Throws InputError naming the
/// option, the file and line for bad input.
void run_query_command(const QueryCommandOptions& o);

/// `gshaptics convert`: the options as on the command line.
struct ConvertCommandOptions {
  SceneOptions scene;       ///< the input, --registration and --up (min_opacity unused: see below)
  std::string out;          ///< .ply or .splat, written atomically
  float min_opacity = -1;   ///< keep Gaussians with opacity > this; < 0: keep all
  bool quiet = false;       ///< no progress bar
};

/// The convert command: loads the scene with its colours, drops Gaussians at or below
/// min_opacity, applies --up and the registration, and writes it in the output format's own
/// convention (so `--up auto` on it gives the world the source gives). For .splat (lossy) it
/// measures, with compare_contacts(), how many tool poses' contacts changed and warns. Throws
/// InputError naming the file for a bad extension or input.
void run_convert_command(const ConvertCommandOptions& o);

}  // namespace gshaptics::session
