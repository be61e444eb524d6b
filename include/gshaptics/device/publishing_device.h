#pragma once
/// @file
/// A device that drives the runtime while every commanded wrench is also written to a second
/// device, a transport that publishes it (the ROS node's local-device mode: the wrench goes out as
/// WrenchStamped for a viewer in a headset or a logger). The second device's own input is not
/// read. Threading: as every HapticDevice (servo thread only); both devices outlive this one.

#include <string>
#include <vector>

#include "gshaptics/device/haptic_device.h"

namespace gshaptics {

class PublishingDevice final : public HapticDevice {
 public:
  /// `local` drives (pose in, wrench out); `publisher` also receives each wrench, and starts
  /// before and stops after `local`, so nothing is published for a device not yet running.
  PublishingDevice(HapticDevice& local, HapticDevice& publisher) : local_(local), publisher_(publisher) {}
  [[nodiscard]] const DeviceInfo& info() const noexcept override { return local_.info(); }
  void start(Nanos now) override {
    publisher_.start(now);
    local_.start(now);
  }
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override { return local_.read(now); }
  void write(const Wrench& w, Nanos now) noexcept override {
    local_.write(w, now);
    publisher_.write(w, now);
  }
  void stop(Nanos now) noexcept override {
    local_.stop(now);
    publisher_.stop(now);
  }
  [[nodiscard]] bool finished() const noexcept override { return local_.finished() || publisher_.finished(); }
  [[nodiscard]] std::string status() const override { return local_.status(); }
  [[nodiscard]] std::vector<DeviceCounter> counters() const override { return local_.counters(); }

 private:
  HapticDevice& local_;
  HapticDevice& publisher_;
};

}  // namespace gshaptics
