#include "gshaptics/objects/push_scenario.h"

#include <Eigen/Geometry>
#include <algorithm>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/device/simulated_device.h"
#include "gshaptics/error.h"
#include "gshaptics/objects/object_renderer.h"
#include "gshaptics/servo/simulated_runtime.h"

namespace gshaptics {
namespace {

// Forwards to the scene's ObjectRenderer and records each tick into storage reserved up front.
class PushRecorder final : public ForceRenderer {
 public:
  PushRecorder(ObjectRenderer& inner, const CollisionWorld& box, const Eigen::Vector3d& half, const ProbeTrajectory& path,
               std::size_t capacity)
      : inner_(inner), query_(box), half_(half), path_(path) {
    samples.reserve(capacity);
  }
  [[nodiscard]] std::string_view name() const noexcept override { return inner_.name(); }
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept override {
    const RenderOutput out = inner_.render(tool, velocity, dt);
    t_ += dt;
    if (samples.size() < samples.capacity()) samples.push_back(sample(tool));
    return out;
  }
  [[nodiscard]] std::span<const Contact> contacts() const noexcept override { return inner_.contacts(); }
  void reset() noexcept override { inner_.reset(); }
  std::vector<PushSample> samples;

 private:
  PushSample sample(const ToolEllipsoid& tool) noexcept {
    const BodyPose& pose = inner_.dynamics().pose(0);
    PushSample s;
    s.t = t_;
    Eigen::Vector3d v;
    path_.sample(t_, s.hand, v);
    s.device = tool.center;
    s.box = pose.position;
    s.box_velocity = pose.linear_velocity;
    s.box_turn = pose.rotation.angularDistance(Eigen::Quaterniond::Identity());
    s.push = -inner_.object_force(0);
    if (s.push.squaredNorm() > 0) {  // the tool at the box's proxy, in the box's frame
      ToolEllipsoid at = tool;
      at.center = pose.rotation.conjugate() * (inner_.object_proxy(0) - pose.position);
      at.rotation = pose.rotation.conjugate() * tool.rotation;
      if (query_.run(at) == QueryStatus::kOk)
        for (const Contact& c : query_.result().contacts()) s.k_min = std::max(s.k_min, c.k_min);
      s.box_depth = depth_into_box(at.center, tool.bounding_radius());
    }
    return s;
  }
  // How far a sphere of `radius` at `centre` (the box's frame) reaches into the box of half
  // extents half_ about its origin: radius less the box's signed distance at the centre.
  [[nodiscard]] double depth_into_box(const Eigen::Vector3d& centre, double radius) const noexcept {
    const Eigen::Vector3d q = centre.cwiseAbs() - half_;
    const double distance = q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
    return std::max(0.0, radius - distance);
  }
  ObjectRenderer& inner_;
  ContactQuery query_;
  Eigen::Vector3d half_;
  const ProbeTrajectory& path_;
  double t_ = 0;
};

void check(const PushScenario& s) {
  if (!(s.box_half.minCoeff() > 0) || !(s.mass > 0) || !(s.friction >= 0) || !(s.spacing > 0) ||
      !(s.tool_radius > 0) || !(s.duration > s.hold) || !(s.hold >= 0) || !(s.end > s.start) ||
      !(s.release >= 0) || !(s.release_time > 0))
    throw InputError("push scenario: sizes, mass, spacing, tool radius and release time must be > 0, friction and "
                     "release >= 0, duration > hold >= 0 and end > start");
}

// Mean push less m a over the ticks where the box slides (v_x above 2 cm/s on two ticks in a row).
void estimate_friction(PushRun& run) {
  double push = 0, accel = 0;
  for (std::size_t k = 1; k < run.samples.size(); ++k) {
    const PushSample &a = run.samples[k - 1], &b = run.samples[k];
    if (a.box_velocity.x() > 0.02 && b.box_velocity.x() > 0.02 && b.t > a.t) {
      push += b.push.x();
      accel += (b.box_velocity.x() - a.box_velocity.x()) / (b.t - a.t);
      ++run.sliding_ticks;
    }
  }
  if (run.sliding_ticks > 0)
    run.friction_estimate = (push - run.scenario.mass * accel) / run.sliding_ticks;
}

}  // namespace

PushRun run_push_scenario(const PushScenario& scenario, const std::function<void(double)>& progress) {
  check(scenario);
  ObjectSpec spec;
  spec.mass = scenario.mass;
  spec.friction = scenario.friction;
  spec.text = "push scenario box";
  const Eigen::Vector3d& h = scenario.box_half;
  const std::vector<RigidObject> objects{
      make_rigid_object(box_surface_gaussians(Eigen::Vector3d(0, 0, h.z()), h, scenario.spacing), spec, WorldConfig{})};
  // The floor: a slab whose top face (the discs' centres) is at z = -spacing / 20, under the box.
  const double slab = scenario.spacing;
  const CollisionWorld floor = CollisionWorld::build(
      box_surface_gaussians(Eigen::Vector3d(0.5 * (scenario.start + scenario.end), 0, -0.05 * scenario.spacing - slab),
                            Eigen::Vector3d(0.5 * (scenario.end - scenario.start) + 4 * h.x(), 4 * h.y(), slab),
                            scenario.spacing),
      WorldConfig{});
  DynamicsParams dp;
  dp.timestep = 1.0 / scenario.runtime.rate_hz;
  auto dynamics = std::make_shared<ObjectDynamics>(objects, support_under(objects, Eigen::Vector3d::UnitZ()), dp);
  const std::unique_ptr<ObjectRenderer> renderer =
      make_object_renderer(scenario.runtime.renderer, floor, objects, dynamics, scenario.runtime.query);

  const double z = h.z();
  const ProbeTrajectory path({{0, Eigen::Vector3d(scenario.start, 0, z)},
                              {scenario.hold, Eigen::Vector3d(scenario.start, 0, z)},
                              {scenario.duration, Eigen::Vector3d(scenario.end, 0, z)},
                              {scenario.duration + scenario.release_time,
                               Eigen::Vector3d(scenario.end - scenario.release, 0, z)}},
                             {}, scenario.tool_radius);
  SimulatedDeviceParams hand;
  hand.loop = false;
  SimulatedDevice device(path, hand);
  RuntimeConfig config = scenario.runtime;
  config.duration = scenario.duration + scenario.release_time;
  config.tool = ToolShape{};
  config.tool.semi_axes = Eigen::Vector3d::Constant(scenario.tool_radius);
  PushRecorder recorder(*renderer, *objects[0].body, h, path,
                        std::size_t((scenario.duration + scenario.release_time) * scenario.runtime.rate_hz) + 16);
  SimulatedRuntime runtime(device, config, std::make_unique<BorrowedRenderer>(recorder));
  runtime.run(progress);

  PushRun run;
  run.scenario = scenario;
  run.samples = std::move(recorder.samples);
  run.runtime = runtime.summary();
  run.travelled = dynamics->pose(0).position.x() - objects[0].rest_origin.x();
  for (const PushSample& s : run.samples) {
    run.deepest_k_min = std::max(run.deepest_k_min, s.k_min);
    run.deepest_box_depth = std::max(run.deepest_box_depth, s.box_depth);
  }
  for (const TickRecord& r : runtime.log().records()) {
    run.lowest_energy = std::min(run.lowest_energy, r.energy);
    run.peak_energy = std::max(run.peak_energy, r.energy);
  }
  run.friction_expected = scenario.friction * scenario.mass * dp.gravity;
  estimate_friction(run);
  return run;
}

}  // namespace gshaptics
