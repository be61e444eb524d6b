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
///   creep through it. The proxy rises at most the slope it slides (tan 76 deg) plus R / 240 a
///   tick (SeenProxy::climb): a rise its slide does not explain (a step lower than the sphere,
///   its footprint closing round it) comes as a ramp of force, not a step.
/// - The proxy's climb is paid for (force/climb_ledger.h): a god-object's step never stretches the
///   coupling (Zilles and Salisbury 1995), and the height field rising under a loaded proxy would,
///   giving the hand back energy it never put in. Under load the proxy rises only on what its
///   falls, and the normal's lean against its slide, paid for; a rise still owed past
///   ClimbLedger::kOweFloor R is charged to the hand as a reaction across the normal against its
///   slide, the slope a rigid sphere climbs onto a step that high. A still hand pays nothing and
///   the proxy keeps its level; relief the proxy does not ride reaches a material's texture tip.
/// The force is the virtual coupling's (Colgate, Stanley and Brown 1995) along the seen surface's
/// normal (SeenSolid::normal: the renderer's normal map and the seen depth's slope, read along four
/// rays 1.5 R around the point; after a contact's first reading one ray a tick; smoothed over 5 ms), with
/// the proxy's stiffness, damping and the renderer's f_max; no energy bound. Friction (mu_s, mu_k)
/// is the friction cone's (Salisbury et al. 1995): the proxy's place across the axis follows the
/// cone's goal (it stays while the device is inside the cone, trails it by mu_k times the depth
/// while sliding), and the height field is read there.
/// - With a material map (set_follower), the material under the contact is read from the layers
///   that make the seen surface under the leading point, weighted as the renderer weighs them
///   (T_k alpha_k: SeenSolid::visit_hit_layers), and followed along the path (MaterialFollower);
///   its texture tip is the leading point itself: the seen surface's depth along the axis where
///   it holds the proxy, high-passed (TextureState::force).
/// - With ProxyParams::seen_footprint, the tool is a sphere, not a point: beside the ray through its leading point, twelve rays
///   parallel to the push at 0.5, 0.7 and 0.85 R from its centre line (30 degrees apart, one
///   read a tick, free and in contact; in contact each searches from the sphere's own point on
///   it, where the proxy rests, to the device's) find the seen surface under the sphere's own
///   surface there. Where the rays that meet a surface surround the centre line (no gap of 180 degrees
///   between them), they hold the sphere as they would a rigid ball: a hole narrower than the
///   tool holds it on its rim, at most 0.13, 0.29 or 0.47 R deeper than the rim (where the rays
///   fall), a rigid ball's depth lying between. A surface met on one side only does not hold it
///   (the proxy does not slide sideways: beside a feature, the surface under the leading point
///   holds it). A groove or a corner narrower than the tool holds it on its walls, as a rigid
///   ball, before its leading point reaches the groove's line. A crack narrower than the tool over a floor it can see is not bridged: the
///   floor holds it.
/// - Across the axis, the proxy's move to the device's place is a push of its own: its line
///   through the sphere's leading point that way, seen from the proxy's centre, stops it kWallGap
///   R short of a wall it meets (one standing on the floor it rests on: the height field alone
///   would let it into the wall and then, where its leading point's ray met the wall's layers,
///   throw it onto the wall's top). What is left of the move slides it along the wall, and the
///   wall adds its own spring along its rendered normal's part across the contact's normal (two
///   planes, as the god-object of Zilles and Salisbury 1995). When the device comes out of the
///   surface along the axis with a wall holding the proxy (up along the wall), a contact along
///   the wall's inward normal begins from where the proxy stands, so the wall holds on.
///   A wall the line does not see (seen edge-on from above, see-through from the side) but whose
///   top the height field over the device would throw the proxy onto, more than R up in one
///   tick, holds it where it stands as a wall too.
/// - Over a convex edge: a face beyond, seen edge-on along the contact's axis, is looked for from
///   the device's centre, looking back along the proxy's slide; once the ball is less deep
///   past that face than past the one under it (for a convex solid the depth is the least over
///   its faces), and the face's seen normal faces the slide and the way to it is clear, the
///   contact begins along that face's inward normal. Where the face under it ends under load
///   with no face beyond found yet, the ball rolls over the face's last point (a sphere on a
///   point: R from it, where the friction cone about its normal there puts it) until a face
///   takes it or it lets go. On the lip the face's material, friction and touched Gaussians
///   (those at the lip) carry on: sliding off a soft, rough ledge the force no longer steps.
///   A seen solid's faces need not meet where the ball turns (the top seen from above overhangs
///   the side seen from the side), so over the device's next R / 4 of path the face beyond's
///   force is blended in from the ball's as it was, rolling over the point it pushed from.
/// Limits: a wall met by the line through the sphere's centre height only (a step lower than
/// that is climbed by the height field); no friction on the wall; no texture relief on a lip; a face beyond an
/// edge whose discs stand above the first face taller than the ball's centre is a wall that holds
/// it (the fidelity cube at 8 mm spacing with a 5 mm ball, as the ellipsoid proxy).
///
/// Frame and units: world, metres as the world's. render() does not allocate, lock, log or throw.

#include <Eigen/Core>
#include <array>
#include <numbers>
#include <span>

#include "gshaptics/collision/tool_ellipsoid.h"
#include "gshaptics/force/climb_ledger.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/force/friction_cone.h"
#include "gshaptics/force/material.h"
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
  /// The materials under the contact (force/material.h), followed by `follower` (owned by the
  /// caller, on the same world; nullptr: none): stiffness, damping, friction, viscosity,
  /// texture and vibration from each tick in contact on.
  void set_follower(MaterialFollower* follower) noexcept { follower_ = follower; }
  [[nodiscard]] const SeenSolid& solid() const noexcept { return solid_; }
  [[nodiscard]] const Eigen::Vector3d& position() const noexcept { return proxy_; }
  [[nodiscard]] const Eigen::Vector3d& contact_normal() const noexcept { return normal_; }
  /// The Gaussians that make the seen surface under the contact, after the last render(): the
  /// layers the leading point's ray composites up to its hit, in depth order, as the renderer
  /// weighs them (SeenSolid::hit_contacts()), those of weight at least 1/255 and
  /// at most kMaxContacts of them. Contact::k_min holds the layer's weight T_k alpha_k in (0, 1]
  /// (its share of what the eye sees there; the weights sum to at most 1), not a K_min: the seen
  /// solid has no overlap depth. Empty out of contact, and on ticks whose surface was held by the
  /// footprint's rays alone (the leading point's ray met nothing); on a lip, the face's layers
  /// at the lip (read once as the ball begins to roll over it). What the viewer draws as the
  /// touched Gaussians.
  [[nodiscard]] std::span<const Contact> contacts() const noexcept { return {contacts_.data(), contact_count_}; }
  static constexpr std::size_t kMaxContacts = 64;

 private:
  // The layers that make `hit` (the last first_inside() on scratch_, read right after it): the
  // touched Gaussians into contacts_ (contacts()) and, with a follower, their materials into
  // target_ (target_held_: some layer holds a material share). An overflowed search has none.
  void read_hit_layers(const SeenHit& hit) noexcept;
  // Free: the proxy moves straight toward the device; true when the seen solid stops it (a
  // contact begins: its axis and eye plane are set).
  bool begin_contact(const Eigen::Vector3d& device, double radius) noexcept;
  // The same for a push along the unit `u` for `len` from where the proxy stands.
  bool begin_contact_along(const Eigen::Vector3d& u, double len, double radius) noexcept;
  // In contact: the proxy on the seen surface along the contact's axis, over the device's leading
  // point; false when the device has come out of the surface.
  // `goal`: where the friction cone puts the proxy across the axis (the device without friction).
  bool hold(const Eigen::Vector3d& device, const Eigen::Vector3d& goal, double radius, double dt) noexcept;
  // A contact begun again along the unit `u` for `len` from where the proxy stands
  // (begin_contact_along), its friction cone restarted and the device held on it (hold(), which
  // sets in_contact_); false, and nothing changed but the footprint's tried reading, when it does
  // not begin. `continued`: the same surface's contact along a turned axis (follow_surface): the
  // proxy keeps its level and rises from there as a resting proxy does (climb(), its ledger
  // kept: a fresh one let it climb 7.7 mm unpaid in one tick on burger), rather than
  // starting on the surface or, where it rested below it, held that much deeper for the
  // whole contact (sunk_).
  bool restart_along(const Eigen::Vector3d& u, double len, const Eigen::Vector3d& device,
                     const Eigen::Vector3d& device_step, double radius, double dt, bool continued = false) noexcept;
  // In contact, after hold(): once the smoothed normal has turned kFollowAngle from the contact's
  // axis while the proxy slid across it more than kFollowSlide R this tick (from `before`) and
  // kFollowPath R since the axis was set (axis_from_), the
  // contact begins again along the normal from where the proxy stands and holds the device
  // (`device`, its `device_step` this tick) on that axis; the force's normal carries over.
  void follow_surface(const Eigen::Vector3d& device, const Eigen::Vector3d& before, const Eigen::Vector3d& device_step,
                      double radius, double dt) noexcept;
  static constexpr double kFollowAngle = 5 * std::numbers::pi / 180;  // rad: the sink stays under 0.004 R
  static constexpr double kFollowSlide = 0.002;  // R a tick
  static constexpr double kFollowPath = 0.25;    // R
  // Over a convex edge: looking back along the proxy's slide (slide_mem_) from the device's
  // centre, a face the ball is less deep past than `load` (its depth past the face
  // under it; +inf: the contact has just ended under load) takes the contact, begun along that
  // face's inward normal from just outside it. True when it did.
  bool turn_over_edge(const Eigen::Vector3d& device, const Eigen::Vector3d& device_step, double radius, double dt,
                      double load) noexcept;
  // A turn over an edge from the ball centred at `was` (the tick before it), the device at
  // `device`: the blend of blend_turn() begins.
  void begin_turn_blend(const Eigen::Vector3d& was, const Eigen::Vector3d& device, double radius) noexcept;
  // The force `f` (N) of the face beyond over the first kTurnBlend R of the device's path after a
  // turn over an edge (turn_left_; `step`: this tick's), blended in from the spring of the ball as
  // it was before the turn: where it was within R of the device, the ball rolls over the point
  // it pushed from (turn_pivot_: R from it, toward the device), whose spring is that tick's;
  // deeper, it stays where it was. A seen solid's faces need not meet: seen from above, the
  // cube's top overhangs its side by the side's discs seen edge-on, the side face takes the
  // contact about 40 deg round the edge, and the force turned 90 deg in one tick
  // (bench/RESULTS.md, ninetieth session). The damping is the coupling's; no friction on the ball
  // before (its spring's direction carries that tick's).
  Eigen::Vector3d blend_turn(const Eigen::Vector3d& f, const Eigen::Vector3d& device, const Eigen::Vector3d& velocity,
                             double step, double radius, double dt) noexcept;
  static constexpr double kTurnBlend = 0.25;  // R of the device's path
  // A contact ended under load while sliding (edge_load_, slide_mem_; `point`: its last contact
  // point, edge_point_), or it sank off the face (sank_through_lip, or ended with the load faded:
  // `point` is kept_point_), the device past `point` along the slide and within R of it, and no
  // deeper than it rested last tick (`rested`, m) plus kLipSlack R: the ball rolls over that
  // point (on_lip_). True when it does.
  bool begin_lip(const Eigen::Vector3d& device, const Eigen::Vector3d& point, double radius, double rested) noexcept;
  // On the lip: whether the ball still rolls on it (on_lip_), and true when a face beyond took
  // the contact this tick (turn_over_edge; it is held already).
  bool roll_over_lip(const Eigen::Vector3d& device, const Eigen::Vector3d& device_step, double radius, double dt) noexcept;
  // On the lip: the ball, where it rolled to last tick, meets a surface along the contact's axis
  // within R of its centre (the floor past a bump or a step down it rolled off),
  // a face across the axis (its seen normal within acos kEdgeAgree of it): that surface takes
  // the contact along the axis (restart_along; it is held already). True
  // when it does. A rigid ball lands there; without it, the ball rolled over a bump's lip on
  // seed 6's crisp cube until the device was R from it and the floor then held nothing.
  bool land_from_lip(const Eigen::Vector3d& device, const Eigen::Vector3d& device_step, double radius, double dt) noexcept;
  // Whether the seen surface a line along `u` met at `at` (`t` along it from its origin) is a face
  // facing `m` (unit): its seen normal over the normal's ring (SeenSolid::normal) within acos
  // kEdgeAgree of m, not one disc met edge-on (turn_over_edge, land_from_lip).
  [[nodiscard]] bool face_agrees(const Eigen::Vector3d& at, const Eigen::Vector3d& u, double t, const Eigen::Vector3d& m,
                                 double radius) noexcept;
  // On the lip's first tick: the layers of the face at the lip (seen along the contact's axis
  // kLipLook R back from it) into contacts_ (kept as lip_contacts_) and, with a follower, the
  // material's target there.
  void read_lip_layers(double radius) noexcept;
  static constexpr double kLipLook = 0.05;  // R
  // On the lip: the ball R from it, toward the friction cone's goal (the device's side without
  // friction), and the coupling's force along that line with the face's material.
  RenderOutput lip_output(const Eigen::Vector3d& device, const Eigen::Vector3d& device_step, const Eigen::Vector3d& velocity,
                          double radius, double dt) noexcept;
  // In contact: whether the face under the proxy ends or falls away within R ahead along its
  // slide (its footprint's rays ahead: kEdgeDrop), where turn_over_edge looks for a face beyond
  // (its look costs a search of the seen solid: burger's probe run's p99 rose from 11 to
  // 16-22 us when it looked on every tick of a slide).
  [[nodiscard]] bool edge_ahead(double radius) const noexcept;
  static constexpr double kEdgeDrop = 0.1;  // R
  // The unit direction of the proxy's last kEdgeSlidePath R of slide across the axis (slide_mem_);
  // zero when it slid less than kEdgeSlideMin R.
  [[nodiscard]] Eigen::Vector3d slide_direction(double radius) const noexcept;
  // In contact: the proxy's slide across the axis this tick (from `before`) into slide_mem_, and
  // its `load` (depth past the surface along the normal) into edge_load_.
  void track_slide(const Eigen::Vector3d& before, double radius, double load) noexcept;
  static constexpr double kEdgeSlidePath = 1.0;  // R: the slide's direction is its last this much of path
  static constexpr double kEdgeSlideMin = 0.1;   // R: a slide shorter than this has no direction
  static constexpr double kEdgeFacing = 0.7071;  // cos 45 deg: the face seen faces the slide
  static constexpr double kEdgeAgree = 0.866;   // cos 30 deg: the face's seen normal agrees with its shade
  static constexpr double kEdgeMargin = 0.02;    // R: the face beyond takes over once the ball is this much less deep past it
  static constexpr double kEdgeGap = 0.05;       // R: the new contact begins this far outside the face
  // R of slide on a face it turned onto before a ball in contact looks for the next edge: at a
  // capture's edge the two faces' discs cross, and the first face's overhang, seen from below
  // by the ball sliding down the second, is no edge to turn over (bench/RESULTS.md,
  // eighty-seventh session).
  static constexpr double kEdgeSettle = 2.0;
  // R of slide after a look that found no face to turn onto before the next: a look costs
  // searches of the seen solid, and ran on 4 % of burger's probe-run ticks, 1 in 8 of them
  // reading a normal (bench/RESULTS.md, eighty-eighth session). The turn comes at most this
  // much slide late.
  static constexpr double kEdgeLookStride = 0.02;
  static constexpr double kEdgeLoad = 0.05;      // R: a contact ended under more than this load looks beyond the edge
  // R: the lip holds a device this far short of it along the slide. The seen edge of a crisp
  // capture is rounded by a few tenths of a mm, so the contact's last point may lie ahead of the
  // device as the contact ends there; with none short of it allowed, a 5 mm ball slid over the
  // crisp 4 mm cube (synth --edge-sigmas 1.17) fell off the edge in one tick (2.1 N) and felt
  // nothing down the side face (bench/RESULTS.md, hundred-and-fifth session).
  static constexpr double kLipBehind = 0.2;
  // R of slide under less than kEdgeLoad R through which the last point it rested on under more
  // (kept_point_, kept_load_) is kept (track_slide; kept_lip()). On the crisp cube (synth --edge-sigmas
  // 1.17) the leading point's ray, just past the top face's end, met the side face's discs seen
  // edge-on 1-1.5 mm lower; the proxy sank onto them and the contact ended a tick or two later
  // with no load, so no lip began, and the ball fell off the edge (bench/RESULTS.md,
  // hundred-and-sixth session).
  static constexpr double kLipKeep = 0.1;
  // R: the most a lip may push deeper than the contact it follows did (k times 0.2 mm on a
  // 10 mm ball); a kept point deeper than that is no roll but a kick (begin_lip).
  static constexpr double kLipSlack = 0.02;
  // After the tick's hold (from `before`): in contact, a turn over an edge ahead or the slide
  // tracked (and a sink off the face's end: a lip); out of it just now, a turn onto a face beyond
  // or a lip. True when the ball is on a lip now (the caller renders lip_output).
  bool at_edge(const Eigen::Vector3d& device, const Eigen::Vector3d& before, const Eigen::Vector3d& device_step, double r,
               double dt, bool was_in_contact) noexcept;
  // In contact: the proxy sank (under kEdgeLoad R of load, within kLipKeep R of slide) to within
  // (1 - kEdgeLoad) R of the point it rested on under load (kept_point_): a rigid ball would
  // have rolled over that point rather than through it; so it does (begin_lip).
  [[nodiscard]] bool sank_through_lip(double radius) const noexcept;
  // Whether a point it rested on under more than kEdgeLoad R is kept (kept_point_: the load
  // fell below that within the last kLipKeep R of slide).
  [[nodiscard]] bool kept_lip(double radius) const noexcept;
  // In contact: where the proxy gets across the contact's axis on its way to `goal` (the goal's
  // own place along the axis kept): stopped by a wall of the seen solid that its move across
  // meets (its line seen from the proxy's centre), then sliding along the wall once (a second
  // wall stops it); sets wall_ (zero: no wall held it).
  Eigen::Vector3d slide_across(const Eigen::Vector3d& goal, double radius) noexcept;
  static constexpr double kWallGap = 1e-3;      // R: a wall stops the proxy this far short of it
  static constexpr double kWallDepth = 0.1;     // R: a wall this far inside the sphere still holds it
  static constexpr double kMaxClimb = seen_footprint::kMaxClimb;  // R: the height field rising more in one tick is a wall
  static constexpr double kSlideMin = 1e-4;     // R: a move across the axis shorter than this is not searched
  // Where the proxy rests this tick (depth from the eye plane): the surface's `rest`, risen from
  // last tick's by at most seen_footprint::rise_allowance of the `slide` across the axis (m,
  // world) and, under load, by what ledger_ says is paid for (ClimbLedger::rise_room).
  // `continued`: a contact's first tick after a turn of its axis (restart_along), which climbs
  // from the proxy's own level as any later tick does.
  [[nodiscard]] double climb(double rest, const Eigen::Vector3d& slide, double radius, bool continued) const noexcept;
  void forget_ledger() noexcept;  // a new contact, or none: no credit, deficit or reaction
  // With a follower: this tick's material at the resting proxy (its contact point `contact`),
  // applied to the coupling and the friction cone (before the force). Returns the kinetic
  // friction coefficient the coupling's force uses (the proxy's own without a follower).
  double apply_material(const Eigen::Vector3d& contact, double radius) noexcept;
  // A contact's output, on a face or a lip: the proxy, the coupling's force `f` (N, world) with
  // the material's viscosity and texture added at `contact` (with a follower), the touched count.
  RenderOutput contact_output(const Eigen::Vector3d& f, const Eigen::Vector3d& contact, const Eigen::Vector3d& velocity,
                              double radius, double dt) noexcept;

  // The normal's reading at the resting point `point` (`depth` from the eye plane) into
  // target_normal_: all its rays for a contact's first, one ray a tick for the later ones.
  void read_normal(const Eigen::Vector3d& point, double radius, double depth) noexcept;
  static constexpr double kNormalTau = 0.005;   // s
  static constexpr double kNormalPath = 0.5;    // R: and over this much of the proxy's slide
  static constexpr double kNormalReuse = 0.05;  // R
  static constexpr double kTrendPath = 4.0;     // R: the normal's turn per slide is followed over this much of it
  static constexpr double kNormalEye = 8;       // R: the normal's rays look from at most this far back
  static constexpr double kGuessMargin = 0.25;  // R: the layers first read reach this past the last hit
  static constexpr double kEyeMargin = 0.25;    // R: the contact's eye plane, this far in front of the surface behind
  // The footprint: ray k lies at kRingRadius[k % 3] R from the centre line, at 30 k degrees.
  static constexpr int kRingRays = seen_footprint::kRays;
  static constexpr const double (&kRingRadius)[3] = seen_footprint::kRadius;
  static constexpr double kRingLook = 1.0;      // R: free footprint rays look this far past the tick's motion
  static constexpr double kRingAxisCos = 0.9986;  // cos 3 deg: a free push turning more forgets the footprint
  static constexpr double kRingDrift = 0.1;     // R: a reading taken this far across is forgotten
  static constexpr double kRingLate = seen_footprint::kLate;  // R: a footprint met later than its refresh and this does not hold
  static constexpr double kSunkSlack = seen_footprint::kSunkSlack;  // R: a new contact's surface deeper behind than its motion and this is sunk_
  // Free: the next ray of the footprint read along u, past the tick's motion `len` by kRingLook R;
  // then how far the sphere moves before rays around it hold it (< 0: it is past them; +inf: not
  // within the look).
  double free_ring(const Eigen::Vector3d& u, double radius, double len, bool leaving) noexcept;
  // In contact: the next footprint ray over the device (centre `device`, `foot` on the eye plane)
  // read against the surface up to `limit` (depth from the eye plane); and where the footprint
  // holds the leading point (depth from the eye plane; +inf: nowhere).
  void read_ring(const Eigen::Vector3d& device, const Eigen::Vector3d& foot, double radius, double limit) noexcept;
  [[nodiscard]] double ring_support(const Eigen::Vector3d& device, double radius) const noexcept;
  // The normal of a sphere its footprint cradles (hold()): the contact's axis, reversed, from
  // this float of its leading point above that point's own surface on (R), wholly from kCradleFull.
  static constexpr double kCradleFrom = 0.05;  // R: the leading point's float above its surface where the cradle's normal starts
  static constexpr double kCradleFull = 0.3;   // R: and where it is the whole normal
  // Ray k's surface as a coordinate along ring_axis_, +inf when none was found or when it was
  // read more than kRingDrift R across from the tool's centre line through `centre`.
  [[nodiscard]] double ring_at(int k, const Eigen::Vector3d& centre, double radius) const noexcept;
  void forget_ring(const Eigen::Vector3d& axis) noexcept;
  // How far ahead of the centre plane the sphere's surface is at ray k's offset.
  [[nodiscard]] static double ring_lead(int k, double radius) noexcept;
  // The least of `support` (per footprint ray) at which the rays at or below it surround the
  // centre line (+inf: they never do).
  [[nodiscard]] static double holding(const std::array<double, kRingRays>& support) noexcept;
  [[nodiscard]] Eigen::Vector3d ring_offset(int k, const Eigen::Vector3d& u, double radius) const noexcept;
  SeenSolid solid_;
  SeenScratch scratch_;
  std::array<Contact, kMaxContacts> contacts_{};
  std::size_t contact_count_ = 0;
  ProxyParams params_;
  VirtualCoupling coupling_;
  FrictionCone friction_;
  FrictionStep friction_step_;
  MaterialFollower* follower_ = nullptr;
  MaterialField::Weights target_{};  // the material shares of the last hit (read_hit_layers)
  bool target_held_ = false;
  Eigen::Vector3d last_device_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d proxy_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_trend_ = Eigen::Vector3d::Zero();  // 1/m: the smoothed normal's turn per slide
  bool fresh_normal_ = false;  // a new contact: its first reading sets normal_ (hold())
  Eigen::Vector3d axis_ = Eigen::Vector3d::Zero();  // the contact's push direction
  Eigen::Vector3d wall_ = Eigen::Vector3d::Zero();  // the outward normal of a wall holding the proxy across the axis this tick
  Eigen::Vector3d eye_ = Eigen::Vector3d::Zero();   // a point of its eye plane
  Eigen::Vector3d target_normal_ = Eigen::Vector3d::Zero();  // the last reading
  SeenNormalReading normal_reading_;
  double last_hit_ = 0;  // the last hit's depth from the eye plane (NaN: none in this contact)
  double rest_ = 0;      // where the surface holds the leading point this tick, depth from the eye plane
  // A contact that begins with the device's leading point already past the surface by more than
  // this tick's motion brought it (seen along a new axis, a surface it did not cross: a faint
  // sheet seen obliquely): how much deeper than that surface the contact holds the proxy, so it
  // starts where the device is instead of snapping back with a force step (constant over the
  // contact: a spring with a fixed rest offset gives back no more than it took).
  double sunk_ = 0;
  // A contact restarted along a turned axis on the surface the proxy rests on (restart_along's
  // `continued`), until its first hold(): its proxy starts at its own level, not the surface's.
  // Measured in bench/RESULTS.md (eighty-fourth session): each turn of the axis over a dome had
  // made the climb still owed a permanent sink, and the force faded along the slide.
  bool continued_ = false;
  Eigen::Vector3d slide_mem_ = Eigen::Vector3d::Zero();  // m: the proxy's slide across the axis, its last kEdgeSlidePath R
  double edge_load_ = 0;  // m: the last tick in contact's depth past the surface along the normal
  Eigen::Vector3d edge_point_ = Eigen::Vector3d::Zero();  // the last tick in contact's contact point
  double kept_load_ = 0;  // m: the last load over kEdgeLoad R (kLipKeep)
  Eigen::Vector3d kept_point_ = Eigen::Vector3d::Zero();  // the contact point under it
  double lip_kept_ = std::numeric_limits<double>::infinity();  // m: slide since kept_point_ was taken
  Eigen::Vector3d lip_ = Eigen::Vector3d::Zero();      // the point the ball rolls over (on_lip_)
  Eigen::Vector3d lip_out_ = Eigen::Vector3d::Zero();  // the slide's direction when it began
  bool on_lip_ = false;
  // A turn's blend (blend_turn): the ball before it and the point it rolls over.
  Eigen::Vector3d turn_from_ = Eigen::Vector3d::Zero(), turn_pivot_ = Eigen::Vector3d::Zero();
  bool turn_on_pivot_ = false;
  double turn_left_ = 0;  // m: the device's path left to blend after it
  std::size_t lip_contacts_ = 0;  // the face's layers at the lip, in contacts_ (read_lip_layers)
  double edge_settle_ = 0;  // m: slide left before a ball in contact looks for the next edge (kEdgeSettle, kEdgeLookStride)
  Eigen::Vector3d axis_from_ = Eigen::Vector3d::Zero();  // where the proxy stood when the contact's axis was set
  double entry_motion_ = 0;  // the leading point's motion along the axis in the tick the contact began
  ClimbLedger ledger_;  // the proxy's own steps against the coupling, and the hand's payments
  double deficit_ = 0;  // m: how far the surface lies above where the proxy rests this tick
  double free_eye_ = 0;  // m: the last free push's eye behind the proxy (a guess; 0: none)
  // How far the seen surface under the leading point lies below where the proxy rests (0: its
  // ray holds it; the footprint holding it over a valley or a hole: deeper; < 0: above it, a rise
  // not yet paid for; +inf: no surface): the relief the proxy does not render, which the texture
  // tip reads.
  double under_ = 0;
  // The footprint's readings: each ray's surface as a coordinate along ring_axis_ (+inf: none
  // found), and the tool's centre when it was read.
  std::array<double, kRingRays> ring_at_{};
  std::array<Eigen::Vector3d, kRingRays> ring_from_{};
  // Each footprint ray's last search in contact (read_ring): its line's origin on the eye plane,
  // its eye, window and crossing t (+inf: none), reused while the line and eye stay (a resting
  // ball's rays over a faint patch composite dozens of layers a read).
  std::array<SeenLineMemo, kRingRays> ring_read_{};  // each footprint ray's last search
  static constexpr double kSameRay = 1e-9;  // R: a footprint ray's line or eye that has not moved
  Eigen::Vector3d ring_axis_ = Eigen::Vector3d::Zero();
  int ring_next_ = 0;
  bool started_ = false, in_contact_ = false;
};

}  // namespace gshaptics
