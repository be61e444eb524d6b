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

#include <array>

#include "gshaptics/collision/compound_tool.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/force_model.h"

namespace gshaptics {

/// What a renderer produced at one tick. World frame, SI units.
struct RenderOutput {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< force on the tool (device), N
  /// Torque on the tool about its tool centre point, N m (compound tools; zero for one
  /// ellipsoid at the TCP).
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
  QueryCounts counts;                               ///< of the tick's contact query
  QueryStatus status = QueryStatus::kOk;
  /// Where the renderer holds the tool: the proxy's centre (m, world); the device's own centre
  /// for renderers without a proxy.
  Eigen::Vector3d proxy = Eigen::Vector3d::Zero();
  std::uint8_t constraints = 0;  ///< constraint planes holding the proxy (0..3)
  /// With a material map (force/material.h): what a vibrotactile device plays. The texture
  /// force's RMS over the last 20 ms, N (MaterialFollower::texture_rms), and the material's
  /// vibration level in contact, [0, 1] (Material::vibration, blended); 0 without.
  float texture_rms = 0;
  float vibration = 0;
};

/// The torque about `tcp` (world, m) of `force` (N) applied at the surface point of `tool` that
/// faces the contact pushing it, i.e. whose outward normal is -force: (surface_point(-F) - tcp) x F,
/// N m. Zero for a sphere centred on the TCP and for a zero force. The contact moment of a
/// renderer whose force acts along the contact normal (the proxy's coupling, the paper's eq. 11).
[[nodiscard]] Eigen::Vector3d contact_torque(const ToolEllipsoid& tool, const Eigen::Vector3d& tcp,
                                             const Eigen::Vector3d& force) noexcept;

class ForceRenderer {
 public:
  virtual ~ForceRenderer() = default;
  /// Short name ("paper", ...), as on the command line.
  [[nodiscard]] virtual std::string_view name() const noexcept = 0;
  /// One tick: the tool ellipsoid where the device is now (world frame, m), its velocity (m/s)
  /// and the time since the previous tick (s, > 0).
  virtual RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept = 0;
  /// One tick with a compound tool (collision/compound_tool.h): its `parts` posed in the world,
  /// the tool centre point `tcp` (world, m), the TCP's velocity (m/s) and the tool's angular
  /// velocity (rad/s, world). The torque is about the TCP. Renderers that take one ellipsoid
  /// (renders_compound() false) render a single part at the TCP with render(), with the torque
  /// of that force applied at the part's surface point facing the contact (contact_torque();
  /// zero for a sphere), and report kInvalidTool for anything else; callers check
  /// renders_compound() at set-up.
  virtual RenderOutput render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                                       const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                                       double dt) noexcept;
  /// True when render_compound() takes several parts and parts off the TCP (after set_tool()).
  [[nodiscard]] virtual bool renders_compound() const noexcept { return false; }
  /// The compound tool render_compound() will be given, in the tool frame (set-up, before the
  /// loop; CollisionWorker calls it). Renderers that keep the tool's own state (the proxy) build
  /// it here and may allocate or throw InputError; the default ignores it.
  virtual void set_tool(const CompoundTool& tool) { (void)tool; }
  /// The contacts of the last render() (valid until the next call); Contact::part names the
  /// part of a compound tool.
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
///
/// With a compound tool it sums eq. 7-11 part by part (one ForceModel, so one set of filters, per
/// part; each part's velocity is v + omega x (c_j - x_tcp)), and the torque about the TCP is
/// sum_j (p_eff,j - x_tcp) x F_j, with p_eff,j the part's softmax-weighted centroid (eq. 8).
/// One sphere at the TCP is the paper's own case (no torque); one other ellipsoid at the TCP
/// (a disc) takes the compound path with its one part.
class PaperRenderer final : public ForceRenderer {
 public:
  PaperRenderer(const CollisionWorld& world, const ForceParams& force = {}, const QueryOptions& query = {});
  [[nodiscard]] std::string_view name() const noexcept override { return "paper"; }
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d& velocity, double dt) noexcept override;
  RenderOutput render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                               const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                               double dt) noexcept override;
  [[nodiscard]] bool renders_compound() const noexcept override { return true; }
  [[nodiscard]] std::span<const Contact> contacts() const noexcept override {
    return compound_ ? merged_.contacts() : query_.result().contacts();
  }
  void reset() noexcept override {
    model_.reset();
    for (ForceModel& m : part_models_) m.reset();
  }
  void set_executor(ParallelExecutor* executor, std::size_t min_candidates) override {
    query_.set_executor(executor, min_candidates);
  }
  [[nodiscard]] const ForceModel& model() const noexcept { return model_; }

 private:
  ContactQuery query_;
  ForceModel model_;
  std::array<ForceModel, kMaxToolParts> part_models_;
  ContactSet merged_;      // every part's contacts, tagged with the part
  bool compound_ = false;  // the last tick was render_compound() with more than one part or an offset
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
  RenderOutput render_compound(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& tcp,
                               const Eigen::Vector3d& velocity, const Eigen::Vector3d& angular_velocity,
                               double dt) noexcept override {
    return inner_.render_compound(parts, tcp, velocity, angular_velocity, dt);
  }
  [[nodiscard]] bool renders_compound() const noexcept override { return inner_.renders_compound(); }
  void set_tool(const CompoundTool& tool) override { inner_.set_tool(tool); }

 private:
  ForceRenderer& inner_;
};

}  // namespace gshaptics
