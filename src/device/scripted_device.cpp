#include "gshaptics/device/scripted_device.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/error.h"

namespace gshaptics {

ScriptedDevice::ScriptedDevice(std::vector<ScriptedPose> poses, double rate_hz)
    : poses_(std::move(poses)), period_s_(rate_hz > 0 ? 1.0 / rate_hz : 0) {
  if (poses_.empty()) throw InputError("scripted device: empty script");
  if (!(rate_hz > 0)) throw InputError("scripted device: the rate must be > 0 Hz");
  info_.name = "scripted (ideal position device)";
  info_.max_rate_hz = 1e6;
  info_.renders_torque = true;
}

void ScriptedDevice::start(Nanos now) {
  t0_ = now;
  sequence_ = 0;
  done_ = false;
}

DeviceSample ScriptedDevice::read(Nanos now) noexcept {
  const double k = std::round(to_seconds(now - t0_) / period_s_);
  const std::size_t last = poses_.size() - 1;
  const std::size_t i = k <= 0 ? 0 : std::min(last, std::size_t(k));
  done_ = i >= last;
  const ScriptedPose& p = poses_[i];
  DeviceSample s;
  s.sequence = ++sequence_;
  s.stamp = now;
  s.position = p.position;
  s.orientation = p.orientation;
  s.velocity = p.velocity;
  return s;
}

void ScriptedDevice::write(const Wrench&, Nanos) noexcept {}
void ScriptedDevice::stop(Nanos) noexcept {}

}  // namespace gshaptics
