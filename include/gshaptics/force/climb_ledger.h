#pragma once
/// @file
/// The seen proxy's climb, paid for: an account of what the proxy's own steps put into the
/// virtual coupling, and the reaction through which the hand pays for a rise still owed.
///
/// A god-object's step never stretches the coupling (Zilles and Salisbury 1995), so the spring
/// stores only what the hand put in. The seen proxies rest on a height field along the contact's
/// axis; where it rises under a loaded proxy (a slope, a step, a footprint ray that meets a surface
/// late) the proxy would rise away from the device and the spring gain F . dx the hand never paid,
/// which the hand gets back when it lets go (bench/RESULTS.md, seventy-fourth to seventy-sixth
/// sessions: on the bundled Truck the passivity controller at its cap).
///
/// The ledger books, over the ticks of one contact, the coupling's force (two ticks' trapezoid)
/// dotted with the proxy's step: a fall toward the device or a slide against the normal's lean
/// earns credit, a rise away from it spends it (book()). Under load the proxy rises only as far as
/// the credit and the normal's lean against its slide pay for (rise_room()). A rise still owed past
/// kOweFloor tool scales is charged to the hand by reaction(): a force across the normal against
/// the device's slide, the slope a rigid sphere climbs onto a step that high (sqrt(2 d / R)) times
/// the normal force, and what the hand does against it is credit (pay()). A still hand pays nothing
/// and the proxy keeps its level. An energy account with dissipation where it runs short, as the
/// time-domain passivity observer of Hannaford and Ryu (2002), kept on the proxy's motion.
///
/// Units: N, m, J, s; world frame. Nothing here allocates, locks, logs or throws.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>

#include "gshaptics/force/seen_solid.h"

namespace gshaptics {

class ClimbLedger {
 public:
  /// A fall's credit is kept up to the normal force times this much rise, in tool scales.
  static constexpr double kCreditPath = 0.2;
  /// A rise owed up to this many tool scales is not charged (the seen surface's own relief at the
  /// scale of its Gaussians; a material's texture tip renders it).
  static constexpr double kOweFloor = 0.05;
  /// The steepest slope the reaction renders, and how fast it reaches it (s).
  static constexpr double kPaySlope = seen_footprint::kClimbSlope;
  static constexpr double kPayRamp = 0.02;
  /// The reaction is at most this times the device's speed across the normal (N s/m): near rest
  /// a bounded damper, never a Coulomb force on the velocity's sign.
  static constexpr double kPayDamping = 1000.0;

  /// A new contact, or none: no credit, no force booked, no reaction.
  void forget() noexcept {
    booked_ = false;
    credit_ = 0;
    fn_ = 0;
    pay_slope_ = 0;
    last_force_.setZero();
    reaction_.setZero();
    torque_.setZero();
  }
  /// The hand's work against last tick's reaction over its step since (`device_step`, m) is credit,
  /// and against last tick's torque on the device (torque_on_device()) over its turn since
  /// (`device_turn`, rotation vector, rad, world frame): a compound tool turned onto a surface lifts
  /// the proxy through its lever, paid by the hand's turn (the tool's own rigid lever, no spring).
  void pay(const Eigen::Vector3d& device_step, const Eigen::Vector3d& device_turn = Eigen::Vector3d::Zero()) noexcept {
    credit_ -= reaction_.dot(device_step) + torque_.dot(device_turn);
  }
  /// Records the torque commanded on the device this tick (N m, world frame, about the tool's
  /// centre point), which the next pay() credits against the device's turn.
  void torque_on_device(const Eigen::Vector3d& torque) noexcept { torque_ = torque; }
  /// How far the proxy may rise along -`axis` this tick (m) with its `slide` across the axis (m),
  /// under the unit outward `normal`: the step may put no more than the credit into the coupling,
  /// F_n (step . n) <= credit. +inf without load. Negative where the slide alone moves the proxy
  /// out along the normal by more than the credit pays for (an axis far off the normal, over a
  /// surface that does not fall away with the slide): the proxy must then come that far toward
  /// the device along the axis, or its slide would push the hand out for free.
  [[nodiscard]] double rise_room(const Eigen::Vector3d& slide, const Eigen::Vector3d& normal,
                                 const Eigen::Vector3d& axis) const noexcept {
    if (!(fn_ > 0) || !(normal.squaredNorm() > 0)) return std::numeric_limits<double>::infinity();
    const double c = std::max(-axis.dot(normal), 1e-3);
    return (credit_ / fn_ - slide.dot(normal)) / c;
  }
  /// Books one tick: the proxy's `step` since the last tick (m), the coupling's `force` on the
  /// device this tick (N), the unit `normal` it was rendered along, the tool's `scale` (m). The
  /// first tick of a contact only records its force.
  void book(const Eigen::Vector3d& step, const Eigen::Vector3d& force, const Eigen::Vector3d& normal,
            double scale) noexcept {
    if (booked_) credit_ -= 0.5 * (last_force_ + force).dot(step);
    last_force_ = force;
    booked_ = true;
    fn_ = std::max(0.0, force.dot(normal));
    credit_ = std::min(credit_, kCreditPath * scale * fn_);
  }
  /// This tick's reaction on the device (N) for a rise still owed, `deficit` (m), with the device's
  /// `velocity` (m/s) across the unit `normal`, the tool's `scale` (m) and the tick `dt` (s): the
  /// slope sqrt(2 (deficit - kOweFloor scale) / scale), at most kPaySlope and rising or falling
  /// by at most kPaySlope over kPayRamp (it opposes the slide, so a slow fall only dissipates; at
  /// once, a rise owed that one tick's reading missed made burger's probe run buzz, 4.4 N at
  /// 250 Hz: bench/RESULTS.md, ninetieth session), times the normal force booked this tick; at most
  /// kPayDamping times the speed across; against the motion across. Call after book().
  [[nodiscard]] Eigen::Vector3d reaction(double deficit, const Eigen::Vector3d& velocity, const Eigen::Vector3d& normal,
                                         double scale, double dt) noexcept {
    const double owed = deficit - kOweFloor * scale;
    const double slope = owed > 0 && scale > 0 ? std::min(std::sqrt(2 * owed / scale), kPaySlope) : 0.0;
    const double ramp = kPaySlope * std::max(dt, 0.0) / kPayRamp;
    pay_slope_ = std::clamp(slope, pay_slope_ - ramp, pay_slope_ + ramp);
    reaction_.setZero();
    const Eigen::Vector3d across = velocity - velocity.dot(normal) * normal;
    const double speed = across.norm();
    const double f = std::min(pay_slope_ * fn_, kPayDamping * speed);
    if (f > 0) reaction_ = -(f / speed) * across;
    return reaction_;
  }
  /// J: what the proxy's falls and the hand's payments earned, less its rises (capped above).
  [[nodiscard]] double credit() const noexcept { return credit_; }

 private:
  bool booked_ = false;
  double credit_ = 0;
  double fn_ = 0;         // N: the coupling's force along the normal this tick
  double pay_slope_ = 0;  // the slope reaction() renders
  Eigen::Vector3d last_force_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d reaction_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_ = Eigen::Vector3d::Zero();  // N m on the device, last tick
};

}  // namespace gshaptics
