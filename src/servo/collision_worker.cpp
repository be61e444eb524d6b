#include "gshaptics/servo/collision_worker.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/error.h"

namespace gshaptics {

ToolShape tool_shape_for(const CompoundTool& tool) {
  ToolShape s;
  if (tool.is_single_at_tcp() && ToolEllipsoid::is_sphere(tool.parts[0].semi_axes)) {
    s.semi_axes = tool.parts[0].semi_axes;
    s.rotation = tool.parts[0].rotation;
  } else {
    s.compound = tool;
    s.semi_axes = Eigen::Vector3d::Constant(tool.largest_semi_axis());
  }
  return s;
}

CollisionWorker::CollisionWorker(const ToolShape& tool, std::unique_ptr<ForceRenderer> renderer, double nominal_dt,
                                 Clock& clock)
    : renderer_(std::move(renderer)), tool_(tool), nominal_dt_(nominal_dt), clock_(clock) {
  if (tool_.compound.count > 0) {
    tool_.compound.validate("tool");
    if (renderer_) renderer_->set_tool(tool_.compound);
    if (!tool_.compound.is_single_at_tcp() && renderer_ && !renderer_->renders_compound())
      throw InputError("the " + std::string(renderer_->name()) + " force renderer renders one ellipsoid at the tool "
                       "centre point; a compound tool (" + describe(tool_.compound) +
                       ") needs one that takes several (the proxy or the paper model)");
  }
}

CollisionWorker::CollisionWorker(const CollisionWorld& world, const ToolShape& tool, const ForceParams& force,
                                 const QueryOptions& query, double nominal_dt, Clock& clock)
    : CollisionWorker(tool, std::make_unique<PaperRenderer>(world, force, query), nominal_dt, clock) {}

ToolEllipsoid CollisionWorker::tool_at(const PoseCommand& pose) const noexcept {
  ToolEllipsoid t;
  t.center = pose.position;
  t.rotation = pose.orientation * tool_.rotation;
  t.semi_axes = tool_.semi_axes;
  return t;
}

bool CollisionWorker::step(PoseChannel& poses, ResultChannel& results) noexcept {
  if (!poses.read_if_new(pose_)) return false;
  // Render time is wall time (the monotonic clock), whatever clock drives the run: on simulated
  // time it is still what the query costs.
  MonotonicClock& wall = MonotonicClock::instance();
  const Nanos t0 = wall.now();
  // dt of the renderer's filters: time between the poses this worker answered. Poses the
  // worker skipped (it was busy) still count, so filters follow real time.
  double dt = nominal_dt_;
  if (have_last_) dt = std::clamp(to_seconds(pose_.stamp - last_stamp_), nominal_dt_ * 0.5, 0.1);
  RenderOutput f;
  if (tool_.compound.count > 0) {
    // Angular velocity from the orientation step (world frame): the rotation taking the last
    // orientation to this one, as an axis times an angle, per second.
    Eigen::Vector3d omega = Eigen::Vector3d::Zero();
    if (have_last_) {
      const Eigen::AngleAxisd step(pose_.orientation * last_orientation_.conjugate());
      const double angle = step.angle() > M_PI ? step.angle() - 2 * M_PI : step.angle();
      if (std::isfinite(angle)) omega = step.axis() * (angle / dt);
    }
    const int n = tool_.compound.posed(pose_.position, pose_.orientation, parts_);
    f = renderer_->render_compound({parts_.data(), std::size_t(n)}, pose_.position, pose_.velocity, omega, dt);
  } else {
    f = renderer_->render(tool_at(pose_), pose_.velocity, dt);
  }
  last_stamp_ = pose_.stamp;
  last_orientation_ = pose_.orientation;
  have_last_ = true;

  CollisionResult r;
  r.pose_sequence = pose_.sequence;
  r.pose_stamp = pose_.stamp;
  r.force = f.force;
  r.torque = f.torque;
  r.counts = f.counts;
  r.status = f.status;
  r.proxy = f.proxy;
  r.constraints = f.constraints;
  r.texture_rms = f.texture_rms;
  r.vibration = f.vibration;
  const Nanos t1 = wall.now();
  r.done = clock_.now();
  r.query_us = float(double(t1 - t0) * 1e-3);
  results.write(r);
  latency_.record(t1 - t0);
  steps_.fetch_add(1, std::memory_order_relaxed);
  if (observer_ != nullptr) observer_->on_result(pose_, renderer_->contacts(), r);
  return true;
}

}  // namespace gshaptics
