#pragma once
// Peers for the benchmark, written by us against Debian's libraries, fed the same filtered,
// registered Gaussians as gshaptics (from a CollisionWorld):
//  - PaperMethodPeer: the paper's method as published (Sec. III-B): kd-tree of centres
//    (nanoflann) queried with one fixed radius, bounding-sphere pre-filter (eq. 4), and a
//    30-iteration golden-section search over K(lambda) with a 3x3 solve per step, in double.
//    The radius is r_tool + the largest Gaussian radius, so no contact is missed.
//  - FclPeer: FCL's DynamicAABBTreeCollisionManager over fcl::Ellipsoid objects, with FCL's
//    default (GJK/EPA via libccd) ellipsoid-ellipsoid test.

#include <cstdint>
#include <memory>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/tool_ellipsoid.h"

namespace gshaptics::peers {

/// Contacts (source indices, sorted) and broad-phase candidates of one peer query.
struct PeerResult {
  std::vector<std::uint32_t> contacts;
  std::uint32_t candidates = 0;
};

class PaperMethodPeer {
 public:
  explicit PaperMethodPeer(const CollisionWorld& world);
  ~PaperMethodPeer();
  void query(const ToolEllipsoid& tool, PeerResult& out);
  [[nodiscard]] std::size_t memory_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

class FclPeer {
 public:
  explicit FclPeer(const CollisionWorld& world);
  ~FclPeer();
  void query(const ToolEllipsoid& tool, PeerResult& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gshaptics::peers
