#include "gshaptics/servo/collision_worker.h"

#include <algorithm>

namespace gshaptics {

CollisionWorker::CollisionWorker(const ToolShape& tool, std::unique_ptr<ForceRenderer> renderer, double nominal_dt,
                                 Clock& clock)
    : renderer_(std::move(renderer)), tool_(tool), nominal_dt_(nominal_dt), clock_(clock) {}

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
  last_stamp_ = pose_.stamp;
  have_last_ = true;
  const RenderOutput f = renderer_->render(tool_at(pose_), pose_.velocity, dt);

  CollisionResult r;
  r.pose_sequence = pose_.sequence;
  r.pose_stamp = pose_.stamp;
  r.force = f.force;
  r.counts = f.counts;
  r.status = f.status;
  r.proxy = f.proxy;
  r.constraints = f.constraints;
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
