#pragma once
/// @file
/// The session layer (see world_session.h), `gshaptics query`: one collision query as the JSON
/// line other tools rely on (the query contract: docs/usage.md).

#include <Eigen/Core>
#include <string>

#include "gshaptics/collision/contact_query.h"

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

}  // namespace gshaptics::session
