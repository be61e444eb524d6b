#pragma once
/// @file
/// The god-object proxy of a compound tool (collision/compound_tool.h) on the seen solid
/// (force/seen_solid.h): ProxyParams::surface == ProxySurface::kSeen with a tool of several parts.
/// It is the one-part seen proxy (seen_proxy.h) given the tool's shape: every part is an
/// ellipsoid, and a part meets the seen solid at its leading point along the push, the point of
/// its surface farthest along it (ToolEllipsoid::surface_point).
///
/// Each tick:
/// 1. Free: the proxy is the device. Each part's centre moves along its chord from the last tick's
///    pose to this one's (translation and turn), its leading point searched along the whole chord
///    (SeenSolid::push: no motion tunnels), each seen from as far behind the part as it is still
///    seen from (at most seen_window tool radii). The part met first begins a contact: its chord
///    is the contact's axis a, and its eye plane the contact's.
/// 2. In contact: the proxy keeps the device's orientation and its place across the axis (or the
///    friction cone's: Salisbury et al. 1995), and rests along a on the seen surface as seen
///    from the eye plane. Each part's leading point is searched along a from the eye plane to its
///    depth; the proxy backs off along -a by the deepest part's depth past its surface (a rigid
///    body on a height field: every part on or above the seen surface under it). When no part
///    reaches the surface, the device has come out and the contact ends.
/// 3. Wrench: the virtual coupling (Colgate, Stanley and Brown 1995) F = max(0, k e . n - b v . n) n,
///    e = x_proxy - x_device, along the seen surface's normal n (SeenSolid::normal: the renderer's
///    normal map and the seen depth's slope, read on a ring of 1.5 times the touching part's
///    middle semi-axis, one ray a tick after a contact's first reading, smoothed over 5 ms), plus
///    friction; applied at the touching parts' surface points facing the contact, each weighted
///    1 - (gap / band)^2 (gap: how far the part's leading point stands above its seen surface,
///    band: half the tool's smallest semi-axis), so a stylus lying on a wall gets the middle of
///    its line of contact, as the compound proxy on the ellipsoids does (compound_proxy.h). The
///    torque about the TCP is the force's moment, (c - x_tcp) x F.
///
/// Not done (the compound proxy on the ellipsoids does these): the proxy does not turn against
/// the surface (a turn that would swing a part into the solid raises the proxy along a instead,
/// and no rotational coupling is rendered); walls parallel to the axis are not felt until the
/// device comes out and pushes on them afresh (the one-part seen proxy's limit); materials are
/// refused (ProxyRenderer::set_materials).
///
/// Frame and units: world, metres as the world's; the TCP and orientation as CompoundProxy's.
/// render() does not allocate, lock, log or throw.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <limits>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/force/friction_cone.h"
#include "gshaptics/force/proxy_params.h"
#include "gshaptics/force/seen_solid.h"
#include "gshaptics/force/virtual_coupling.h"

namespace gshaptics {

class SeenCompoundProxy {
 public:
  /// On `solid` (kept by reference: it outlives the proxy). `params` as SeenProxy reads them
  /// ("tool radii": the tool's largest semi-axis); `f_max` clamps the coupling force, N.
  /// Throws InputError for an invalid tool.
  SeenCompoundProxy(const SeenSolid& solid, const CompoundTool& tool, const ProxyParams& params,
                    double f_max = std::numeric_limits<double>::infinity());

  /// One tick: the device's TCP position (m) and orientation (tool frame -> world), its velocity
  /// (m/s) and angular velocity (rad/s), dt (s, > 0). Force and torque (about the TCP) on the
  /// device, world frame; RenderOutput::proxy is the proxy's TCP.
  RenderOutput render(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                      const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity, double dt) noexcept;
  void reset() noexcept;

  [[nodiscard]] const CompoundTool& tool() const noexcept { return tool_; }
  [[nodiscard]] const Eigen::Vector3d& position() const noexcept { return x_; }
  [[nodiscard]] const Eigen::Vector3d& contact_normal() const noexcept { return normal_; }
  [[nodiscard]] bool in_contact() const noexcept { return in_contact_; }
  /// The parts touching at the last tick (weight > 0).
  [[nodiscard]] int touching() const noexcept { return touching_; }

 private:
  // The parts posed at (x, q) into parts_.
  void pose(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept;
  // Free: the parts' chords from the last pose to (x, q); true when one meets the seen solid
  // (the contact's axis and eye plane are set).
  bool begin_contact(const Eigen::Vector3d& x, const Eigen::Quaterniond& q) noexcept;
  // In contact: the proxy along the axis over the goal's place across it, the device's depth;
  // false when no part reaches the surface.
  bool hold(const Eigen::Vector3d& device, const Eigen::Vector3d& goal, const Eigen::Quaterniond& q) noexcept;
  // The touching parts' weighted contact point (world) and the heaviest part; false if none.
  bool contact_point(Eigen::Vector3d& c, int& heaviest) const noexcept;
  void read_normal(const Eigen::Vector3d& point, double h, double depth) noexcept;
  void release() noexcept;

  static constexpr double kNormalTau = 0.005;   // s (SeenProxy's)
  static constexpr double kNormalPath = 0.5;    // tool radii (SeenProxy's)
  static constexpr double kNormalReuse = 0.05;  // tool radii
  static constexpr double kNormalEye = 8;       // tool radii
  static constexpr double kNormalSpan = 1.5;    // the ring, in the touching part's middle semi-axis
  static constexpr double kGuessMargin = 0.25;  // tool radii
  static constexpr double kEyeMargin = 0.25;    // tool radii
  static constexpr double kContactBand = 0.5;   // the smallest semi-axis (CompoundProxy's)

  const SeenSolid* solid_;
  CompoundTool tool_;
  ProxyParams params_;
  double f_max_;
  double radius_ = 0, min_axis_ = 0;  // the tool's largest and smallest semi-axes
  SeenScratch scratch_;
  VirtualCoupling coupling_;
  FrictionCone friction_;
  FrictionStep friction_step_;
  std::array<ToolEllipsoid, kMaxToolParts> parts_{};
  std::array<double, kMaxToolParts> gap_{};       // each part's leading point above its surface (+inf: none)
  std::array<double, kMaxToolParts> last_hit_{};  // each part's last hit, depth from the eye plane (NaN: none)
  Eigen::Vector3d x_ = Eigen::Vector3d::Zero(), last_device_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero(), target_normal_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_at_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_ = Eigen::Vector3d::Zero(), eye_ = Eigen::Vector3d::Zero();
  int pending_ray_ = -1;
  Eigen::Vector3d pending_at_ = Eigen::Vector3d::Zero();
  double pending_back_ = 0, pending_h_ = 0;
  std::array<SeenHit, SeenSolid::kNormalRays> pending_hits_{};
  int touching_ = 0;
  bool started_ = false, in_contact_ = false;
};

}  // namespace gshaptics
