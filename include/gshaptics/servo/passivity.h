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
/// capped at what the device renders without chattering (passivity_damping_cap: the device's own
/// DeviceInfo::max_damping, else 20 N s/m; under admittance control the virtual tool's) and applied only above
/// `min_speed` (below it no damping dissipates anything). Two rules keep it from being felt where
/// it should not be: it never acts on a zero force (free space stays free), and while the force
/// pushes along the motion it may cancel that component at most, never reverse it (the hand is
/// never pulled into the surface; a deficit left over is paid back over the next ticks), and a
/// deficit carried over from before the contact (left at a release) is paid back with a damping
/// force no larger than the force it corrects (what the coming tick would give, and a deficit run
/// up within the contact, are always dissipated in full): a stale deficit met at the next touch
/// doubles the touch's force at most instead of knocking at the clamp. The safety
/// layer's limits apply after it, and the observer counts the force actually sent.
///
/// Reset: when the force held is zero the environment holds no energy (the proxy sits on the
/// device; the paper's penalty has no memory), so a positive E is dropped there and a deficit is
/// kept: a long passive contact cannot mask an active one later (the observer's drift that
/// Hannaford & Ryu discuss), and a deficit left at release is paid back over the next contact.
///
/// Transport delay (a network link, a device-side loop): a force sent at tick k acts at the device
/// d_down later, and the position read at tick j was measured d_up earlier. With the round trip
/// n = (d_up + d_down) / T ticks known (DeviceInfo::transport_delay), the observer pairs each
/// displacement it reads with the force that was acting at the device while it happened, the one
/// sent n ticks before the previous read: the energy at the device's port, exactly, known n ticks
/// late. The controller then predicts over the forces still in flight as well (the energy they will
/// take at the current velocity). This is the one-port form of the time-delay power network of
/// Artigas, Ryu and Preusche 2010 ("Time domain passivity control for position-position
/// teleoperation architectures", Presence 19(5)); without it an observer on the renderer's side
/// of a delay pairs each force with the wrong motion and calls an oscillating wall passive.
///
/// Threading: one servo thread; every call is allocation-free and noexcept (the force history is
/// reserved by the constructor).

#include <Eigen/Core>
#include <span>
#include <vector>

namespace gshaptics {

struct TickRecord;

/// The damping cap when neither the option nor the device gives one, N s/m: what desktop devices
/// render without chattering (CHAI3D's device table: 20-40 N s/m).
inline constexpr double kDefaultPassivityMaxDamping = 20;

/// Parameters of the passivity observer and controller. SI units.
struct PassivityParams {
  bool enabled = true;       ///< observe and control (false: observe only)
  /// Cap on the controller's damping, N s/m (>= 0); 0: the device's own (passivity_damping_cap).
  double max_damping = 0;
  double min_speed = 1e-4;   ///< below this device speed the controller does not act, m/s
  /// Longest round trip the observer can pair across, ticks (sizes its force history).
  int max_delay_ticks = 1000;
};

/// The controller's decision for one tick.
struct PassivityStep {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< the force with the damping term, N
  double damping = 0;  ///< alpha applied, N s/m (0: none)
};

/// The damping cap in force, N s/m: the option's when given (> 0), lowered to the device's own when
/// that is lower; the device's when only it gives one (> 0); else kDefaultPassivityMaxDamping.
/// A stiff, heavy device (the simulated ideal device, an admittance virtual tool) renders far more
/// damping than a desktop device: with the desktop cap a release at speed there gives energy back
/// (15 N released at 0.1 m/s needs 150 N s/m; the Truck's probe run, issue 73 item 6).
[[nodiscard]] double passivity_damping_cap(double option, double device) noexcept;

class PassivityController {
 public:
  /// Reserves the force history (params.max_delay_ticks + 1 forces).
  explicit PassivityController(const PassivityParams& params = {});
  /// Forget the energy and the last tick (at the start of a run); `delay_ticks`: the round trip
  /// between sending a force and reading the motion it caused, ticks (clamped to
  /// [0, max_delay_ticks]; 0: the device applies each force before the next read).
  void reset(int delay_ticks = 0) noexcept;
  /// At the start of a tick: the observer accounts the interval that just ended, the last force
  /// sent times the device's displacement to `position` (m). Call only with a finite position.
  void account(const Eigen::Vector3d& position) noexcept;
  /// Before the safety layer: `force` (N) with the damping that keeps the energy predicted over
  /// the coming tick of `dt` s at `velocity` (m/s) from going negative. Unchanged when disabled.
  [[nodiscard]] PassivityStep correct(const Eigen::Vector3d& force, const Eigen::Vector3d& velocity,
                                      double dt) const noexcept;
  /// After the safety layer: the force actually sent this tick (held at the device until the next
  /// one arrives there).
  void sent(const Eigen::Vector3d& force) noexcept;
  /// The observed energy, J (< 0: the environment has been active).
  [[nodiscard]] double energy() const noexcept { return energy_; }
  [[nodiscard]] const PassivityParams& params() const noexcept { return params_; }
  /// Sets the damping cap, N s/m (> 0; at start, once the device is known: passivity_damping_cap).
  void set_damping_cap(double cap) noexcept { if (cap > 0) cap_ = cap; }
  [[nodiscard]] double damping_cap() const noexcept { return cap_; }
  [[nodiscard]] int delay_ticks() const noexcept { return delay_; }

 private:
  // The force sent `age` ticks ago (0: the newest).
  [[nodiscard]] const Eigen::Vector3d& force_sent(int age) const noexcept;
  PassivityParams params_;
  double cap_ = kDefaultPassivityMaxDamping;
  double energy_ = 0;
  double stale_ = 0;  // the part of a deficit carried over a zero-force hold not yet paid, J (<= 0)
  bool have_position_ = false;
  int delay_ = 0;
  Eigen::Vector3d last_position_ = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> forces_;  // ring of the last delay_ + 1 forces sent
  std::size_t newest_ = 0;
};

/// The work the proxy's own steps did on the virtual coupling over a run, J.
struct ProxyStepWork {
  double stored = 0;  ///< the positive steps' sum (>= 0): energy the proxy put into the coupling
  double net = 0;     ///< every step's sum (< 0: the proxy's steps took more out than they put in)
};

/// The work the proxy's own steps did on the virtual coupling over a run's `ticks`: over each pair
/// of consecutive ticks that both hold a proxy contact (TickRecord::constraints > 0), the
/// coupling's force on the device (the force model's output, `desired`, N, averaged over the two
/// ticks: exact for a linear spring while the device stands) dotted with the proxy's step (m).
/// What the positive steps store is energy the hand did not put in: a god-object's own step
/// moves toward the device and stores none (Zilles and Salisbury 1995), and the passivity
/// observer sees it only when the hand is given it back. With the device moving during a step the
/// average is an estimate: on the bundled Truck's probe runs the god-object on the ellipsoids
/// reads 90-290 mJ stored, -72 to +228 mJ net (seeds 1-3). Zero for models without a proxy (the paper's
/// penalty). Offline, over a whole log; allocates nothing.
[[nodiscard]] ProxyStepWork proxy_step_work(std::span<const TickRecord> ticks) noexcept;

}  // namespace gshaptics
