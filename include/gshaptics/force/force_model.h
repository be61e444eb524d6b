#pragma once
/// @file
/// Penalty force from a contact set (paper Sec. III-C, eq. 7-11), with the sign convention of
/// docs/design.md Sec. 5: the force pushes the tool from the contact centroid toward the tool centre.
///
/// Threading: a ForceModel holds one device's filter state; use one per device and thread.
/// update() never allocates, locks, logs or throws.

#include <Eigen/Core>
#include <limits>
#include <span>

#include "gshaptics/collision/contact_query.h"

namespace gshaptics {

/// Force-model parameters. Units: metres, seconds, newtons (world frame of the registration).
/// The smoothing factors of the paper are per tick; here they are time constants and converted
/// with the actual tick period: beta = 1 - exp(-dt / tau) (tau = 0 disables smoothing).
struct ForceParams {
  double k_base = 0.05;        ///< base stiffness, N per contact (eq. 9-10)
  double damping = 5.0;        ///< D, N s/m (eq. 10)
  /// Eq. 11's clamp on the force magnitude, N. +inf by default: the runtime's safety layer
  /// limits every renderer (SafetyParams::f_max and the device's own limit).
  double f_max = std::numeric_limits<double>::infinity();
  double tau_normal = 0.010;   ///< time constant of the normal EMA, s
  double tau_opacity = 0.010;  ///< time constant of the opacity EMA, s
  double tau_velocity = 0.005; ///< time constant of the tool-velocity filter, s
};

/// The filter state carried from tick to tick.
struct ForceState {
  Eigen::Vector3d n_smooth = Eigen::Vector3d::Zero();  ///< unit, valid when has_normal
  double alpha = 0;                                   ///< smoothed contact opacity alpha(t)
  Eigen::Vector3d v_filtered = Eigen::Vector3d::Zero();
  bool in_contact = false;
  bool has_normal = false;
  bool has_velocity = false;
};

/// Everything the force model computed at one tick (for logs and plots).
struct ForceOutput {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();     ///< F_out, N, world frame (eq. 11)
  double magnitude = 0;                                ///< |F_out|, N
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();    ///< n_smooth (zero without contact)
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  ///< p_eff (eq. 8)
  double k_eff = 0;                                    ///< N per contact (eq. 9)
  double elastic = 0;                                  ///< F_elastic = k_eff * N (eq. 10)
  double damping_along_normal = 0;                     ///< F_damp . n_smooth (eq. 10-11)
  std::size_t contacts = 0;
};

/// Converts a time constant to a per-tick EMA factor.
[[nodiscard]] double ema_factor(double tau, double dt) noexcept;

/// The paper's force model with per-device state.
class ForceModel {
 public:
  explicit ForceModel(const ForceParams& params = {}) : params_(params) {}

  /// One tick: contacts at time t, tool centre (world), tool velocity (world, m/s) and the
  /// time since the previous tick dt (s, > 0). Returns the clamped force along n_smooth.
  ForceOutput update(std::span<const Contact> contacts, const Eigen::Vector3d& tool_center,
                     const Eigen::Vector3d& tool_velocity, double dt) noexcept;

  /// Forgets all filter state (new device, new run).
  void reset() noexcept { state_ = {}; }
  [[nodiscard]] const ForceState& state() const noexcept { return state_; }
  [[nodiscard]] const ForceParams& params() const noexcept { return params_; }

 private:
  ForceParams params_;
  ForceState state_;
};

}  // namespace gshaptics
