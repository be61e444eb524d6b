#pragma once
/// @file
/// The god-object proxy on the seen solid (force/seen_solid.h): ProxyParams::surface ==
/// ProxySurface::kSeen. The proxy is a sphere of the tool's bounding radius R.
/// - Free, it moves straight toward the device; its leading point (centre + R u) stops where the
///   seen solid begins for that push, seen from as far behind the proxy as it is still seen from
///   (at most seen_window R; SeenSolid::eye_distance), and the whole segment is searched, so no
///   motion tunnels. That begins a contact, along the push's axis, with its eye plane.
/// - In contact, the proxy rests on the seen surface as seen along the axis from the eye plane,
///   over the device's leading point (a height field along the axis: the device slides it
///   freely across), until the device comes out of the surface. The eye plane stays put, so a
///   proxy pressed into a faint layer keeps the layer in front of its eye: small steps do not
///   creep through it.
/// The force is the virtual coupling's (Colgate, Stanley and Brown 1995) along the seen surface's
/// normal (four rays; after a contact's first reading one ray a tick; smoothed over 5 ms), with
/// the proxy's stiffness, damping and the renderer's f_max; no friction, no energy bound. Limits: walls parallel to the contact's axis are not felt until the
/// device comes out and pushes on them afresh.
///
/// Frame and units: world, metres as the world's. render() does not allocate, lock, log or throw.

#include <Eigen/Core>
#include <array>

#include "gshaptics/collision/tool_ellipsoid.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/force/proxy_params.h"
#include "gshaptics/force/seen_solid.h"
#include "gshaptics/force/virtual_coupling.h"

namespace gshaptics {

class SeenProxy {
 public:
  /// Builds the seen solid of `world` (keep faint Gaussians: WorldConfig::min_opacity near 1/255).
  SeenProxy(const CollisionWorld& world, const ProxyParams& params, double f_max);
  /// One tick: the tool where the device is (its centre and bounding radius), its velocity
  /// (m/s) and the tick (s). RenderOutput::proxy is the proxy's centre; constraints the planes
  /// met this tick.
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept;
  void reset() noexcept;
  [[nodiscard]] const SeenSolid& solid() const noexcept { return solid_; }
  [[nodiscard]] const Eigen::Vector3d& position() const noexcept { return proxy_; }
  [[nodiscard]] const Eigen::Vector3d& contact_normal() const noexcept { return normal_; }

 private:
  // Free: the proxy moves straight toward the device; true when the seen solid stops it (a
  // contact begins: its axis and eye plane are set).
  bool begin_contact(const Eigen::Vector3d& device, double radius) noexcept;
  // In contact: the proxy on the seen surface along the contact's axis, over the device's leading
  // point; false when the device has come out of the surface.
  bool hold(const Eigen::Vector3d& device, double radius, double dt) noexcept;
  // The normal's reading at the resting point `point` (`depth` from the eye plane): all four rays
  // for a contact's first, one ray a tick for the later ones.
  void read_normal(const Eigen::Vector3d& point, double radius, double depth) noexcept;
  static constexpr double kNormalTau = 0.005;   // s
  static constexpr double kNormalReuse = 0.05;  // R
  static constexpr double kNormalEye = 8;       // R: the normal's rays look from at most this far back
  static constexpr double kNormalSpan = 1.0;    // R: the normal's rays, this far to each side
  static constexpr double kGuessMargin = 0.25;  // R: the layers first read reach this past the last hit
  SeenSolid solid_;
  SeenScratch scratch_;
  ProxyParams params_;
  VirtualCoupling coupling_;
  Eigen::Vector3d proxy_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_ = Eigen::Vector3d::Zero();  // the contact's push direction
  Eigen::Vector3d eye_ = Eigen::Vector3d::Zero();   // a point of its eye plane
  Eigen::Vector3d target_normal_ = Eigen::Vector3d::Zero(), normal_at_ = Eigen::Vector3d::Zero();  // last reading
  int pending_ray_ = -1;  // the next ray of a reading under way (-1: none)
  Eigen::Vector3d pending_at_ = Eigen::Vector3d::Zero();
  double pending_back_ = 0;
  std::array<SeenHit, 4> pending_hits_{};
  double last_hit_ = 0;  // the last hit's depth from the eye plane (NaN: none in this contact)
  bool started_ = false, in_contact_ = false;
};

}  // namespace gshaptics
