#pragma once
/// @file
/// Device classes: the force limit, coupling stiffness and workspace a class of haptic device can
/// render, so that a scene is felt within what the hardware gives.

#include <Eigen/Core>
#include <string>
#include <string_view>
#include <vector>

#include "gshaptics/force/force_model.h"
#include "gshaptics/force/proxy_renderer.h"

namespace gshaptics {

/// What a class of device renders. Values are the published figures of a representative device
/// (cited per profile); a specific device may differ, and explicit options override a profile.
struct DeviceProfile {
  std::string name;
  double f_max = 30;        ///< peak force, N (SafetyParams::f_max, every model)
  double stiffness = ProxyParams{}.stiffness;  ///< proxy coupling stiffness k_c, N/m
  /// Workspace extents (width, height, depth), m; zero: no bound (room scale).
  Eigen::Vector3d workspace = Eigen::Vector3d::Zero();
  std::string source;       ///< where the figures come from
};

/// The known profiles:
/// - "desktop": a 3D Systems Touch class device: 3.3 N peak force, 1 N/mm stiffness (its
///   smallest axis: X 1.26, Y 2.31, Z 1.02 N/mm), a 160 x 120 x 70 mm workspace (3D Systems,
///   Touch specifications, 2016). A Novint Falcon (8.9 N, 10 cm cube) is of the same class.
/// - "room": a tracked arm or room-scale device: 30 N, 1000 N/m, no workspace bound (the
///   defaults of ForceParams and ProxyParams).
[[nodiscard]] const std::vector<DeviceProfile>& device_profiles();

/// The profile called `name`; throws InputError naming `source` (an option) and the known names.
[[nodiscard]] const DeviceProfile& device_profile(std::string_view name, const std::string& source);

/// Applies `profile` to a session's force limit `f_max` (N, the safety layer's) and the proxy's
/// coupling stiffness, except the ones the caller set explicitly (`keep_f_max`,
/// `keep_stiffness`). The one place a profile is applied: the CLI's --device-profile and
/// Python's device_profile= both call it.
void apply_device_profile(const DeviceProfile& profile, double& f_max, ProxyParams& proxy, bool keep_f_max = false,
                          bool keep_stiffness = false) noexcept;

/// True when a scene of `robust_size` (world units, metres after registration) fits the
/// profile's workspace (always true without a bound).
[[nodiscard]] bool fits_workspace(const DeviceProfile& profile, double robust_size);

}  // namespace gshaptics
