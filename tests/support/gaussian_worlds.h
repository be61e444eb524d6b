#pragma once
// Small hand-built worlds of Gaussians for the proxy's and the sweep query's tests.

#include <Eigen/Geometry>
#include <tuple>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/io/gaussian_scene.h"

namespace gshaptics::test {

/// (centre, semi-axes, rotation) of one Gaussian, m.
using GaussianSpec = std::tuple<Eigen::Vector3f, Eigen::Vector3f, Eigen::Quaternionf>;

/// A world of the given Gaussians, opacity `opacity` each, default world options.
inline CollisionWorld world_of(const std::vector<GaussianSpec>& gs, float opacity = 1.0f) {
  GaussianScene s;
  std::uint32_t i = 0;
  for (const auto& [c, a, q] : gs) s.push_back(c, a, Eigen::Vector4f(q.w(), q.x(), q.y(), q.z()), opacity, i++);
  return CollisionWorld::build(s, WorldConfig{});
}

/// A flat layer of round discs (spacing h, radius h, thickness 0.05 h) at height z over
/// [-half, half]^2, normal +z.
inline void add_layer(std::vector<GaussianSpec>& gs, float z, float h, float half) {
  for (float x = -half; x <= half; x += h)
    for (float y = -half; y <= half; y += h)
      gs.emplace_back(Eigen::Vector3f(x, y, z), Eigen::Vector3f(h, h, 0.05f * h), Eigen::Quaternionf::Identity());
}

/// Whether `t` overlaps any Gaussian of `w` (the exact test).
inline bool overlaps(const CollisionWorld& w, const ToolEllipsoid& t) {
  ContactQuery q(w);
  return q.any_contact(t);
}

}  // namespace gshaptics::test
