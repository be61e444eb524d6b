#pragma once
/// @file
/// The one-ellipsoid proxy's contact normal (one of the proxy renderer's parts, beside
/// ProxySolver, FrictionCone and VirtualCoupling): the direction the coupling force acts along
/// once the god-object has come to rest against the Gaussians.
///
/// It is read in two stages, with the renderer's pocket test between them (a proxy caught in a
/// Gaussian-scale pocket rejoins the device, proxy_solver.h's caught_in_pocket):
/// 1. shaded(): force shading (Morgenbesser & Srinivasan 1996) on the Gaussians, the negative
///    gradient of their opacity-weighted density widened by a kernel (shaded_normal.h), read where
///    the tool's inscribed ball rests free (FreeBall), leaving out the discs of the other face
///    behind a fin (front_face, ProxyParams::overhang_falloff), kept while the proxy moves less
///    than ProxyParams::shading_reuse and prepared over the ticks before it falls due
///    (ShadedNormalCache::read_ahead, ProxyParams::shading_budget).
/// 2. refined(): where the field turns slowly, blended with the reading where the device would
///    rest (ProxyParams::device_shading); at a clean convex corner, turned to the patch's support
///    normal (edge_normal.h, ProxyParams::corner_normal), which gives way to a fin.
///
/// Threading: one thread; shaded() and refined() allocate, lock, log and throw nothing.

#include <Eigen/Core>
#include <span>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/edge_normal.h"
#include "gshaptics/force/floater_rule.h"
#include "gshaptics/force/proxy_params.h"
#include "gshaptics/force/shaded_normal.h"

namespace gshaptics {

class ProxyNormal {
 public:
  /// Reads `params` (shading_*, device_shading, corner_normal, overhang_falloff, pass_isolated,
  /// isolation_gap) from a copy of `params`; the caller validates them.
  ProxyNormal(const CollisionWorld& world, const ProxyParams& params);

  /// Stage 1: the shaded normal (unit, world frame, Gaussians -> tool; zero when no Gaussian is
  /// near) for `tool` resting with its centre at `proxy` (m) against `blockers`, `support` the
  /// unit mean of the constraint planes' normals (ProxySolver::support_normal; zero: none).
  Eigen::Vector3d shaded(const ToolEllipsoid& tool, const Eigen::Vector3d& proxy, std::span<const Contact> blockers,
                         const Eigen::Vector3d& support) noexcept;
  /// Stage 2: `n` (unit, on the spring's side: n . (proxy - device) > 0) refined by the
  /// device-side reading and the corner normal. `device`: the tool's centre as the device holds
  /// it, m; `floaters`: the proxy's floater rule (the corner patch leaves floaters out as the
  /// sweeps do). Unit, world frame.
  Eigen::Vector3d refined(const Eigen::Vector3d& n, const ToolEllipsoid& tool, const Eigen::Vector3d& proxy,
                          const Eigen::Vector3d& device, FloaterRule& floaters) noexcept;
  /// Forgets every cached reading (a new contact, a re-placed proxy).
  void forget() noexcept;
  /// The clean convex edge or corner the last crest reading found under the proxy (its faces'
  /// normals and edge line, EdgeNormalAnswer), or null: none, no reading since forget(), or
  /// corner_normal and crest_hold both off.
  [[nodiscard]] const EdgeNormalAnswer* crest() const noexcept {
    return crest_cache_.valid && crest_cache_.answer.feature() ? &crest_cache_.answer : nullptr;
  }

  /// Readings of the shaded normal so far (the cache's misses; profiling).
  [[nodiscard]] std::uint64_t reads() const noexcept { return shade_.reads(); }
  /// The shaded normal's cache (its readings, whole and ahead; profiling).
  [[nodiscard]] const ShadedNormalCache& cache() const noexcept { return shade_; }

  /// ProxyParams::corner_normal: where the last corner reading found a messy patch (a real
  /// scene's), the next comes once the proxy has moved this many tool radii (elsewhere,
  /// shading_reuse's).
  static constexpr double kCornerSearch = 0.5;
  /// ProxyParams::corner_normal: the corner patch's reach beyond the tool, in its smallest
  /// semi-axis (EdgeNormal's band, as the compound proxy's edge patch: it takes in the other
  /// faces' discs while the tool rests on one face within a radius of the corner; half of it
  /// left seed 5's 8 mm corner at 6.7 degrees, bench/RESULTS.md).
  static constexpr double kCornerBand = 1.0;
  /// ProxyParams::device_shading's blend: the reading where the device would rest counts fully
  /// while it is within kDeviceShadingFrom degrees of the proxy's, not at all past
  /// kDeviceShadingTo (linear between).
  static constexpr double kDeviceShadingFrom = 6.0, kDeviceShadingTo = 12.0;
  /// The cosine of the turn of the face under an overhang (front_face) past which the cached
  /// shaded readings are made again (10 degrees).
  static constexpr double kFaceTurn = 0.985;

 private:
  // The device-side reading blended in (device_shading), or `n` as it is.
  Eigen::Vector3d with_device_reading(const Eigen::Vector3d& n, const Eigen::Vector3d& proxy,
                                      const Eigen::Vector3d& device, double radius,
                                      const Eigen::Vector3d& offset) noexcept;
  // Reads the clean convex edge or corner under the proxy (kept for crest(): crest_hold) and
  // blends a corner's support normal in (corner_normal), giving way to a fin.
  Eigen::Vector3d with_crest_reading(const Eigen::Vector3d& n, const ToolEllipsoid& tool, const Eigen::Vector3d& proxy,
                                      const Eigen::Vector3d& offset, FloaterRule& floaters) noexcept;

  const CollisionWorld* world_;
  ProxyParams params_;
  ShadedNormalCache shade_;
  ShadedNormalCache shade_device_;  // the field where the device would rest (device_shading)
  ShadingScratch shading_scratch_;  // the shaded normal's working memory
  // Its own working memory: a reading in shading_scratch_ would give up shade_'s reading ahead.
  ShadingScratch device_scratch_;
  // The patch's clean convex edge or corner: its support normal at a corner (corner_normal),
  // an edge's or corner's faces and normal cone for the renderer's hold (crest_hold).
  EdgeNormal crests_;
  EdgeNormalCache crest_cache_;
  // The last stage 1's inputs that stage 2 reads again.
  FreeBall ball_{};
  FrontFace front_{};
  double spacing_ = 0;
  Eigen::Vector3d face_ = Eigen::Vector3d::Zero();  // the FreeBall::face the cached readings were made for
};

}  // namespace gshaptics
