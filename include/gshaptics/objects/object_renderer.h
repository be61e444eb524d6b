#pragma once
/// @file
/// Force rendering in a scene with rigid objects (issue 72): one renderer on the static world
/// and one per object on the object's body-frame world, each holding its own proxy; the dynamics
/// (ObjectDynamics, MuJoCo) stepped inside the tick.
///
/// Each tick, per object: the tool (pose, velocity relative to the body's own motion at the tool)
/// is moved into the object's body frame with the object's pose now, the object's renderer moves
/// its proxy there (a sweep in the body frame sees the body's motion over the tick as the tool's
/// relative motion, so the proxy never passes through a moving object, and an object moving into
/// a resting proxy carries it along and pushes the hand), and its force and torque come back to
/// the world. The hand gets the proxies' forces combined as one god-object on all the bodies
/// would push (load_shares: a corner between an object and the scene is felt as the two springs'
/// sum; a seam where an object was cut from a flat surface is felt once, not twice); each object
/// gets the reaction to its share, -s F at its proxy's tool centre plus the couple -s tau, as an
/// external wrench for the next step.
///
/// The support carries the hand too, where a cut left a hole in the static scene (the capture
/// never saw under the object): within each object's footprint at rest (its hull's extent across
/// the support's normal), the tool meets a plane at the height of the object's lowest point at
/// rest (where the surface under it was; the ground's normal). A tool part below it by d (its support point along -n) is pushed back by the coupling's spring and
/// damper, F = (k_c d - b_c v.n) n, never pulling, at that point (torque about the TCP). As a
/// proxy would, the plane only holds a part that reached it from above (or from the scene beside
/// the hole, within one semi-axis of the plane): a part that is already deep under it, or that
/// leaves the footprint, is let go, so the plane never shoves a hand that is under the scene.
///
/// The captured scene, where its objects still stand: a proxy per body rests on half a surface at
/// the seam of a cut (it sinks or tilts where the other body's Gaussians held a single proxy), so
/// the renderer also holds one proxy on the whole scene (WholeSceneWorld: the static part joined
/// with every object where it stands untouched). While the objects near the tool stand within
/// WholeScene::rest_tolerance of those poses, the hand gets that proxy's force: one god-object on
/// all the Gaussians. As an object near the tool leaves its pose, the hand's force blends linearly,
/// over that tolerance, into the per-body proxies' (load_shares), so the blend is continuous in the
/// object's motion and in the tool's. Where its weight is 0 the whole scene's proxy is not moved
/// (it would slide along an object that has left, at a cost); it starts afresh, as a proxy in free
/// space does, once the tool touches nothing and the objects near it stand. The objects get their
/// reactions from the per-body proxies either way.
///
/// Sources: the god-object (Zilles and Salisbury 1995) per rigid body, as multi-object proxies
/// do (Ruspini, Kolarov and Khatib 1997); the coupling force as the body's external wrench, as in
/// virtual-coupling rigid-body haptics (Colgate, Stanley and Brown 1995; Otaduy and Lin 2006).
///
/// Threading and hot path as ForceRenderer: render() never allocates, locks, logs or throws; the
/// MuJoCo step runs inside it at the dynamics' timestep (at most kMaxDynamicsSteps per tick).

#include <array>
#include <memory>
#include <span>
#include <vector>

#include "gshaptics/force/force_renderer.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/objects/object_dynamics.h"

namespace gshaptics {

/// Where a cut left a hole in the static scene: the object's footprint at rest in the support's
/// plane coordinates (support_axes), and the height (m, along the support's normal) of the
/// surface there, the object's lowest point at rest.
struct SupportHole {
  Eigen::AlignedBox2d area;
  double height = 0;
};

/// At most this many dynamics steps in one tick: a late tick does not make the next one later.
inline constexpr int kMaxDynamicsSteps = 4;

/// The share s_i in [0, 1] of each proxy's force `forces[i]` (N, world) that the hand gets when
/// several proxies hold one tool (the static scene's and each object's): the force a single
/// god-object on all the bodies would push with (Zilles and Salisbury 1995: one proxy, one
/// spring), each proxy's force read as a constraint that the hand be pushed at least |F_i| along
/// F_i: the least force F = sum_i s_i F_i with F . n_i >= |F_i| (n_i = F_i / |F_i|), each proxy
/// giving at most its own force. Two proxies side by side on one flat surface (a seam where an
/// object was cut from a table) push once, the deeper one's force; at a corner (orthogonal
/// forces) both add; at 45 degrees F meets both constraints exactly; squeezed between opposed
/// proxies, both push (they cancel). F is unique and continuous in the F_i (the shares need not
/// be unique: side by side, any split). Solved as the box-constrained dual by projected
/// Gauss-Seidel, at most kLoadShareSweeps sweeps. A zero force gets share 0; `share` must be as
/// long as `forces` (at most kMaxObjects + 1 are read).
inline constexpr int kLoadShareSweeps = 200;
void load_shares(std::span<const Eigen::Vector3d> forces, std::span<double> share) noexcept;

/// How far (m) an object may stand, at the tool, from where the whole scene holds it and still be
/// felt as part of that scene; the whole scene's force fades out over this distance.
inline constexpr double kWholeSceneRestTolerance = 5e-4;
/// An object is placed in the whole scene where it settles untouched (untouched_drift) when that
/// moves no point of its box farther than this (m); else where it was captured.
inline constexpr double kWholeSceneSettleTolerance = 2e-3;

/// The scene as the hand meets it before it touches anything: the static part joined with each
/// object where it stands untouched (whole_scene_world()).
struct WholeSceneWorld {
  std::shared_ptr<const CollisionWorld> world;
  std::array<BodyPose, kMaxObjects> poses{};  ///< where each object is in `world` (velocities zero)
};

/// One proxy on the whole scene (ObjectRenderer's seam handling); null renderer: none.
struct WholeScene {
  std::unique_ptr<ForceRenderer> renderer;
  std::shared_ptr<const WholeSceneWorld> scene;  ///< what the renderer reads (kept alive here)
  double rest_tolerance = kWholeSceneRestTolerance;  ///< m, > 0
};

class ObjectRenderer final : public ForceRenderer {
 public:
  /// `scene` renders the static world; `bodies[i]` renders objects[i].body (the same order as
  /// the dynamics' objects); `worlds` keeps the body worlds alive. Throws InputError when the
  /// counts differ or a renderer is null.
  /// `support_coupling`: the plane's spring (N/m) and damper (N s/m), the proxy's k_c and b_c.
  /// `holes`: where the support carries the hand (support_holes(); empty: nowhere).
  /// `whole`: the renderer on the whole scene (whole_scene_world()); without one, the hand gets
  /// the per-body proxies' force everywhere. Throws InputError for a tolerance <= 0.
  ObjectRenderer(std::unique_ptr<ForceRenderer> scene, std::vector<std::unique_ptr<ForceRenderer>> bodies,
                 std::vector<std::shared_ptr<const CollisionWorld>> worlds, std::shared_ptr<ObjectDynamics> dynamics,
                 const Eigen::Vector2d& support_coupling = Eigen::Vector2d(ProxyParams{}.stiffness,
                                                                           ProxyParams{}.damping),
                 std::vector<SupportHole> holes = {}, WholeScene whole = {});
  [[nodiscard]] std::string_view name() const noexcept override { return scene_->name(); }
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept override;
  RenderOutput render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                               const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                               double dt) noexcept override;
  [[nodiscard]] bool renders_compound() const noexcept override;
  void set_tool(const CompoundTool& tool) override;
  /// The static scene's contacts then each object's, centres in the world, Contact::body set.
  [[nodiscard]] std::span<const Contact> contacts() const noexcept override { return merged_.contacts(); }
  /// Forgets every proxy and puts the objects back at rest where they were captured.
  void reset() noexcept override;
  void set_executor(ParallelExecutor* executor, std::size_t min_candidates) override;

  [[nodiscard]] ObjectDynamics& dynamics() noexcept { return *dynamics_; }
  [[nodiscard]] const ObjectDynamics& dynamics() const noexcept { return *dynamics_; }
  /// The force (N, world) object i's renderer put on the tool at the last tick.
  [[nodiscard]] const Eigen::Vector3d& object_force(std::size_t i) const noexcept { return object_force_[i]; }
  /// Where object i's renderer held the tool at the last tick: its proxy's centre, world, m.
  [[nodiscard]] const Eigen::Vector3d& object_proxy(std::size_t i) const noexcept { return object_proxy_[i]; }
  /// The weight in [0, 1] the whole scene's proxy had in the hand's force at the last tick (0
  /// without a whole scene).
  [[nodiscard]] double whole_scene_weight() const noexcept { return whole_weight_; }

 private:
  template <class RenderIn>
  RenderOutput render_all(RenderOutput scene_out, RenderIn&& render_in, double dt) noexcept;
  void gather_contacts(std::span<const Contact> contacts, std::uint8_t body, const BodyPose* pose) noexcept;
  void step_dynamics(double dt) noexcept;
  // The support plane's push on the tool's parts (world), added to `sum`.
  void add_support(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp, const Eigen::Vector3d& velocity,
                   const Eigen::Vector3d& angular_velocity, RenderOutput& sum) noexcept;
  // The whole scene's weight for a tool whose parts are `parts` (world): 1 while every object
  // near them stands at rest, falling to 0 as one near them leaves its rest pose.
  [[nodiscard]] double whole_weight(std::span<const ToolEllipsoid> parts) const noexcept;
  // `cut` (the per-body proxies' output) with the whole scene's force (render_whole()) blended in.
  template <class RenderWhole>
  RenderOutput blend_whole(RenderOutput cut, std::span<const ToolEllipsoid> parts, RenderWhole&& render_whole) noexcept;
  // The hole whose footprint holds `p` (null: none).
  [[nodiscard]] const SupportHole* hole_at(const Eigen::Vector3d& p) const noexcept;

  std::unique_ptr<ForceRenderer> scene_;
  std::vector<std::unique_ptr<ForceRenderer>> bodies_;
  std::vector<std::shared_ptr<const CollisionWorld>> worlds_;
  std::shared_ptr<ObjectDynamics> dynamics_;
  struct Reaction {
    Eigen::Vector3d force = Eigen::Vector3d::Zero(), point = Eigen::Vector3d::Zero(), couple = Eigen::Vector3d::Zero();
  };
  std::array<Eigen::Vector3d, kMaxObjects> object_force_{}, object_proxy_{};
  std::array<Reaction, kMaxObjects> reaction_{};  // on each object over this tick (world)
  ContactSet merged_{1u << 12};
  double pending_ = 0;  // simulated time owed to the dynamics, s
  Eigen::Vector2d support_coupling_;  // k_c (N/m), b_c (N s/m)
  std::vector<SupportHole> holes_;
  std::array<Eigen::Vector3d, 2> hole_axes_;  // support_axes() of the dynamics' support, once
  std::array<bool, kMaxToolParts> support_held_{};  // each part held by the plane since it reached it
  WholeScene whole_;
  // Each object's bounding sphere: centre in its body frame and radius (m), from its world's bounds.
  std::array<Eigen::Vector3d, kMaxObjects> body_centre_{};
  std::array<double, kMaxObjects> body_radius_{};
  double whole_weight_ = 0;
  // The whole scene's proxy is followed tick by tick; it stops where its weight is 0 (it would
  // slide along an object that has left) and restarts afresh with the tool free.
  bool whole_live_ = true;
};

/// Each object's footprint on `plane` at rest (where its cut left a hole): the box of its hull
/// points at rest in the plane's coordinates (support_axes), and the height along the plane's
/// normal of its lowest hull point at rest.
[[nodiscard]] std::vector<SupportHole> support_holes(std::span<const RigidObject> objects, const SupportPlane& plane);

/// The whole scene: the static `scene` joined with each object's body world (CollisionWorld::joined)
/// placed where `drift` says it settles untouched (UntouchedDrift::settled, when that moves no
/// corner of its box more than kWholeSceneSettleTolerance), else at its rest pose as captured.
/// Build it once per scene; renderers share it.
[[nodiscard]] std::shared_ptr<const WholeSceneWorld> whole_scene_world(const CollisionWorld& scene,
                                                                       std::span<const RigidObject> objects,
                                                                       const UntouchedDrift& drift);

/// What make_object_renderer() gives the ObjectRenderer of the scene as captured.
struct WholeSceneOptions {
  bool enabled = true;  ///< false: the per-body proxies alone (a seam is felt as two half surfaces)
  /// whole_scene_world() of the same scene and objects; null: built by make_object_renderer()
  /// (1 s of untouched dynamics first, as untouched_drift()).
  std::shared_ptr<const WholeSceneWorld> world;
  double rest_tolerance = kWholeSceneRestTolerance;  ///< m, > 0
};

/// The renderer `spec` names on the static `scene`, on each object's body world and on the
/// whole scene (`whole`), with the objects' dynamics. Throws InputError as make_force_renderer()
/// and ObjectRenderer.
[[nodiscard]] std::unique_ptr<ObjectRenderer> make_object_renderer(const RendererSpec& spec, const CollisionWorld& scene,
                                                                   std::span<const RigidObject> objects,
                                                                   std::shared_ptr<ObjectDynamics> dynamics,
                                                                   const QueryOptions& query = {},
                                                                   WholeSceneOptions whole = {});

}  // namespace gshaptics
