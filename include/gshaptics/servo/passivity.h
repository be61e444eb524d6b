#pragma once
/// @file
/// Time-domain passivity observer and controller (Hannaford & Ryu 2002, "Time-domain passivity
/// control of haptic interfaces", IEEE Trans. Robotics and Automation 18(1)): the servo step
/// watches the energy that flows between the hand and the virtual environment and, when the
/// environment has given back more than it took (a delayed force, a stale result, a stiff wall
/// sampled too slowly), adds just enough damping to dissipate the difference. It needs no model
/// of the device or the environment, so it applies to every force model.
///
/// Observer: the device holds each tick's force F_k (N) while it moves from x_k to x_k+1 (a
/// zero-order hold), so the energy into the environment is counted from positions,
///   E <- E - F_k . (x_k+1 - x_k)        (J; > 0 while the environment is passive),
/// which includes the half tick the hold adds (the source of the b > K T / 2 condition of
/// Colgate & Schenkel 1997); a velocity-sampled sum F_k . v_k dt would miss it.
/// Controller (impedance causality): when the coming tick would leave E < 0 (predicted with the
/// device velocity v: E' = E - F . v dt), the force gets a damping term -alpha v with
/// alpha = -E' / (|v|^2 dt),
/// capped at `max_damping` (what the device renders without chattering) and applied only above
/// `min_speed` (below it no damping dissipates anything). Two rules keep it from being felt where
/// it should not be: it never acts on a zero force (free space stays free), and while the force
/// pushes along the motion it may cancel that component at most, never reverse it (the hand is
/// never pulled into the surface; a deficit left over is paid back over the next ticks). The
/// safety layer's limits apply after it, and the observer counts the force actually sent.
///
/// Reset: when the force held is zero the environment holds no energy (the proxy sits on the
/// device; the paper's penalty has no memory), so a positive E is dropped there and a deficit is
/// kept: a long passive contact cannot mask an active one later (the observer's drift that
/// Hannaford & Ryu discuss), and a deficit left at release is paid back at the next contact.
///
/// Threading: one servo thread; every call is allocation-free and noexcept.

#include <Eigen/Core>

namespace gshaptics {

/// Parameters of the passivity observer and controller. SI units.
struct PassivityParams {
  bool enabled = true;       ///< observe and control (false: observe only)
  double max_damping = 20;   ///< cap on the controller's damping, N s/m (>= 0)
  double min_speed = 1e-4;   ///< below this device speed the controller does not act, m/s
};

/// The controller's decision for one tick.
struct PassivityStep {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< the force with the damping term, N
  double damping = 0;  ///< alpha applied, N s/m (0: none)
};

class PassivityController {
 public:
  explicit PassivityController(const PassivityParams& params = {}) noexcept : params_(params) {}
  /// Forget the energy and the last tick (at the start of a run).
  void reset() noexcept {
    energy_ = 0;
    have_position_ = false;
    last_force_.setZero();
  }
  /// At the start of a tick: the observer accounts the interval that just ended, the last force
  /// sent times the device's displacement to `position` (m). Call only with a finite position.
  void account(const Eigen::Vector3d& position) noexcept;
  /// Before the safety layer: `force` (N) with the damping that keeps the energy predicted over
  /// the coming tick of `dt` s at `velocity` (m/s) from going negative. Unchanged when disabled.
  [[nodiscard]] PassivityStep correct(const Eigen::Vector3d& force, const Eigen::Vector3d& velocity,
                                      double dt) const noexcept;
  /// After the safety layer: the force actually sent this tick (held until the next account()).
  void sent(const Eigen::Vector3d& force) noexcept { last_force_ = force; }
  /// The observed energy, J (< 0: the environment has been active).
  [[nodiscard]] double energy() const noexcept { return energy_; }
  [[nodiscard]] const PassivityParams& params() const noexcept { return params_; }

 private:
  PassivityParams params_;
  double energy_ = 0;
  bool have_position_ = false;
  Eigen::Vector3d last_position_ = Eigen::Vector3d::Zero(), last_force_ = Eigen::Vector3d::Zero();
};

}  // namespace gshaptics
