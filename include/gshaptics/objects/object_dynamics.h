#pragma once
/// @file
/// Rigid-body dynamics of a scene's objects on MuJoCo (Todorov, Erez and Tassa 2012; Debian's
/// libmujoco 2.2.2): each object is a MuJoCo body with a free joint whose collision geometry is
/// the convex hull MuJoCo builds from RigidObject::hull_points, its inertia that of the given mass
/// spread uniformly over the hull; the static scene gives the support, a plane.
///
/// Contacts use MuJoCo's elliptic friction cone with impratio 100 (friction constraints stiffer
/// than the normal ones) and a stiffer impedance than MuJoCo's default (solimp 0.95 0.99 0.001):
/// a box under a steady push below mu m g holds within 1 mm over 400 ms, where the default
/// pyramidal cone creeps centimetres, and slides at (F - mu m g) / m within 5 % above it
/// (bench/RESULTS.md, tests/objects_test.cpp).
///
/// Threading: one thread steps the model (the servo thread: ObjectRenderer steps it inside its
/// render()); step(), apply_wrench() and the accessors never allocate, lock, log or throw. Other
/// threads read the poses through the ObjectPoseChannel it publishes to (lock-free).

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "gshaptics/device/triple_buffer.h"
#include "gshaptics/objects/rigid_object.h"

struct mjModel_;
struct mjData_;

namespace gshaptics {

/// The static support of the objects, world frame: a plane (the ground), plus the convex hulls
/// of chosen static parts of the scene (`--support`: a table top) that the objects can stand on,
/// slide off and fall from.
struct SupportPlane {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();      ///< on the plane, m
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();    ///< unit, pointing into free space (up)
  /// Each static support's hull points (world frame, m): MuJoCo builds a static convex body of each.
  std::vector<std::vector<Eigen::Vector3d>> hulls;
};

/// The plane under `objects`: normal `up` (unit, world), through the lowest hull point along
/// `up` of all of them, so each object rests on it or drops onto it as captured.
[[nodiscard]] SupportPlane support_under(std::span<const RigidObject> objects, const Eigen::Vector3d& up);

/// Two unit axes across `normal` (u, v): a point p's coordinates in a plane of that normal are
/// (u.p, v.p).
[[nodiscard]] std::array<Eigen::Vector3d, 2> support_axes(const Eigen::Vector3d& normal) noexcept;

/// A support plane fitted to the static scene (fit_support_plane).
struct SupportFit {
  SupportPlane plane;
  bool fitted = false;      ///< false: too few Gaussians near the objects (the plane is support_under's)
  std::size_t points = 0;   ///< Gaussians the fit kept
  double rms = 0;           ///< their distance to the plane, RMS, m
  double tilt = 0;          ///< the plane's normal from `up`, rad
};

/// The ground the objects stand on, fitted to the static scene: the opaque static Gaussians
/// (opacity >= kHullMinOpacity) around the footprints of `objects` (the rigid objects, or the
/// static supports they stand on when there are any: then the ground is the floor under the table) (each footprint widened by half
/// its size, at least 2 cm) and near the height of their lowest points (within a quarter of the
/// objects' height, at least 1 cm), fitted by least squares (the normal is the direction of least
/// spread) with the points farther than 2.5 median distances dropped twice. Falls back on
/// support_under() when fewer than 20 Gaussians are there or the fit turns more than 25 degrees
/// from `up` (not a ground). The normal points along `up`.
[[nodiscard]] SupportFit fit_support_plane(const CollisionWorld& static_world, std::span<const RigidObject> objects,
                                           const Eigen::Vector3d& up);

/// A cut object seated on the ground a capture shows around it. The capture never saw where an
/// object meets the ground, and a cut's hull (the 1-sigma tips of its opaque Gaussians) rarely
/// meets the fitted plane: large Gaussians poke their tips into it, or the cut's bottom lies above
/// it (a fire pit sunk in sand, cut above the sand). MuJoCo then pushes the object up and tilts
/// it, or drops it (as cut, the fire pit of firepit.ply moved 43 mm and turned 4 deg in its first
/// second untouched, its lowest tip 105 mm under the ground: bench/RESULTS.md, sixty-first
/// session). When the lowest hull point lies more than kBaseGap and at most kBaseReach of the
/// object's height (along the support's normal) from `support`'s plane: below it, the points
/// under the plane are raised onto it; above it, each convex piece whose lowest point lies within
/// kBaseBand of the height of the object's lowest gets its points' shadows on the plane added
/// (the hull reaches down to the ground). Farther either way is no seating (the plane is no
/// ground for it, or it stands on something else: --support). Only `hull_points` (and
/// `piece_ends`) change: its Gaussians, what the hand feels, stay as captured. Returns how far
/// the lowest hull point stood above the plane as cut (m; < 0: under it), 0 when nothing changed.
/// The caller chooses the objects: the session seats cuts, never a file object placed by its own
/// registration.
double seat_on_support(RigidObject& object, const SupportPlane& support);
inline constexpr double kBaseGap = 0.01;   ///< of the object's height along the support's normal
inline constexpr double kBaseReach = 0.5;  ///< of its height
inline constexpr double kBaseBand = 0.05;  ///< of its height

/// What the objects stand on, as every command builds it: the ground fitted around the objects
/// (or around the static `supports` when there are any, whose hulls join it: add_support_hulls),
/// and, with no static supports, each cut object (ObjectSpec::Cut kBox or kIndices) seated on
/// that ground (seat_on_support; `objects` change). `base[i]`: how far object i's lowest hull
/// point stood above the ground as cut, m (< 0: under it; 0: not seated).
struct ObjectSupport {
  SupportFit fit;        ///< fit.plane is without the supports' hulls
  SupportPlane plane;    ///< the dynamics' support: the fitted plane and the supports' hulls
  std::vector<double> base;
};
[[nodiscard]] ObjectSupport object_support(const CollisionWorld& static_world, std::vector<RigidObject>& objects,
                                           std::span<const RigidObject> supports);

/// Adds each of `supports`' convex pieces (RigidObject::piece, moved to the world by its rest
/// origin) to `plane.hulls`: the static bodies the objects stand on and fall from (a table top).
void add_support_hulls(SupportPlane& plane, std::span<const RigidObject> supports);

/// The dynamics' settings.
struct DynamicsParams {
  double timestep = 0.001;  ///< s: the servo period (or a multiple of it)
  double gravity = 9.81;    ///< m/s^2, along -SupportPlane::normal
  int stack = 0;            ///< MuJoCo's stack, mjtNums (<size nstack>); 0: MuJoCo's default
};

/// The MuJoCo model of a scene's objects, stepped at a fixed timestep.
class ObjectDynamics {
 public:
  /// Builds the MuJoCo model (objects at their rest pose, at rest). Throws InputError with
  /// MuJoCo's message when it rejects the model (for example, a hull of coplanar points), and
  /// for an empty `objects` or a non-positive timestep.
  /// `channel`: where each step's poses and applied wrenches go (the viewer, ROS and the logs
  /// subscribe to it); null: a channel of its own (channel()).
  ObjectDynamics(std::span<const RigidObject> objects, const SupportPlane& support, const DynamicsParams& params = {},
                 std::shared_ptr<ObjectPoseChannel> channel = nullptr);
  ~ObjectDynamics();
  ObjectDynamics(const ObjectDynamics&) = delete;
  ObjectDynamics& operator=(const ObjectDynamics&) = delete;

  [[nodiscard]] std::size_t size() const noexcept { return bodies_; }
  [[nodiscard]] const DynamicsParams& params() const noexcept { return params_; }
  [[nodiscard]] const SupportPlane& support() const noexcept { return support_; }
  /// Object i's body-frame pose and velocity now (world frame).
  [[nodiscard]] const BodyPose& pose(std::size_t i) const noexcept { return poses_.poses[i]; }
  /// Object i's centre of mass now, world, m; its mass, kg.
  [[nodiscard]] Eigen::Vector3d center_of_mass(std::size_t i) const noexcept;
  [[nodiscard]] double mass(std::size_t i) const noexcept;
  /// Simulated time since the start, s.
  [[nodiscard]] double time() const noexcept { return poses_.time; }

  /// Adds `force` (N, world) acting at `point` (world, m), plus the pure couple `couple` (N m,
  /// world), on object i for the next step(). Non-finite input is ignored.
  void apply_wrench(std::size_t i, const Eigen::Vector3d& force, const Eigen::Vector3d& point,
                    const Eigen::Vector3d& couple = Eigen::Vector3d::Zero()) noexcept;
  /// One MuJoCo step of params().timestep with the wrenches applied since the last step, which
  /// it then clears; publishes the new poses. Sleeping: once no object has moved more than
  /// kRestDrift (or turned more than kRestTurn) over kSleepSteps steps, a step with no wrench
  /// applied only advances the time (nothing could move them; MuJoCo's resting contacts chatter
  /// at ~1e-4 m/s without going anywhere); any wrench wakes them.
  void step() noexcept;
  /// Whether the last step() slept (see step()).
  [[nodiscard]] bool asleep() const noexcept { return slept_; }
  static constexpr double kRestDrift = 2e-5;  ///< m
  static constexpr double kRestTurn = 2e-4;   ///< rad
  static constexpr int kSleepSteps = 50;
  /// Back to the rest poses, at rest, time 0.
  void reset() noexcept;

  /// The poses, velocities and applied wrenches as of the last step (the value published).
  [[nodiscard]] const ObjectPoses& state() const noexcept { return poses_; }
  /// Where the poses are published after each step, for other threads.
  [[nodiscard]] ObjectPoseChannel& channel() noexcept { return *channel_; }
  /// MuJoCo warnings raised since the start (contact buffer full, bad state ...); a step that
  /// raised one keeps going as MuJoCo does.
  [[nodiscard]] static long warnings() noexcept;
  /// Whether MuJoCo raised an error (mju_error: its stack overflowed, ...) in a step or reset of
  /// this model: the dynamics stopped there, the objects stay where they were (still felt, no
  /// longer moved), the run goes on. MuJoCo's default would end the process.
  [[nodiscard]] bool failed() const noexcept { return failed_; }
  /// MuJoCo errors since the start (every model), and the last one's message (read it once the
  /// runs are over).
  [[nodiscard]] static long errors() noexcept;
  [[nodiscard]] static std::string last_error();

 private:
  void read_poses() noexcept;
  bool clear_wrenches() noexcept;  // true when one was not zero
  DynamicsParams params_;
  SupportPlane support_;
  mjModel_* model_ = nullptr;
  mjData_* data_ = nullptr;
  std::size_t bodies_ = 0;
  std::array<int, kMaxObjects> body_id_{};
  ObjectPoses poses_;
  std::shared_ptr<ObjectPoseChannel> channel_;
  int resting_steps_ = 0;  // consecutive steps with every object within the rest bounds of anchor_
  std::array<BodyPose, kMaxObjects> anchor_{};
  bool slept_ = false;
  bool failed_ = false;
};

/// How far each object goes untouched: `seconds` of dynamics from rest on a model of its own (the
/// objects' own weight only). An object that falls, slides or tips by itself does not stand on
/// the support as it was cut (a chunk of a larger thing, a ground fitted badly): the scene stops
/// looking like the capture as soon as a run starts.
struct UntouchedDrift {
  std::array<double, kMaxObjects> moved{};   ///< m, each object's body origin from rest
  std::array<double, kMaxObjects> turned{};  ///< rad, from rest
  /// Each object's pose at the end (where it settled, if it did; velocities as then).
  std::array<BodyPose, kMaxObjects> settled{};
};
[[nodiscard]] UntouchedDrift untouched_drift(std::span<const RigidObject> objects, const SupportPlane& support,
                                             const DynamicsParams& params, double seconds = 1.0);
/// An object moving more than this untouched (untouched_drift over 1 s) gets a warning.
inline constexpr double kUntouchedDriftWarn = 0.01;        ///< m
inline constexpr double kUntouchedTurnWarn = 5 * M_PI / 180;  ///< rad

/// The MJCF text of the model ObjectDynamics builds (for inspection: `--objects-mjcf`): one body
/// per object with its hulls as meshes (by density over their volumes when there are several),
/// the support plane and hulls, the options above. Throws InputError when MuJoCo rejects the
/// model it weighs a many-piece object with.
[[nodiscard]] std::string object_model_xml(std::span<const RigidObject> objects, const SupportPlane& support,
                                           const DynamicsParams& params);

}  // namespace gshaptics
