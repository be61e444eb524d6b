#pragma once
/// @file
/// The device registry: every device a `--device` value can name, in one table. A kind has a
/// name ("dhd"), a grammar ("dhd[:N]"), a one-line summary for help texts, a check of its
/// argument (run before any scene is loaded), a factory and a probe that says whether this
/// machine can use it and why not. `open_device("dhd:1", options)` and `list_devices(options)`
/// are what the CLI, the Python module and an embedder call.
///
/// Adding a device: write its driver (a HapticDevice; docs/devices.md, "Adding a device"), then
/// add one DeviceKind to the registry: built-in kinds in register_builtin_devices()
/// (src/device/device_registry.cpp), kinds that live in an optional library through that library's
/// own registration call (register_haply_device() in the viewer library).
///
/// Threading: build the registry before any run starts; lookups are read-only and may run on
/// any thread. Factories and probes may block (they open libraries and devices); never call them
/// on the servo thread.

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "gshaptics/device/device_model.h"
#include "gshaptics/device/hand_trajectory.h"
#include "gshaptics/device/haptic_device.h"

namespace gshaptics {

/// What the device factories may need besides the `--device` value.
struct DeviceOptions {
  std::string haply_url = "ws://127.0.0.1:10001/";  ///< the Haply Inverse Service's WebSocket
  /// Haply: render force to an Inverse3 whose status says it is not calibrated (refused by default).
  bool haply_allow_uncalibrated = false;
  double calibration_wait = 5.0;  ///< OpenHaptics: how long start() waits for inkwell calibration, s
  /// sim: the path the simulated hand follows (the session makes it from the loaded scene; not
  /// owned, copied by the factory). Null for a kind that needs no scene.
  const ProbeTrajectory* hand_path = nullptr;
  /// sim: the simulated device's causality (--control): the ideal mass-damper (impedance) or the
  /// robot under a position servo with a force sensor (admittance; simulated_device.h).
  Causality causality = Causality::kImpedance;
};

/// One row of list_devices(): a device (or a kind with none found) and whether it can be used.
struct DeviceStatus {
  std::string spec;      ///< what to pass to --device ("dhd:0"), or the kind's grammar
  bool available = false;
  std::string note;      ///< what it is (workspace, rate, limits) or why it cannot be used
};

/// A kind of device.
struct DeviceKind {
  std::string name;     ///< "dhd": matches "dhd" and "dhd:ARG"
  std::string grammar;  ///< "dhd[:N]", for help texts
  std::string summary;  ///< one line for help texts
  bool hardware = false;  ///< a physical device: placed in the world through a workspace mapping
  /// Opened once the scene is loaded, with what the scene gives (DeviceOptions::hand_path).
  bool needs_scene = false;
  /// Validates ARG (the text after "name:", empty when absent); throws InputError naming the
  /// value. Cheap: no library is opened.
  std::function<void(const std::string& arg)> check;
  /// Makes the device (not started). Throws InputError (a missing library, a bad argument).
  std::function<std::unique_ptr<HapticDevice>(const std::string& arg, const DeviceOptions&)> open;
  /// Whether this machine can use the kind, one row per device found (may open devices briefly,
  /// at zero force). Empty: the kind cannot be probed without a scene (sim, replay).
  std::function<std::vector<DeviceStatus>(const DeviceOptions&)> probe;
};

class DeviceRegistry {
 public:
  /// Adds a kind; throws InputError when the name is taken.
  void add(DeviceKind kind);
  /// The kind `spec` names ("dhd", "dhd:1"), or null.
  [[nodiscard]] const DeviceKind* find(std::string_view spec) const noexcept;
  /// Checks `spec` (kind known, argument valid); throws InputError naming the value and the
  /// known grammars.
  void check(const std::string& spec) const;
  /// Makes the device `spec` names. Throws InputError.
  [[nodiscard]] std::unique_ptr<HapticDevice> open(const std::string& spec, const DeviceOptions& options = {}) const;
  /// One row per kind or device found, in registration order.
  [[nodiscard]] std::vector<DeviceStatus> list(const DeviceOptions& options = {}) const;
  [[nodiscard]] const std::vector<DeviceKind>& kinds() const noexcept { return kinds_; }
  /// "replay:FILE, dhd[:N], ...", for help texts and errors.
  [[nodiscard]] std::string grammars() const;

 private:
  std::vector<DeviceKind> kinds_;
};

/// The process-wide registry, with the built-in kinds (sim, replay, dhd, openhaptics) on first use.
/// Optional libraries add theirs (register_haply_device()).
[[nodiscard]] DeviceRegistry& device_registry();

/// open_device / list_devices on device_registry().
[[nodiscard]] std::unique_ptr<HapticDevice> open_device(const std::string& spec, const DeviceOptions& options = {});
[[nodiscard]] std::vector<DeviceStatus> list_devices(const DeviceOptions& options = {});

/// "kind:ARG" -> the index ARG as a number 0-63 (0 when absent); throws InputError naming `spec`.
[[nodiscard]] int device_index_arg(const std::string& spec, const std::string& arg);

/// "NAME: workspace W x H x D mm, up to R Hz" for a device's rows.
[[nodiscard]] std::string describe_device(const HapticDevice& device);

}  // namespace gshaptics
