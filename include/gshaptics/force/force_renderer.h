#pragma once
/// @file
/// A haptic force renderer: the whole per-tick path from a tool pose to a force, with its
/// collision queries inside. The paper's penalty model (PaperRenderer: one contact query, then
/// eq. 7-11) is one; models that keep more state (a proxy) are others. Benchmarks, the fidelity
/// matrix and embedders drive any of them through this interface.
///
/// Threading: a renderer belongs to one thread (one device) and holds that device's state. It
/// may share its CollisionWorld with other renderers. render() never allocates, locks, logs or
/// throws.

#include <Eigen/Core>
#include <memory>
#include <span>
#include <string>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/force_model.h"

namespace gshaptics {

/// What a renderer produced at one tick. World frame, SI units.
struct RenderOutput {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< force on the tool (device), N
  QueryCounts counts;                               ///< of the tick's contact query
  QueryStatus status = QueryStatus::kOk;
  /// Where the renderer holds the tool: the proxy's centre (m, world); the device's own centre
  /// for renderers without a proxy.
  Eigen::Vector3d proxy = Eigen::Vector3d::Zero();
  std::uint8_t constraints = 0;  ///< constraint planes holding the proxy (0..3)
};

class ForceRenderer {
 public:
  virtual ~ForceRenderer() = default;
  /// Short name ("paper", ...), as on the command line.
  [[nodiscard]] virtual std::string_view name() const noexcept = 0;
  /// One tick: the tool ellipsoid where the device is now (world frame, m), its velocity (m/s)
  /// and the time since the previous tick (s, > 0).
  virtual RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept = 0;
  /// The contacts of the last render() (valid until the next call).
  [[nodiscard]] virtual std::span<const Contact> contacts() const noexcept = 0;
  /// Forgets all per-device state (a new run, a teleport).
  virtual void reset() noexcept = 0;
  /// Shares large queries' narrow phase with `executor` (ContactQuery::set_executor); renderers
  /// without a contact query ignore it. Called before the loop starts, never on the hot path.
  virtual void set_executor(ParallelExecutor* executor, std::size_t min_candidates) {
    (void)executor;
    (void)min_candidates;
  }
};

/// The paper's renderer: ContactQuery (broad + narrow phase, eq. 4-6) then ForceModel (eq. 7-11)
/// on the tool centre and velocity.
class PaperRenderer final : public ForceRenderer {
 public:
  PaperRenderer(const CollisionWorld& world, const ForceParams& force = {}, const QueryOptions& query = {})
      : query_(world, query), model_(force) {}
  [[nodiscard]] std::string_view name() const noexcept override { return "paper"; }
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept override;
  [[nodiscard]] std::span<const Contact> contacts() const noexcept override { return query_.result().contacts(); }
  void reset() noexcept override { model_.reset(); }
  void set_executor(ParallelExecutor* executor, std::size_t min_candidates) override {
    query_.set_executor(executor, min_candidates);
  }
  [[nodiscard]] const ForceModel& model() const noexcept { return model_; }

 private:
  ContactQuery query_;
  ForceModel model_;
};

/// A renderer that forwards to one the caller owns and keeps (it must outlive this one): for
/// handing a caller's renderer to a runtime that takes ownership of its renderer.
class BorrowedRenderer final : public ForceRenderer {
 public:
  explicit BorrowedRenderer(ForceRenderer& inner) noexcept : inner_(inner) {}
  [[nodiscard]] std::string_view name() const noexcept override { return inner_.name(); }
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept override {
    return inner_.render(tool, velocity, dt);
  }
  [[nodiscard]] std::span<const Contact> contacts() const noexcept override { return inner_.contacts(); }
  void reset() noexcept override { inner_.reset(); }
  void set_executor(ParallelExecutor* executor, std::size_t min_candidates) override {
    inner_.set_executor(executor, min_candidates);
  }

 private:
  ForceRenderer& inner_;
};

/// The force-model names renderer_spec() knows, for help texts: "proxy, paper".
[[nodiscard]] std::string_view force_model_names() noexcept;

/// True when renderer_spec() knows `name`.
[[nodiscard]] bool is_force_model(std::string_view name) noexcept;

}  // namespace gshaptics
