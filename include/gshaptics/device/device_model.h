#pragma once
/// @file
/// The simulated devices' models, in one place: the ideal mass-damper the main job's simulated
/// device renders (AdmittanceDevice, with the simulated user hand that drives it; paper Sec. IV-V)
/// and DeviceModel, below.
///
/// DeviceModel: a simulated haptic device that can go unstable, as real ones do. Impedance-type (the default):
/// a moving mass
/// with little physical damping, driven by the commanded force through a zero-order hold, read
/// through an encoder of finite resolution, commanded through a force output of finite
/// resolution, held by a human hand with its own impedance, and linked to the renderer through a
/// transport delay in each direction (a ROS link, a network, a slow driver).
///
/// Model (per axis, world frame, SI units), integrated in fixed substeps of `substep` seconds
/// (semi-implicit Euler; the default 10 us is a hundredth of a 1 kHz tick):
///   (m + m_h) a = F_cmd(t - delay_down) - (b + b_h) v + k_h (x_hand - x) + F_push
/// where F_cmd is the last force written (held between writes: the amplifier's zero-order hold),
/// rounded to `force_resolution` and limited to `max_force`. read(now) reports the position at
/// now - delay_up rounded to `encoder_resolution`, and the velocity as the backward difference of
/// two such positions one read apart (what device drivers do without a tachometer).
///
/// The sampled-wall analysis this model is built to reproduce: a virtual spring K with virtual
/// damping B, sampled every T and held, is passive iff b > K T / 2 + |B| (Colgate and Schenkel
/// 1997, "Passivity of a class of sampled-data systems: application to haptic interfaces",
/// J. Robotic Systems 14(1)); a delay d adds d to the hold's T/2 (the spring lags by T/2 + d),
/// so the limit stiffness of a plain wall is K = b / (T/2 + d). tests/stability_test.cpp
/// finds the limit on this model within 20 % of that prediction.
///
/// The hand: a mass-spring-damper gripping the device (mass, stiffness toward `hand_anchor`,
/// damping), plus a constant push. Measured ranges for a stylus or fingertip grip are a mass of a
/// few grams (fingertip) to a few hundred grams (hand and forearm), damping of a few N s/m and
/// stiffness of a few hundred N/m, all growing with grip force (Hajian and Howe 1997, "Identification
/// of the mechanical impedance at the human finger tip", J. Biomech. Eng. 119(1); Fu and
/// Cavusoglu 2012, "Human-arm-and-hand-dynamic model with variability analyses for a stylus-based
/// haptic interface", IEEE Trans. SMC-B 42(6)). The hand's damping adds to the device's and
/// makes walls more stable; the "hands-off" case (all zero) is the worst one, which is how
/// stability limits are usually stated.
///
/// Admittance-type (DeviceModelParams::causality = kAdmittance; the HapticGiant class of the
/// paper, Sec. IV): the same mass is a robot under a stiff position servo,
///   F_servo = position_gain (x_sp - x) + velocity_gain (v_sp - v),
/// that tracks the setpoint the runtime writes (HapticDevice::write_setpoint, through the same
/// delay and hold), and a force sensor between the hand and the robot reports the hand's force
/// (DeviceSample::user_force). Commanded wrenches are ignored.
///
/// Threading: as every HapticDevice (servo thread only); read() and write() never allocate (the
/// delay lines are sized in the constructor).

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "gshaptics/device/haptic_device.h"

namespace gshaptics {

// ---- The ideal device and the simulated hand (SimulatedDevice, the probe run) ----


/// Virtual mass-damper the admittance controller renders: m a = F_user + F_render - b v.
struct AdmittanceParams {
  double mass = 3.0;     ///< virtual mass, kg
  double damping = 20.0; ///< virtual damping, N s/m
  /// Admittance control's virtual tool in rotation (a 6-DoF handle): moment of inertia about any
  /// axis through the TCP, kg m^2, and rotational damping, N m s/rad (the same 0.15 s time
  /// constant as the translation's defaults; 0.3 N m of wrist torque turns it at 2 rad/s).
  double inertia = 0.015;
  double angular_damping = 0.15;
};

/// Translational state of the device's tool centre point (world frame).
struct DeviceState {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< m
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< m/s
};

/// Admittance device integrated with semi-implicit Euler (stable for the default parameters at
/// servo periods up to several ms).
class AdmittanceDevice {
 public:
  explicit AdmittanceDevice(const AdmittanceParams& params = {}, const DeviceState& initial = {})
      : params_(params), state_(initial) {}
  /// Advances by dt seconds under the sum of external forces (N, world frame).
  void step(const Eigen::Vector3d& external_force, double dt) noexcept;
  [[nodiscard]] const DeviceState& state() const noexcept { return state_; }
  void set_state(const DeviceState& s) noexcept { state_ = s; }

 private:
  AdmittanceParams params_;
  DeviceState state_;
};

/// The user's hand as a spring-damper pulling the device toward a target pose, with a force
/// limit (a person pushes with tens of newtons, not more).
struct UserHandParams {
  double stiffness = 600.0;  ///< N/m
  double damping = 40.0;     ///< N s/m
  double max_force = 60.0;   ///< N
};

/// Force the hand applies to the device (N, world frame).
[[nodiscard]] Eigen::Vector3d user_hand_force(const UserHandParams& params,
                                              const DeviceState& device,
                                              const Eigen::Vector3d& target_position,
                                              const Eigen::Vector3d& target_velocity) noexcept;

// ---- A device that can go unstable (the stability sweep) ----

/// The hand holding the device. SI units.
struct HandImpedance {
  double mass = 0;       ///< kg, moves with the device
  double stiffness = 0;  ///< N/m, toward DeviceModelParams::hand_anchor
  double damping = 0;    ///< N s/m
  /// Constant force the hand pushes with, N, world frame (on top of the spring).
  Eigen::Vector3d push = Eigen::Vector3d::Zero();
};

/// Impedance-type: the runtime commands force. Admittance-type: the runtime commands a position
/// setpoint and reads the user's force.
enum class Causality : std::uint8_t { kImpedance, kAdmittance };

struct DeviceModelParams {
  Causality causality = Causality::kImpedance;
  /// Admittance-type only: the robot's position servo. N/m and N s/m.
  double position_gain = 2e5;
  double velocity_gain = 1500;
  double mass = 0.1;        ///< kg, the device's moving mass at the tool centre point (each axis)
  double damping = 1.0;     ///< b, N s/m, the device's physical (viscous) damping
  double encoder_resolution = 0;  ///< m per count; 0: exact position
  double force_resolution = 0;    ///< N per count of the force output; 0: exact force
  /// Peak force the device can output, N (reported as DeviceInfo::max_force; the safety layer
  /// limits to it). +inf: none.
  double max_force = std::numeric_limits<double>::infinity();
  double delay_up = 0;      ///< s, device -> renderer (the position the runtime reads is this old)
  double delay_down = 0;    ///< s, renderer -> device (a written force acts this much later)
  double substep = 1e-5;    ///< s, physics step (> 0, <= 1 ms)
  double max_rate_hz = 10000;  ///< highest servo rate accepted (sizes the force delay line)
  HandImpedance hand;
  Eigen::Vector3d hand_anchor = Eigen::Vector3d::Zero();  ///< m, where the hand's spring is at rest
  Eigen::Vector3d initial_position = Eigen::Vector3d::Zero();  ///< m
  Eigen::Vector3d initial_velocity = Eigen::Vector3d::Zero();  ///< m/s
  /// The run ends (finished() turns true) after this much simulated time, s; 0: never.
  double duration = 0;
};

/// The simulated impedance device. Time zero is the `now` given to start(); the state restarts
/// from the initial position and velocity at every start().
class DeviceModel final : public HapticDevice {
 public:
  /// Throws InputError for a non-positive mass or substep, negative damping, resolutions or
  /// delays, a delay over 1 s, or a non-finite parameter.
  explicit DeviceModel(const DeviceModelParams& params);
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos now) override;
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  void write_setpoint(const Setpoint& setpoint, Nanos now) noexcept override;
  void stop(Nanos now) noexcept override;
  [[nodiscard]] bool finished() const noexcept override;

  /// The true (unquantised, undelayed) state, for measurements.
  [[nodiscard]] const Eigen::Vector3d& position() const noexcept { return x_; }
  [[nodiscard]] const Eigen::Vector3d& velocity() const noexcept { return v_; }
  /// The force the device's actuators apply now (after delay, quantisation and limit; the
  /// position servo's force on an admittance-type device), N.
  [[nodiscard]] const Eigen::Vector3d& applied_force() const noexcept { return applied_; }
  /// Work the device's output force has done on the mass since start, J (> 0: the renderer
  /// pushed energy into the hand and device; its growth over a contact is the instability).
  [[nodiscard]] double work_by_force() const noexcept { return work_; }
  [[nodiscard]] const DeviceModelParams& params() const noexcept { return params_; }

 private:
  struct Timed {
    Nanos t = 0;
    Eigen::Vector3d v = Eigen::Vector3d::Zero();  // force, or setpoint position
    Eigen::Vector3d w = Eigen::Vector3d::Zero();  // setpoint velocity
  };
  void enqueue(const Timed& command) noexcept;
  void integrate_to(Nanos now) noexcept;
  [[nodiscard]] Eigen::Vector3d position_at(Nanos t) const noexcept;
  [[nodiscard]] Eigen::Vector3d quantize(const Eigen::Vector3d& v, double step) const noexcept;

  DeviceModelParams params_;
  DeviceInfo info_;
  Nanos h_ = 0, t0_ = 0, t_ = 0, last_read_ = 0;
  Eigen::Vector3d x_, v_, applied_ = Eigen::Vector3d::Zero(), last_reported_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d setpoint_ = Eigen::Vector3d::Zero(), setpoint_velocity_ = Eigen::Vector3d::Zero();
  double work_ = 0;
  std::uint64_t sequence_ = 0;
  bool have_reported_ = false;
  // Position history for the upward delay (ring, one entry per substep).
  std::vector<Timed> history_;
  std::size_t history_head_ = 0, history_size_ = 0;
  // Commands in flight for the downward delay (ring, in write order).
  std::vector<Timed> commands_;
  std::size_t command_head_ = 0, command_size_ = 0;
};

}  // namespace gshaptics
