#pragma once
// Shared by the device tests (vendor_devices_test, haply_device_test): a wall-time-bounded wait,
// a pose in contact with the bundled Truck, and a real-time runtime config for a device test.

#include <chrono>
#include <thread>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "support/ellipsoid_params.h"

namespace gshaptics::test {

/// Polls `done()` every millisecond until it is true or `seconds` of wall time pass.
template <class F>
bool eventually(F done, double seconds = 5.0) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return done();
}

/// The centre of the largest opaque (alpha > 0.9) Gaussian of `world`: a tool there touches it.
inline Eigen::Vector3d contact_point(const CollisionWorld& world) {
  const CollisionGaussian* g = nullptr;
  for (const CollisionGaussian& c : world.gaussians())
    if (c.opacity > 0.9f && (g == nullptr || c.semi_axes[0] > g->semi_axes[0])) g = &c;
  return g == nullptr ? Eigen::Vector3d::Zero() : Eigen::Vector3d(g->center[0], g->center[1], g->center[2]);
}

/// 1 kHz, a 5 cm spherical tool, `seconds` long, normal scheduling (CI has no privileges), the
/// proxy on the Gaussians' ellipsoids: these tests hold the device still at a Gaussian's centre
/// (contact_point()) from the first tick, where the ellipsoid proxy places itself outside and
/// pushes; the seen solid is seen from the tool's approach, and a device that never moved has none.
inline RuntimeConfig device_test_config(double seconds) {
  RuntimeConfig c;
  c.renderer = ProxyModelSpec{ellipsoid_params(), nullptr};
  c.rate_hz = 1000;
  c.duration = seconds;
  c.tool.semi_axes = Eigen::Vector3d::Constant(0.05);
  c.realtime.servo_priority = 0;
  c.realtime.worker_priority = 0;
  return c;
}

}  // namespace gshaptics::test
