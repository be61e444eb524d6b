#pragma once
/// @file
/// Workspace mapping for desktop devices: a device workspace of ~16 cm is mapped onto a region of
/// the scene by a scale and an offset, with a clutch that re-centres the mapping without moving
/// the tool in the scene, and optional rate control near the workspace edge that drifts the
/// mapping ("bubble" navigation, Dominjon et al., "The Bubble technique", IEEE VR 2005).
///
/// Frames: device coordinates (metres, the device's axes) map to world coordinates by
///   x_world = s R x_device + o,  v_world = s R v_device,
/// with s = `scale` (world metres per device metre), R = `rotation`, o the current offset.
/// Forces are NOT scaled: a 1 N scene force is 1 N in the hand whatever s (f_device = R^T f_world),
/// so the stiffness felt in the hand is the world coupling stiffness times s. Choose the world
/// stiffness so that k_c s stays within what the device renders (its passivity bound).
///
/// Threading: a mapping is owned by the servo thread; to_world()/to_device() do not allocate,
/// lock or throw.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>

#include "gshaptics/device/haptic_device.h"

namespace gshaptics {

struct WorkspaceMappingParams {
  double scale = 1.0;                                               ///< s, world m per device m (> 0)
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();     ///< R: device axes -> world axes
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();                 ///< o: world point of the device origin, m
  /// Button (bit index of DeviceSample::buttons) that holds the clutch; -1: no clutch.
  int clutch_button = -1;
  /// Rate control: beyond this distance from `bubble_center` (device frame, m) the mapping
  /// drifts outward at `bubble_gain` * (distance - radius) world m/s per device m. 0: off.
  double bubble_radius = 0;
  double bubble_gain = 0;
  Eigen::Vector3d bubble_center = Eigen::Vector3d::Zero();
};

class WorkspaceMapping {
 public:
  /// Throws InputError for scale <= 0 or non-finite parameters.
  explicit WorkspaceMapping(const WorkspaceMappingParams& params);

  /// The device's sample in the world frame; advances the clutch and the bubble drift by `dt`
  /// (s). While the clutch is held the world pose stays where it was when it engaged (velocity
  /// zero); on release the offset is re-anchored so the pose continues from there without a jump.
  [[nodiscard]] DeviceSample to_world(const DeviceSample& device, double dt) noexcept;
  /// The world wrench in device axes, unscaled; zero while the clutch is held.
  [[nodiscard]] Wrench to_device(const Wrench& world) const noexcept;

  [[nodiscard]] bool clutched() const noexcept { return clutched_; }
  [[nodiscard]] const Eigen::Vector3d& offset() const noexcept { return offset_; }
  [[nodiscard]] const WorkspaceMappingParams& params() const noexcept { return p_; }
  /// The world box a device box maps to (the box around its 8 mapped corners), for display.
  [[nodiscard]] Eigen::AlignedBox3d world_box(const Eigen::AlignedBox3d& device_box) const noexcept;

 private:
  WorkspaceMappingParams p_;
  Eigen::Matrix3d r_;
  Eigen::Vector3d offset_;
  bool clutched_ = false;
  Eigen::Vector3d frozen_ = Eigen::Vector3d::Zero();  // world position held while clutched
};

/// A device seen through a WorkspaceMapping: reads map to the world, writes map back (zero force
/// while clutched). A pose outside the wrapped device's own workspace is reported as NaN, which
/// the safety layer refuses (zero force, counted as an invalid pose). The wrapped device must
/// outlive this one.
class MappedDevice final : public HapticDevice {
 public:
  MappedDevice(HapticDevice& inner, const WorkspaceMappingParams& params);
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  void start(Nanos now) override;
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  void stop(Nanos now) noexcept override;
  [[nodiscard]] bool finished() const noexcept override { return inner_.finished(); }
  [[nodiscard]] std::string status() const override { return inner_.status(); }
  [[nodiscard]] std::vector<DeviceCounter> counters() const override { return inner_.counters(); }
  [[nodiscard]] const WorkspaceMapping& mapping() const noexcept { return mapping_; }

 private:
  HapticDevice& inner_;
  WorkspaceMapping mapping_;
  DeviceInfo info_;
  Nanos last_ = 0;
};

}  // namespace gshaptics
