#include "gshaptics/force/friction_cone.h"

#include <Eigen/Geometry>

namespace gshaptics {

FrictionStep FrictionCone::update(bool in_contact, const Eigen::Vector3d& normal, const Eigen::Vector3d& device,
                                  const Eigen::Vector3d& proxy, const Eigen::Vector3d& device_step,
                                  double radius) noexcept {
  FrictionStep out;
  out.goal = device;
  const bool was_sliding = sliding_;
  sliding_ = false;
  if (!(in_contact && mu_s_ > 0 && normal.squaredNorm() > 0)) return out;
  const Eigen::Vector3d e = device - proxy;
  const double depth = -e.dot(normal);
  const Eigen::Vector3d et = e + depth * normal;
  const double offset = et.norm();
  if (depth > 0 && offset > 0) {
    const Eigen::Vector3d dir = et / offset;
    const bool moving_on = was_sliding && device_step.dot(dir) > 0;
    const double limit = (was_sliding ? mu_k_ : mu_s_) * depth;
    if (offset <= limit && !moving_on) {
      out.sticking = true;
      out.goal = proxy;  // stuck: the proxy stays (the device is inside the cone)
    } else {
      // Kinetic friction opposes the sliding motion: the device's own tangential step when it
      // has one (the offset's direction wanders with the shell's bumps), else the offset.
      out.sliding = sliding_ = true;
      const Eigen::Vector3d step_t = device_step - device_step.dot(normal) * normal;
      out.slip_dir = step_t.norm() > 1e-9 * radius ? Eigen::Vector3d(step_t.normalized()) : dir;
      out.goal = device - out.slip_dir * (mu_k_ * depth);
    }
  } else if (depth > 0) {
    out.sticking = true;
    out.goal = proxy;
  }
  return out;
}

}  // namespace gshaptics
