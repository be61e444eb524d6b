#include "gshaptics/device/device_registry.h"

#ifdef GSHAPTICS_HAVE_HAPLY
#include "gshaptics/device/haply_device.h"
#endif

#include <cstdio>
#include <utility>

#include "gshaptics/error.h"
#include "gshaptics/device/replay_device.h"
#include "gshaptics/device/simulated_device.h"
#include "gshaptics/device/vendor_devices.h"
#include "gshaptics/device/vendor_library.h"

namespace gshaptics {

namespace {

std::string arg_of(std::string_view spec, const std::string& name) {
  return spec.size() > name.size() ? std::string(spec.substr(name.size() + 1)) : std::string();
}

bool names(std::string_view spec, const std::string& name) {
  return spec == name || (spec.size() > name.size() && spec.substr(0, name.size()) == name && spec[name.size()] == ':');
}

/// A probe row for a device made by `make`: started briefly (zero force) to report what it is,
/// or the one-line reason it cannot be used.
template <class Make>
DeviceStatus started_briefly(const std::string& spec, Make make) {
  try {
    auto d = make();
    d->start(0);
    const std::string note = describe_device(*d) + ", " + d->status();
    d->stop(0);
    return {spec, true, note};
  } catch (const InputError& e) {
    return {spec, false, e.what()};
  }
}

void register_builtin_devices(DeviceRegistry& r) {
  DeviceKind sim;
  sim.name = "sim";
  sim.grammar = "sim";
  sim.summary = "a simulated device and hand pressing the scene's probe sites (the default)";
  sim.needs_scene = true;
  sim.check = [](const std::string& arg) {
    if (!arg.empty()) throw InputError("--device sim takes no argument, got 'sim:" + arg + "'");
  };
  sim.open = [](const std::string&, const DeviceOptions& o) -> std::unique_ptr<HapticDevice> {
    if (o.hand_path == nullptr) throw InputError("--device sim: needs a scene to press (no hand path given)");
    SimulatedDeviceParams p;
    p.causality = o.causality;
    return std::make_unique<SimulatedDevice>(*o.hand_path, p);
  };
  sim.probe = [](const DeviceOptions&) {
    return std::vector<DeviceStatus>{{"sim", true, "simulated device and hand, impedance or admittance causality (run, serve, device-sim)"}};
  };
  r.add(std::move(sim));

  DeviceKind replay;
  replay.name = "replay";
  replay.grammar = "replay:FILE";
  replay.summary = "a pose log (CSV time_s,x,y,z[,vx,vy,vz][,qw,qx,qy,qz]) played back, e.g. a servo_log.csv";
  replay.check = [](const std::string& arg) {
    if (arg.empty()) throw InputError("--device replay:FILE: no file given");
  };
  replay.open = [](const std::string& arg, const DeviceOptions&) -> std::unique_ptr<HapticDevice> {
    if (arg.empty()) throw InputError("--device replay:FILE: no file given");
    return std::make_unique<ReplayDevice>(load_pose_log(arg), "replay " + arg);
  };
  replay.probe = [](const DeviceOptions&) {
    return std::vector<DeviceStatus>{{"replay:FILE", true, "a pose log played back (run, serve)"}};
  };
  r.add(std::move(replay));

  DeviceKind dhd;
  dhd.name = "dhd";
  dhd.grammar = "dhd[:N]";
  dhd.summary = "a Force Dimension device (omega.x, delta.x, sigma.x, Falcon) through libdhd";
  dhd.hardware = true;
  dhd.check = [](const std::string& arg) { (void)device_index_arg("dhd:" + arg, arg); };
  dhd.open = [](const std::string& arg, const DeviceOptions&) -> std::unique_ptr<HapticDevice> {
    return std::make_unique<DhdDevice>(device_index_arg("dhd:" + arg, arg));
  };
  dhd.probe = [](const DeviceOptions&) {
    std::vector<DeviceStatus> rows;
    const VendorLibraryProbe p = probe_dhd_library();
    if (!p.available) return std::vector<DeviceStatus>{{"dhd[:N]", false, p.why}};
    if (p.devices <= 0)
      return std::vector<DeviceStatus>{
          {"dhd[:N]", false, p.library + " loads (" + p.path + ") but reports no device: check the USB cable, "
                             "the power and the udev rules of the Force Dimension SDK"}};
    for (int i = 0; i < p.devices; ++i)
      rows.push_back(started_briefly("dhd:" + std::to_string(i), [i] { return std::make_unique<DhdDevice>(i); }));
    return rows;
  };
  r.add(std::move(dhd));

  DeviceKind hd;
  hd.name = "openhaptics";
  hd.grammar = "openhaptics[:NAME]";
  hd.summary = "a 3D Systems device (Touch, Touch X, Phantom) through OpenHaptics' libHD";
  hd.hardware = true;
  hd.check = [](const std::string&) {};
  hd.open = [](const std::string& arg, const DeviceOptions& o) -> std::unique_ptr<HapticDevice> {
    OpenHapticsParams p;
    p.device_name = arg;
    p.calibration_wait = o.calibration_wait;
    return std::make_unique<OpenHapticsDevice>(p);
  };
  hd.probe = [](const DeviceOptions& o) {
    const VendorLibraryProbe p = probe_openhaptics_library();
    if (!p.available) return std::vector<DeviceStatus>{{"openhaptics[:NAME]", false, p.why}};
    OpenHapticsParams hp;
    hp.calibration_wait = o.calibration_wait;
    return std::vector<DeviceStatus>{
        started_briefly("openhaptics", [&hp] { return std::make_unique<OpenHapticsDevice>(hp); })};
  };
  r.add(std::move(hd));
}

}  // namespace

int device_index_arg(const std::string& spec, const std::string& arg) {
  if (arg.empty()) return 0;
  std::size_t used = 0;
  int i = -1;
  try {
    i = std::stoi(arg, &used);
  } catch (...) {
    used = 0;
  }
  if (used != arg.size() || i < 0 || i > 63)
    throw InputError("--device " + spec + ": the index after ':' must be a number 0-63");
  return i;
}

std::string describe_device(const HapticDevice& d) {
  const DeviceInfo& info = d.info();
  const Eigen::AlignedBox3d& ws = info.workspace;
  char box[96] = "workspace not reported, ";
  if (ws.sizes().allFinite() && ws.sizes().maxCoeff() < 1e3)
    std::snprintf(box, sizeof box, "workspace %.0f x %.0f x %.0f mm, ", ws.sizes().x() * 1e3, ws.sizes().y() * 1e3,
                  ws.sizes().z() * 1e3);
  char rate[64];
  std::snprintf(rate, sizeof rate, "up to %.0f Hz", info.max_rate_hz);
  return info.name + ": " + box + rate;
}

void DeviceRegistry::add(DeviceKind kind) {
  if (find(kind.name) != nullptr) throw InputError("device registry: a kind named '" + kind.name + "' exists");
  kinds_.push_back(std::move(kind));
}

const DeviceKind* DeviceRegistry::find(std::string_view spec) const noexcept {
  for (const DeviceKind& k : kinds_)
    if (names(spec, k.name)) return &k;
  return nullptr;
}

std::string DeviceRegistry::grammars() const {
  std::string s;
  for (const DeviceKind& k : kinds_) s += (s.empty() ? "" : ", ") + k.grammar;
  return s;
}

void DeviceRegistry::check(const std::string& spec) const {
  const DeviceKind* k = find(spec);
  if (k == nullptr)
    throw InputError("--device: '" + spec + "' is not a device kind of this build (" + grammars() +
                     "; `gshaptics devices` lists what this machine has)");
  if (k->check) k->check(arg_of(spec, k->name));
}

std::unique_ptr<HapticDevice> DeviceRegistry::open(const std::string& spec, const DeviceOptions& options) const {
  check(spec);
  return find(spec)->open(arg_of(spec, find(spec)->name), options);
}

std::vector<DeviceStatus> DeviceRegistry::list(const DeviceOptions& options) const {
  std::vector<DeviceStatus> rows;
  for (const DeviceKind& k : kinds_) {
    if (!k.probe) {
      rows.push_back({k.grammar, true, k.summary});
      continue;
    }
    for (DeviceStatus& s : k.probe(options)) rows.push_back(std::move(s));
  }
  return rows;
}

DeviceRegistry& device_registry() {
  static DeviceRegistry r = [] {
    DeviceRegistry built;
    register_builtin_devices(built);
#ifdef GSHAPTICS_HAVE_HAPLY
    register_haply_device(built);  // built into this library when Boost.Beast was found
#endif
    return built;
  }();
  return r;
}

std::unique_ptr<HapticDevice> open_device(const std::string& spec, const DeviceOptions& options) {
  return device_registry().open(spec, options);
}

std::vector<DeviceStatus> list_devices(const DeviceOptions& options) { return device_registry().list(options); }

}  // namespace gshaptics
