#include "gshaptics/device/workspace_mapping.h"

#include <cstdio>

#include <cmath>

#include "gshaptics/error.h"

namespace gshaptics {

WorkspaceMapping::WorkspaceMapping(const WorkspaceMappingParams& params)
    : p_(params), r_(params.rotation.normalized().toRotationMatrix()), offset_(params.offset) {
  if (!(p_.scale > 0) || !std::isfinite(p_.scale)) throw InputError("WorkspaceMappingParams::scale: must be finite and > 0");
  if (!p_.offset.allFinite() || !p_.bubble_center.allFinite() || !std::isfinite(p_.bubble_radius) ||
      !std::isfinite(p_.bubble_gain) || p_.bubble_radius < 0 || p_.bubble_gain < 0 ||
      p_.rotation.coeffs().norm() < 1e-9)
    throw InputError("WorkspaceMappingParams: offset, bubble and rotation must be finite (radius, gain >= 0)");
}

DeviceSample WorkspaceMapping::to_world(const DeviceSample& device, double dt) noexcept {
  DeviceSample w = device;
  const bool pressed = p_.clutch_button >= 0 && p_.clutch_button < 32 &&
                       ((device.buttons >> unsigned(p_.clutch_button)) & 1u) != 0;
  const Eigen::Vector3d mapped = p_.scale * (r_ * device.position) + offset_;
  if (pressed && !clutched_) {
    clutched_ = true;
    frozen_ = mapped;
  } else if (!pressed && clutched_) {
    clutched_ = false;
    offset_ += frozen_ - mapped;  // continue from the frozen point: no jump
  }
  if (clutched_) {
    w.position = frozen_;
    w.velocity.setZero();
    w.angular_velocity = r_ * device.angular_velocity;
  } else {
    // Bubble: outside the radius the mapping drifts outward, proportional to the overshoot.
    if (p_.bubble_radius > 0 && p_.bubble_gain > 0 && dt > 0) {
      const Eigen::Vector3d d = device.position - p_.bubble_center;
      const double n = d.norm();
      if (n > p_.bubble_radius) offset_ += (p_.bubble_gain * (n - p_.bubble_radius) * dt / n) * (r_ * d);
    }
    w.position = p_.scale * (r_ * device.position) + offset_;
    w.velocity = p_.scale * (r_ * device.velocity);
    w.angular_velocity = r_ * device.angular_velocity;
  }
  w.orientation = (Eigen::Quaterniond(r_) * device.orientation).normalized();
  w.user_force = r_ * device.user_force;
  return w;
}

Wrench WorkspaceMapping::to_device(const Wrench& world) const noexcept {
  Wrench d;
  if (clutched_) return d;
  d.force = r_.transpose() * world.force;
  d.torque = r_.transpose() * world.torque;
  return d;
}

Eigen::AlignedBox3d WorkspaceMapping::world_box(const Eigen::AlignedBox3d& device_box) const noexcept {
  Eigen::AlignedBox3d out;
  for (int c = 0; c < 8; ++c)
    out.extend(p_.scale * (r_ * device_box.corner(Eigen::AlignedBox3d::CornerType(c))) + offset_);
  return out;
}

MappedDevice::MappedDevice(HapticDevice& inner, const WorkspaceMappingParams& params)
    : inner_(inner), mapping_(params), info_(inner.info()) {
  char scale[32];
  std::snprintf(scale, sizeof scale, "%.4g", params.scale);
  info_.name = inner.info().name + " (mapped x" + scale + ")";
  // The mapping drifts (clutch, bubble), so the inner device's workspace is no fixed world box:
  // read() checks it in device coordinates instead, and leaves the world box unbounded.
  info_.workspace = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1e300), Eigen::Vector3d::Constant(1e300));
}

void MappedDevice::start(Nanos now) {
  last_ = now;
  inner_.start(now);
  // Vendor drivers learn their limits in start(): take them over (forces are not scaled).
  const DeviceInfo& in = inner_.info();
  info_.max_rate_hz = in.max_rate_hz;
  info_.rate_source = in.rate_source;
  info_.max_force = in.max_force;
  info_.max_continuous_force = in.max_continuous_force;
  info_.max_stiffness = in.max_stiffness;
  info_.limit_source = in.limit_source;
  info_.renders_torque = in.renders_torque;
  info_.max_torque = in.max_torque;
  info_.torque_limit_source = in.torque_limit_source;
  info_.calibration = in.calibration;
}

DeviceSample MappedDevice::read(Nanos now) noexcept {
  const DeviceSample s = inner_.read(now);
  const double dt = last_ > 0 && now > last_ ? to_seconds(now - last_) : 0.0;
  last_ = now;
  DeviceSample w = mapping_.to_world(s, dt);
  // Outside the device's own workspace: a pose the safety layer refuses (force zero at once).
  if (!inner_.info().workspace.contains(s.position)) w.position.setConstant(std::nan(""));
  return w;
}

void MappedDevice::write(const Wrench& wrench, Nanos now) noexcept { inner_.write(mapping_.to_device(wrench), now); }

void MappedDevice::stop(Nanos now) noexcept { inner_.stop(now); }

}  // namespace gshaptics
