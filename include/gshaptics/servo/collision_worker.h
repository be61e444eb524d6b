#pragma once
/// @file
/// The collision side of the runtime (paper Sec. IV: the "collision node"): takes the newest tool
/// pose from the servo loop, runs the broad + narrow phase and the force model, and publishes the
/// resulting force back. The servo loop never waits on it.
///
/// Threading contract: one CollisionWorker is driven by one thread at a time: its own worker
/// thread in the decoupled mode (the paper's, and the default), or the servo thread itself in the
/// inline mode. The two PoseChannel / ResultChannel hand-offs are single-producer single-consumer
/// triple buffers: the servo thread writes poses and reads results, the worker reads poses and
/// writes results. step() never allocates, locks, logs or throws.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <span>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/device/clock.h"
#include "gshaptics/servo/latency_histogram.h"
#include "gshaptics/device/triple_buffer.h"

namespace gshaptics {

/// A tool pose handed from the servo loop to the worker. World frame, metres.
struct PoseCommand {
  std::uint64_t sequence = 0;  ///< servo tick that read it (0: none yet)
  Nanos stamp = 0;             ///< when the device data was read, ns
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< tool frame -> world
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();               ///< m/s
};

/// A force computed for one pose, handed back to the servo loop.
struct CollisionResult {
  std::uint64_t pose_sequence = 0;  ///< the PoseCommand it answers (0: no result yet)
  Nanos pose_stamp = 0;             ///< its stamp: result age = now - pose_stamp
  Nanos done = 0;                   ///< when the force was ready, ns
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< force model output, N, world (eq. 11)
  Eigen::Vector3d torque = Eigen::Vector3d::Zero(); ///< about the tool centre point, N m, world (compound tools)
  QueryCounts counts;
  QueryStatus status = QueryStatus::kOk;
  float query_us = 0;  ///< broad + narrow phase + force model, microseconds
  Eigen::Vector3d proxy = Eigen::Vector3d::Zero();  ///< proxy centre (the pose's own centre without a proxy), m
  std::uint8_t constraints = 0;                     ///< constraint planes holding the proxy
  float texture_rms = 0;  ///< RenderOutput::texture_rms, N
  float vibration = 0;    ///< RenderOutput::vibration, [0, 1]
};

using PoseChannel = TripleBuffer<PoseCommand>;
using ResultChannel = TripleBuffer<CollisionResult>;

/// Shape of the tool, in the tool frame (the device's TCP frame): one ellipsoid at the TCP, or
/// a compound tool (collision/compound_tool.h) when `compound.count` > 0.
struct ToolShape {
  Eigen::Vector3d semi_axes = Eigen::Vector3d::Constant(0.01);  ///< m, all > 0
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  ///< ellipsoid axes in the tool frame
  /// Parts of a compound tool (count 0: the single ellipsoid above). Rendered with
  /// ForceRenderer::render_compound(), which gives the torque about the TCP too.
  CompoundTool compound;
};

/// The ToolShape of a compound tool: a single sphere at the TCP becomes the plain tool (its
/// torque about the TCP is zero); anything else stays compound, a single ellipsoid at the TCP
/// included (every renderer takes it, and render_compound() gives the torque of its off-centre
/// contact, e.g. a tilted disc touching with its rim).
[[nodiscard]] ToolShape tool_shape_for(const CompoundTool& tool);

/// Sees every result with its contacts, on the worker's thread right after step() computed it
/// (for viewers and network bridges). Must return quickly and never block; the contacts span is
/// valid only during the call.
class ResultObserver {
 public:
  virtual ~ResultObserver() = default;
  virtual void on_result(const PoseCommand& pose, std::span<const Contact> contacts,
                         const CollisionResult& result) noexcept = 0;
};

class CollisionWorker {
 public:
  /// Renders with `renderer` (any ForceRenderer: make_force_renderer(), or your own).
  /// `nominal_dt` is the servo period, s: the renderer's dt for the first pose and the lower
  /// bound of the dt between poses. Throws InputError for a compound tool (`tool.compound`)
  /// the renderer cannot render (ForceRenderer::renders_compound()).
  CollisionWorker(const ToolShape& tool, std::unique_ptr<ForceRenderer> renderer, double nominal_dt, Clock& clock);
  /// Renders with the paper's model (PaperRenderer with `force` and `query`).
  CollisionWorker(const CollisionWorld& world, const ToolShape& tool, const ForceParams& force,
                  const QueryOptions& query, double nominal_dt, Clock& clock);

  /// Runs the query and force model for the newest pose if one arrived since the last step and
  /// publishes the result; returns whether it did.
  bool step(PoseChannel& poses, ResultChannel& results) noexcept;

  /// The tool ellipsoid for a pose (world frame).
  [[nodiscard]] ToolEllipsoid tool_at(const PoseCommand& pose) const noexcept;
  void set_observer(ResultObserver* observer) noexcept { observer_ = observer; }
  /// Query + force time of each step, ns (written by the worker's thread, readable from any).
  [[nodiscard]] const LatencyHistogram& latency() const noexcept { return latency_; }
  [[nodiscard]] std::uint64_t steps() const noexcept { return steps_.load(std::memory_order_relaxed); }
  [[nodiscard]] const ForceRenderer& renderer() const noexcept { return *renderer_; }
  /// For set-up before the loop starts (e.g. ForceRenderer::set_executor).
  [[nodiscard]] ForceRenderer& renderer() noexcept { return *renderer_; }

 private:
  std::unique_ptr<ForceRenderer> renderer_;
  ToolShape tool_;
  double nominal_dt_;
  Clock& clock_;
  ResultObserver* observer_ = nullptr;
  PoseCommand pose_;
  Eigen::Quaterniond last_orientation_ = Eigen::Quaterniond::Identity();
  std::array<ToolEllipsoid, kMaxToolParts> parts_{};
  Nanos last_stamp_ = 0;
  bool have_last_ = false;
  LatencyHistogram latency_;
  std::atomic<std::uint64_t> steps_{0};
};

}  // namespace gshaptics
