#pragma once
/// @file
/// The device layer: one interface for every haptic device the runtime drives (pose, velocity and
/// buttons in; wrench out), whatever it is: a simulated admittance device, a replayed log, a
/// mouse in a browser or a robot across a network.
///
/// Threading contract: the servo thread owns the device between HapticRuntime start and stop;
/// read() and write() are called from that thread only, once per tick each, and must not block,
/// allocate, lock, log or throw. info() is const and may be called from any thread.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "gshaptics/device/clock.h"

namespace gshaptics {

/// What the device reports at one tick. World frame (the frame the scene is registered into),
/// metres, seconds.
struct DeviceSample {
  /// Increments every time the device delivers new data. The runtime's watchdog trips when it
  /// stops changing (a stalled driver, a dead network link). 0: no data yet (the runtime
  /// neither uses the pose nor renders a force).
  std::uint64_t sequence = 0;
  Nanos stamp = 0;  ///< when the data was measured, ns on the runtime's clock
  Eigen::Vector3d position = Eigen::Vector3d::Zero();                  ///< tool centre point, m
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();     ///< tool frame -> world
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();                  ///< m/s
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();          ///< rad/s, world frame
  /// Force the user applies, N, world frame, when the device measures or simulates it (zero
  /// otherwise). Logged only; the force model does not use it.
  Eigen::Vector3d user_force = Eigen::Vector3d::Zero();
  /// Torque the user applies about the tool centre point, N m, world frame, when the device
  /// measures it (an admittance device's force/torque sensor; zero otherwise).
  Eigen::Vector3d user_torque = Eigen::Vector3d::Zero();
  std::uint32_t buttons = 0;  ///< bit i set: button i pressed
};

/// The wrench the runtime commands, world frame, at the tool centre point.
struct Wrench {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   ///< N
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();  ///< N m (zero: the paper renders force only)
};

/// What an admittance-type device is commanded: where its tool centre point should be, world
/// frame. The device's own position servo tracks it.
struct Setpoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< m
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< m/s (feed-forward)
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< tool frame -> world
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();       ///< rad/s, world frame (feed-forward)
};

/// Whether a device's position sensing is calibrated (vendor libraries report it; simulated and
/// networked devices have nothing to calibrate).
enum class Calibration : std::uint8_t {
  kNotApplicable,  ///< nothing to calibrate (simulated, replayed, streamed)
  kCalibrated,     ///< the vendor library says it is calibrated
  kNeedsUser,      ///< the user must act (inkwell, reset position): no force is rendered
  kUnknown,        ///< the library does not say
};

/// Static facts about a device. The vendor drivers fill the limits in start() (that is when
/// their libraries answer); read them after start.
struct DeviceInfo {
  std::string name;
  double max_rate_hz = 10000;  ///< highest servo rate the device accepts, Hz
  /// Where max_rate_hz comes from ("vendor library", "measured", "device type", "default").
  std::string rate_source = "default";
  /// Where the tool centre may be, world frame, m. Outside it the runtime commands zero force.
  Eigen::AlignedBox3d workspace{Eigen::Vector3d::Constant(-1e300), Eigen::Vector3d::Constant(1e300)};
  /// Peak force the device may be commanded, N; +inf: no limit of its own (simulated devices).
  /// The safety layer's limit is min(this, the configured F_max), whatever the options say.
  double max_force = std::numeric_limits<double>::infinity();
  /// Force the device may hold continuously, N (its motors heat up above it); +inf: none known.
  /// The safety layer bounds the time-averaged force by it (SafetyParams::continuous_window).
  double max_continuous_force = std::numeric_limits<double>::infinity();
  /// Highest stable stiffness the vendor gives, N/m; 0: not given.
  double max_stiffness = 0;
  /// Highest damping the device renders without chattering, N s/m; 0: not given. The passivity
  /// controller's cap (servo/passivity.h, passivity_damping_cap).
  double max_damping = 0;
  /// Where max_force and max_continuous_force come from (e.g. "HD_NOMINAL_MAX_FORCE"), for the
  /// run summary; empty: no limit of its own.
  std::string limit_source;
  /// Round trip between the runtime and the device's amplifier, s: the age of a position read plus
  /// the time a written force takes to act (a network link, a device-side loop). 0: none known.
  /// The passivity observer pairs each force with the motion it acted on this much later.
  double transport_delay = 0;
  /// Admittance-type: the device measures the user's force (DeviceSample::user_force) and takes
  /// position setpoints (HapticDevice::write_setpoint), like the paper's HapticGiant. Such a device
  /// can be driven with RuntimeConfig::control = kAdmittance.
  bool admittance = false;
  /// Admittance-type: the force sensor's range, N per axis; a reading at it is a saturated sensor
  /// and stops the run. +inf: none known.
  double force_sensor_range = std::numeric_limits<double>::infinity();
  /// The device renders torque (6-DoF output). When false the runtime sends force only and
  /// counts the ticks whose torque it dropped (RuntimeStats::torque_dropped_ticks).
  bool renders_torque = false;
  /// Peak torque the device may be commanded, N m; +inf: no limit of its own. The safety layer's
  /// torque limit is min(this, SafetyParams::tau_max).
  double max_torque = std::numeric_limits<double>::infinity();
  /// Where max_torque comes from (e.g. "dhdGetMaxTorque"), for the run summary; empty: none.
  std::string torque_limit_source;
  Calibration calibration = Calibration::kNotApplicable;
};

/// An event a device counted during a session (for the run summary), e.g. writes the device
/// saturated or malformed network messages.
struct DeviceCounter {
  std::string name;
  std::uint64_t count = 0;
};

/// A haptic device as the runtime sees it.
class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  [[nodiscard]] virtual const DeviceInfo& info() const noexcept = 0;
  /// Called once on the servo thread before the first tick (time `now`). May throw InputError
  /// (a device that cannot start); the runtime then does not start.
  virtual void start(Nanos now) = 0;
  /// The newest data at time `now`. A device with nothing new returns its previous sample
  /// (same sequence). Never blocks.
  [[nodiscard]] virtual DeviceSample read(Nanos now) noexcept = 0;
  /// Commands a wrench, applied until the next write. In admittance control the runtime still
  /// writes the environment's force on the virtual tool (for display and feed-forward); an
  /// admittance-type device may ignore it.
  virtual void write(const Wrench& wrench, Nanos now) noexcept = 0;
  /// Admittance control: the position the device should be at, held until the next call. Called
  /// before write() on every tick the device is driven in admittance control. Impedance-type
  /// devices ignore it (the default).
  virtual void write_setpoint(const Setpoint& setpoint, Nanos now) noexcept {
    (void)setpoint;
    (void)now;
  }
  /// Called once on the servo thread after the last tick, after a zero wrench was written.
  virtual void stop(Nanos now) noexcept = 0;
  /// True when the device has nothing more to give (a replay at its end); the runtime then stops.
  [[nodiscard]] virtual bool finished() const noexcept { return false; }
  /// One line on the device's own state for people (vendor status, calibration, link); empty:
  /// nothing to say. Not for the servo thread.
  [[nodiscard]] virtual std::string status() const { return {}; }
  /// What the device counted in its current or last session (saturated writes, stale commands,
  /// reconnects); only non-zero counts need be listed. Not for the servo thread.
  [[nodiscard]] virtual std::vector<DeviceCounter> counters() const { return {}; }
};

}  // namespace gshaptics
