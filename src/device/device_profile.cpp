#include "gshaptics/device/device_profile.h"

#include "gshaptics/error.h"

namespace gshaptics {

const std::vector<DeviceProfile>& device_profiles() {
  static const std::vector<DeviceProfile> profiles = [] {
    DeviceProfile desktop;
    desktop.name = "desktop";
    desktop.f_max = 3.3;
    desktop.stiffness = ProxyParams{}.stiffness;
    desktop.workspace = Eigen::Vector3d(0.16, 0.12, 0.07);
    desktop.source = "3D Systems Touch specifications: 3.3 N peak, X/Y/Z 1.26/2.31/1.02 N/mm, 160x120x70 mm";
    DeviceProfile room;
    room.name = "room";
    room.f_max = ForceParams{}.f_max;
    room.stiffness = ProxyParams{}.stiffness;
    room.source = "gshaptics defaults for arms and room-scale devices";
    return std::vector<DeviceProfile>{desktop, room};
  }();
  return profiles;
}

const DeviceProfile& device_profile(std::string_view name, const std::string& source) {
  std::string known;
  for (const DeviceProfile& p : device_profiles()) {
    if (p.name == name) return p;
    known += (known.empty() ? "" : ", ") + p.name;
  }
  throw InputError(source + ": unknown device profile '" + std::string(name) + "' (expected " + known + ")");
}

void apply_device_profile(const DeviceProfile& profile, double& f_max, ProxyParams& proxy, bool keep_f_max,
                          bool keep_stiffness) noexcept {
  if (!keep_f_max) f_max = profile.f_max;
  if (!keep_stiffness) proxy.stiffness = profile.stiffness;
}

bool fits_workspace(const DeviceProfile& profile, double robust_size) {
  if (profile.workspace.isZero(0)) return true;
  return robust_size <= profile.workspace.maxCoeff();
}

}  // namespace gshaptics
