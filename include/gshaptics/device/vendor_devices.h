#pragma once
/// @file
/// Desktop haptic devices through their vendors' C libraries, loaded at run time (dlopen, see
/// vendor_library.h), so nothing proprietary is needed to build gshaptics:
///   - Force Dimension devices (omega.x, delta.x, sigma.x, Novint Falcon) through the DHD API;
///   - 3D Systems devices (Touch, Touch X, Phantom Premium) through the OpenHaptics HD API.
///
/// Only the C functions and constants used are declared, each as documented by the vendor:
/// Force Dimension SDK reference (dhdc.h: dhdOpenID, dhdGetPosition [m], dhdGetLinearVelocity
/// [m/s], dhdSetForce [N], dhdGetButton, dhdEnableForce, dhdGetStatus with DHD_STATUS_* indices
/// 0..9 stable since SDK 3.2); OpenHaptics Toolkit API Reference (hd.h, hdDefines.h:
/// HD_CURRENT_POSITION 0x2050 [mm], HD_CURRENT_VELOCITY 0x2051 [mm/s], HD_CURRENT_BUTTONS
/// 0x2000, HD_CURRENT_FORCE 0x2700 [N], HD_USABLE_WORKSPACE_DIMENSIONS 0x2551 [mm],
/// HD_NOMINAL_MAX_FORCE 0x2603 [N], HD_UPDATE_RATE 0x2600 [Hz], HD_FORCE_OUTPUT 0x4000,
/// HD_CALIBRATION_* 0x5000-0x5002).
///
/// Frames. Every device here reports in one *device frame*: right-handed, metres, origin at the
/// vendor's workspace centre, x to the user's right, y away from the user, z up. A
/// WorkspaceMapping then places that frame in the world. The vendor frames are:
///   - DHD: x towards the user, y to the right, z up, metres  -> device (y_d, -x_d, z_d);
///   - HD:  x to the right, y up, z towards the user, millimetres -> device (x_h, -z_h, y_h)/1000.
/// Forces use the same axis changes and are never scaled (N in, N out).
///
/// Threading: DhdDevice calls the DHD library from the servo thread (read: position, velocity,
/// buttons; write: force), as Force Dimension's own examples and CHAI3D do: those calls are the
/// device's USB transfer, the tick's only I/O. OpenHapticsDevice runs inside OpenHaptics' own
/// servo scheduler (hdScheduleAsynchronous) and exchanges samples and forces with the runtime's
/// servo thread through wait-free triple buffers; its callback zeroes the force by itself when the
/// runtime has not written for `command_timeout` (a stalled or dead servo thread).

#include <atomic>
#include <cstdint>
#include <string>

#include "gshaptics/device/haptic_device.h"
#include "gshaptics/device/device_link.h"
#include "gshaptics/device/triple_buffer.h"

namespace gshaptics {

/// DHD frame (x to the user, y right, z up) -> device frame. Also for velocities and forces.
[[nodiscard]] Eigen::Vector3d dhd_to_device(const Eigen::Vector3d& v) noexcept;
/// Device frame -> DHD frame.
[[nodiscard]] Eigen::Vector3d device_to_dhd(const Eigen::Vector3d& v) noexcept;
/// The rotation dhd_to_device applies, as a matrix (its columns: the DHD axes in the device
/// frame). Torques and the wrist's orientation frame turn with it.
[[nodiscard]] Eigen::Matrix3d dhd_axes_in_device() noexcept;
/// HD frame (x right, y up, z to the user), millimetres -> device frame, metres.
[[nodiscard]] Eigen::Vector3d hd_mm_to_device_m(const Eigen::Vector3d& mm) noexcept;
/// A force (N) in the device frame -> HD frame (N; no unit change).
[[nodiscard]] Eigen::Vector3d device_force_to_hd(const Eigen::Vector3d& f) noexcept;

/// What gshaptics knows of a DHD device type (dhdGetSystemType): the vendor's rated
/// translational force and translational workspace (a cylinder, diameter x height, m), as Force
/// Dimension's and Novint's product specifications give them.
struct DhdDeviceType {
  int system_type = -1;  ///< DHD_DEVICE_* (dhdc.h)
  std::string name;
  double rated_force = 0;         ///< N
  double workspace_diameter = 0;  ///< m
  double workspace_height = 0;    ///< m
  /// Rated torque of the active wrist, N m (CHAI3D's device table: delta.6 and sigma.7 0.2);
  /// 0: the type's rotation is not actuated.
  double rated_torque = 0;
};
/// The type table; an unknown code gets the family's lowest rating and smallest workspace.
[[nodiscard]] const DhdDeviceType& dhd_device_type(int system_type) noexcept;

/// A Force Dimension device through libdhd (DHD API).
class DhdDevice final : public HapticDevice {
 public:
  /// Loads the library (probe_dhd_library). `index`: which device, 0-based as dhdOpenID counts
  /// them. Throws InputError when the library is missing (the probe's explanation: file, places
  /// searched, what to install) or reports fewer devices than index + 1.
  explicit DhdDevice(int index = 0);
  ~DhdDevice() override;
  DhdDevice(const DhdDevice&) = delete;
  DhdDevice& operator=(const DhdDevice&) = delete;

  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  /// dhdOpenID; dhdGetStatus, and refuses (closes, InputError saying what to do) a device that
  /// is not powered, not connected, in error or in RESET mode (not calibrated); takes the force
  /// limit from the device type's rating (dhdGetSystemType), or dhdGetMaxForce when a lower
  /// software limit is set, and the workspace from the type; asks dhdHasActiveWrist (a wrist
  /// that renders torque: DeviceInfo::renders_torque, written with dhdSetForceAndTorque; its
  /// torque rating is not known here, so SafetyParams::tau_max limits it); measures the rate;
  /// commands zero force (and torque), then dhdEnableForce(on). Throws InputError naming the
  /// index and dhdErrorGetLastStr().
  void start(Nanos now) override;
  /// Position, velocity, the wrist's orientation (dhdGetOrientationFrame, when the library has
  /// it; identity otherwise) and buttons 0-3. A failed read returns the previous sample (same
  /// sequence), so the runtime's watchdog zeroes the force if the device stops answering.
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  /// dhdSetForceAndTorque on an active wrist, dhdSetForce otherwise (the torque is then not
  /// rendered; the servo counts it).
  void write(const Wrench& wrench, Nanos now) noexcept override;
  /// Zero force (and torque), force off, dhdClose.
  void stop(Nanos now) noexcept override;
  /// What dhdGetStatus said at start, with the device type, its force rating and the rate.
  [[nodiscard]] std::string status() const override;
  /// "saturated writes" (dhdSetForce returned DHD_MOTOR_SATURATED).
  [[nodiscard]] std::vector<DeviceCounter> counters() const override;
  /// dhdSetForce / dhdSetForceAndTorque calls that returned DHD_MOTOR_SATURATED in this session.
  [[nodiscard]] std::uint64_t saturated_writes() const noexcept { return saturated_.load(std::memory_order_relaxed); }
  [[nodiscard]] const DhdDeviceType& device_type() const noexcept { return type_; }

  struct Api;  // the DHD functions, resolved with dlsym

 private:
  void zero_output() noexcept;  // zero force (and torque on an active wrist)
  void wrist_torque_limit();    // DeviceInfo::max_torque of an active wrist (start())
  const Api* api_ = nullptr;
  int index_ = 0;
  char id_ = -1;
  bool open_ = false;
  DhdDeviceType type_;
  std::atomic<std::uint64_t> saturated_{0};
  DeviceInfo info_;
  DeviceSample last_;
  std::string status_;
};

/// A 3D Systems device through libHD (OpenHaptics HD API).
struct OpenHapticsParams {
  /// The device name as configured in the vendor's Touch Setup; empty: HD_DEFAULT_DEVICE.
  std::string device_name;
  /// The servo thread has not written a force for this long: the HD callback commands zero. s.
  double command_timeout = 0.05;
  /// A device that needs manual calibration (stylus in the inkwell) is waited for this long at
  /// start, polling its calibration inside a servo frame; then start() refuses. s.
  double calibration_wait = 5.0;
};

class OpenHapticsDevice final : public HapticDevice {
 public:
  /// Loads the library (probe_openhaptics_library); throws InputError when it is missing.
  explicit OpenHapticsDevice(const OpenHapticsParams& params = {});
  ~OpenHapticsDevice() override;
  OpenHapticsDevice(const OpenHapticsDevice&) = delete;
  OpenHapticsDevice& operator=(const OpenHapticsDevice&) = delete;

  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  /// hdInitDevice; reads the usable workspace, the nominal peak and continuous force, stiffness,
  /// output DOF and update rate into info(); starts the scheduler; checks the calibration inside
  /// a frame on the scheduler (hdScheduleSynchronous, as the vendor's Calibration example does),
  /// updates it when the device can do so itself, waits up to calibration_wait for manual
  /// input (inkwell) and otherwise refuses with InputError before any force is enabled; then
  /// schedules the servo callback and enables force output. Every start() after a stop() is a
  /// fresh session. Throws InputError with the HD error code.
  void start(Nanos now) override;
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  /// Zero force (waits up to 50 ms for the callback to apply it), stops the scheduler,
  /// unschedules the callback, disables the device.
  void stop(Nanos now) noexcept override;
  /// Calibration state and the nominal limits read at start.
  [[nodiscard]] std::string status() const override;
  /// "stale commands zeroed", "HD frame errors", "stops without a confirmed zero frame".
  [[nodiscard]] std::vector<DeviceCounter> counters() const override;
  /// Nominal max force, N (HD_NOMINAL_MAX_FORCE), after start; 0 before. Also info().max_force.
  [[nodiscard]] double max_force() const noexcept { return max_force_; }
  /// HD callbacks run so far, and how many of them zeroed a stale command.
  [[nodiscard]] std::uint64_t callbacks() const noexcept { return callbacks_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t stale_commands() const noexcept { return link_.stale_commands(); }
  /// Stops whose final zero-force frame the callback did not confirm within 50 ms.
  [[nodiscard]] std::uint64_t unconfirmed_stops() const noexcept { return unconfirmed_stops_.load(std::memory_order_relaxed); }

  struct Api;
  /// The HD scheduler callback's body (public for the C trampoline only).
  unsigned int servo_callback() noexcept;

 private:
  const Api* api_ = nullptr;
  OpenHapticsParams params_;
  unsigned int handle_ = 0xFFFFFFFFu;
  unsigned long schedule_ = 0;
  bool scheduled_ = false;
  DeviceInfo info_;
  std::string status_;
  double max_force_ = 0;
  DeviceLink link_;  // HD callback <-> servo thread; HD frame, mm converted to m
  std::atomic<bool> running_{false};
  std::atomic<std::uint64_t> callbacks_{0}, hd_errors_{0}, unconfirmed_stops_{0};
  std::atomic<bool> zero_applied_{false};
};

}  // namespace gshaptics
