#include "gshaptics/servo/vendor_devices.h"

#include <dlfcn.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include "gshaptics/error.h"
#include "gshaptics/servo/vendor_library.h"

namespace gshaptics {

// ---- frames ------------------------------------------------------------------------------------

Eigen::Vector3d dhd_to_device(const Eigen::Vector3d& v) noexcept { return {v.y(), -v.x(), v.z()}; }
Eigen::Vector3d device_to_dhd(const Eigen::Vector3d& v) noexcept { return {-v.y(), v.x(), v.z()}; }
Eigen::Vector3d hd_mm_to_device_m(const Eigen::Vector3d& mm) noexcept {
  return Eigen::Vector3d(mm.x(), -mm.z(), mm.y()) * 1e-3;
}
Eigen::Vector3d device_force_to_hd(const Eigen::Vector3d& f) noexcept { return {f.x(), f.z(), -f.y()}; }

namespace {

template <class F>
F symbol(void* handle, const char* name) {
  // The probe has checked that every symbol is present.
  return reinterpret_cast<F>(dlsym(handle, name));
}

std::int64_t steady_ns() noexcept {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

// ---- Force Dimension (DHD) ---------------------------------------------------------------------

// Force Dimension SDK, dhdc.h. Every function takes the device ID last (char; -1: the default).
struct DhdDevice::Api {
  int (*get_device_count)();
  int (*open_id)(char index);
  int (*close)(char id);
  int (*get_position)(double*, double*, double*, char id);          // m
  int (*get_linear_velocity)(double*, double*, double*, char id);   // m/s
  int (*set_force)(double, double, double, char id);                // N
  int (*get_button)(int index, char id);                            // DHD_ON / DHD_OFF
  int (*enable_force)(unsigned char on, char id);
  int (*get_status)(int* status, char id);                          // DHD_MAX_STATUS ints
  const char* (*get_system_name)(char id);
  const char* (*error_last)();
};

namespace {
constexpr unsigned char kDhdOn = 1, kDhdOff = 0;
// dhdGetStatus indices (dhdc.h; unchanged since SDK 3.2; DHD_MAX_STATUS has grown from 12 to 17,
// so the call gets a buffer larger than any version writes).
constexpr int kDhdStatusPower = 0, kDhdStatusConnected = 1, kDhdStatusReset = 3, kDhdStatusError = 9;
constexpr int kDhdStatusBuffer = 64;
constexpr int kDhdButtons = 4;

const DhdDevice::Api* load_dhd() {
  static const VendorLibraryProbe probe = probe_dhd_library();
  if (!probe.available) throw InputError("--device dhd: " + probe.why);
  static const DhdDevice::Api api = [] {
    void* h = probe.handle;
    DhdDevice::Api a{};
    a.get_device_count = symbol<decltype(a.get_device_count)>(h, "dhdGetDeviceCount");
    a.open_id = symbol<decltype(a.open_id)>(h, "dhdOpenID");
    a.close = symbol<decltype(a.close)>(h, "dhdClose");
    a.get_position = symbol<decltype(a.get_position)>(h, "dhdGetPosition");
    a.get_linear_velocity = symbol<decltype(a.get_linear_velocity)>(h, "dhdGetLinearVelocity");
    a.set_force = symbol<decltype(a.set_force)>(h, "dhdSetForce");
    a.get_button = symbol<decltype(a.get_button)>(h, "dhdGetButton");
    a.enable_force = symbol<decltype(a.enable_force)>(h, "dhdEnableForce");
    a.get_status = symbol<decltype(a.get_status)>(h, "dhdGetStatus");
    a.get_system_name = symbol<decltype(a.get_system_name)>(h, "dhdGetSystemName");
    a.error_last = symbol<decltype(a.error_last)>(h, "dhdErrorGetLastStr");
    return a;
  }();
  return &api;
}
}  // namespace

DhdDevice::DhdDevice(int index) : api_(load_dhd()), index_(index) {
  if (index < 0) throw InputError("--device dhd:" + std::to_string(index) + ": the index must be >= 0");
  const int count = api_->get_device_count();
  if (count <= index)
    throw InputError("--device dhd:" + std::to_string(index) + ": libdhd reports " +
                     std::to_string(count < 0 ? 0 : count) +
                     " device(s); check the USB cable and power, and that this user may open the "
                     "device (udev rules from the Force Dimension SDK)");
  info_.name = "dhd:" + std::to_string(index);
  info_.max_rate_hz = 8000;  // DHD devices run their USB loop at up to 8 kHz
}

DhdDevice::~DhdDevice() {
  if (open_) stop(0);
}

void DhdDevice::start(Nanos) {
  const int id = api_->open_id(static_cast<char>(index_));
  if (id < 0)
    throw InputError("--device dhd:" + std::to_string(index_) + ": dhdOpenID failed: " + api_->error_last());
  id_ = static_cast<char>(id);
  open_ = true;
  int st[kDhdStatusBuffer] = {};
  if (api_->get_status(st, id_) >= 0) {
    if (st[kDhdStatusPower] == 0) status_ = "not powered (switch the controller on)";
    else if (st[kDhdStatusConnected] == 0) status_ = "not connected";
    else if (st[kDhdStatusError] != 0) status_ = "reports an error";
    else if (st[kDhdStatusReset] != 0)
      status_ = "in RESET mode: move it to its calibration position so it calibrates, then press the force button";
    else status_ = "powered, connected, calibrated";
  } else {
    status_ = std::string("status unreadable: ") + api_->error_last();
  }
  if (const char* name = api_->get_system_name(id_)) info_.name = std::string(name) + " (dhd:" + std::to_string(index_) + ")";
  api_->set_force(0, 0, 0, id_);
  if (api_->enable_force(kDhdOn, id_) < 0) {
    const std::string err = api_->error_last();
    api_->close(id_);
    open_ = false;
    throw InputError("--device dhd:" + std::to_string(index_) + ": dhdEnableForce failed: " + err);
  }
}

DeviceSample DhdDevice::read(Nanos now) noexcept {
  double p[3], v[3];
  if (api_->get_position(&p[0], &p[1], &p[2], id_) < 0 ||
      api_->get_linear_velocity(&v[0], &v[1], &v[2], id_) < 0)
    return last_;  // same sequence: the watchdog decides
  DeviceSample s;
  s.sequence = last_.sequence + 1;
  s.stamp = now;
  s.position = dhd_to_device({p[0], p[1], p[2]});
  s.velocity = dhd_to_device({v[0], v[1], v[2]});
  for (int b = 0; b < kDhdButtons; ++b)
    if (api_->get_button(b, id_) == kDhdOn) s.buttons |= 1u << b;
  last_ = s;
  return s;
}

void DhdDevice::write(const Wrench& wrench, Nanos) noexcept {
  const Eigen::Vector3d f = device_to_dhd(wrench.force);
  api_->set_force(f.x(), f.y(), f.z(), id_);
}

void DhdDevice::stop(Nanos) noexcept {
  if (!open_) return;
  api_->set_force(0, 0, 0, id_);
  api_->enable_force(kDhdOff, id_);
  api_->close(id_);
  open_ = false;
}

// ---- 3D Systems OpenHaptics (HD) ---------------------------------------------------------------

namespace {
// hdDefines.h (OpenHaptics Toolkit).
using HHD = unsigned int;
using HDenum = unsigned int;
using HDSchedulerHandle = unsigned long;
struct HDErrorInfo {
  unsigned int errorCode;
  int internalErrorCode;
  HHD hHD;
};
using HDCallback = unsigned int (*)(void*);
constexpr HDenum kHdCurrentButtons = 0x2000, kHdCurrentPosition = 0x2050, kHdCurrentVelocity = 0x2051,
                 kHdUsableWorkspace = 0x2551, kHdCalibrationStyle = 0x2555, kHdUpdateRate = 0x2600,
                 kHdNominalMaxForce = 0x2603, kHdCurrentForce = 0x2700, kHdForceOutput = 0x4000;
constexpr HDenum kHdCalibrationOk = 0x5000, kHdCalibrationNeedsUpdate = 0x5001,
                 kHdCalibrationNeedsManual = 0x5002;
constexpr int kHdCalibrationEncoderReset = 1 << 0, kHdCalibrationAuto = 1 << 1, kHdCalibrationInkwell = 1 << 2;
constexpr unsigned int kHdCallbackDone = 0, kHdCallbackContinue = 1;
constexpr unsigned short kHdMaxSchedulerPriority = 0xFFFF;  // USHRT_MAX
constexpr HHD kHdInvalidHandle = 0xFFFFFFFFu;

std::string hd_error_text(const HDErrorInfo& e) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "HD error 0x%04x (device code %d)", e.errorCode, e.internalErrorCode);
  return buf;
}

unsigned int hd_trampoline(void* self) { return static_cast<OpenHapticsDevice*>(self)->servo_callback(); }
}  // namespace

struct OpenHapticsDevice::Api {
  HHD (*init_device)(const char* name);
  void (*disable_device)(HHD);
  HDErrorInfo (*get_error)();
  void (*begin_frame)(HHD);
  void (*end_frame)(HHD);
  void (*get_doublev)(HDenum, double*);
  void (*get_integerv)(HDenum, int*);
  void (*set_doublev)(HDenum, const double*);
  void (*enable)(HDenum);
  HDenum (*check_calibration)();
  void (*update_calibration)(int style);
  void (*start_scheduler)();
  void (*stop_scheduler)();
  HDSchedulerHandle (*schedule_asynchronous)(HDCallback, void*, unsigned short priority);
  void (*unschedule)(HDSchedulerHandle);
};

namespace {
const OpenHapticsDevice::Api* load_hd() {
  static const VendorLibraryProbe probe = probe_openhaptics_library();
  if (!probe.available) throw InputError("--device openhaptics: " + probe.why);
  static const OpenHapticsDevice::Api api = [] {
    void* h = probe.handle;
    OpenHapticsDevice::Api a{};
    a.init_device = symbol<decltype(a.init_device)>(h, "hdInitDevice");
    a.disable_device = symbol<decltype(a.disable_device)>(h, "hdDisableDevice");
    a.get_error = symbol<decltype(a.get_error)>(h, "hdGetError");
    a.begin_frame = symbol<decltype(a.begin_frame)>(h, "hdBeginFrame");
    a.end_frame = symbol<decltype(a.end_frame)>(h, "hdEndFrame");
    a.get_doublev = symbol<decltype(a.get_doublev)>(h, "hdGetDoublev");
    a.get_integerv = symbol<decltype(a.get_integerv)>(h, "hdGetIntegerv");
    a.set_doublev = symbol<decltype(a.set_doublev)>(h, "hdSetDoublev");
    a.enable = symbol<decltype(a.enable)>(h, "hdEnable");
    a.check_calibration = symbol<decltype(a.check_calibration)>(h, "hdCheckCalibration");
    a.update_calibration = symbol<decltype(a.update_calibration)>(h, "hdUpdateCalibration");
    a.start_scheduler = symbol<decltype(a.start_scheduler)>(h, "hdStartScheduler");
    a.stop_scheduler = symbol<decltype(a.stop_scheduler)>(h, "hdStopScheduler");
    a.schedule_asynchronous = symbol<decltype(a.schedule_asynchronous)>(h, "hdScheduleAsynchronous");
    a.unschedule = symbol<decltype(a.unschedule)>(h, "hdUnschedule");
    return a;
  }();
  return &api;
}
}  // namespace

OpenHapticsDevice::OpenHapticsDevice(const OpenHapticsParams& params) : api_(load_hd()), params_(params) {
  if (!(params.command_timeout > 0)) throw InputError("openhaptics: command_timeout must be > 0");
  info_.name = "openhaptics" + (params.device_name.empty() ? std::string() : ":" + params.device_name);
  info_.max_rate_hz = 1000;  // the HD scheduler's default servo rate
}

OpenHapticsDevice::~OpenHapticsDevice() {
  if (handle_ != kHdInvalidHandle) stop(0);
}

void OpenHapticsDevice::start(Nanos) {
  const std::string what = "--device " + info_.name;
  const HHD h = api_->init_device(params_.device_name.empty() ? nullptr : params_.device_name.c_str());
  HDErrorInfo e = api_->get_error();
  if (e.errorCode != 0 || h == kHdInvalidHandle)
    throw InputError(what + ": hdInitDevice failed: " + hd_error_text(e) +
                     " (is the device configured in Touch Setup, and its driver running?)");
  handle_ = h;
  double ws[6] = {};
  api_->get_doublev(kHdUsableWorkspace, ws);  // min x,y,z, max x,y,z, mm
  const Eigen::Vector3d a = hd_mm_to_device_m({ws[0], ws[1], ws[2]});
  const Eigen::Vector3d b = hd_mm_to_device_m({ws[3], ws[4], ws[5]});
  if ((a - b).norm() > 0) info_.workspace = Eigen::AlignedBox3d(a.cwiseMin(b), a.cwiseMax(b));
  api_->get_doublev(kHdNominalMaxForce, &max_force_);
  int rate = 0;
  api_->get_integerv(kHdUpdateRate, &rate);
  if (rate > 0) info_.max_rate_hz = rate;
  const HDenum cal = api_->check_calibration();
  if (cal == kHdCalibrationNeedsManual) {
    api_->disable_device(handle_);
    handle_ = kHdInvalidHandle;
    throw InputError(what + ": the device needs calibrating by hand: put the stylus in its inkwell "
                     "(or run Touch Diagnostic), then start again");
  }
  if (cal == kHdCalibrationNeedsUpdate) {
    int styles = 0;
    api_->get_integerv(kHdCalibrationStyle, &styles);
    const int style = (styles & kHdCalibrationAuto) ? kHdCalibrationAuto
                      : (styles & kHdCalibrationInkwell) ? kHdCalibrationInkwell
                                                          : kHdCalibrationEncoderReset;
    api_->update_calibration(style);
    status_ = "calibration updated";
  } else {
    status_ = cal == kHdCalibrationOk ? "calibrated" : "calibration state unknown";
  }
  api_->enable(kHdForceOutput);
  commands_.write(Command{Eigen::Vector3d::Zero(), steady_ns()});
  running_.store(true, std::memory_order_release);
  schedule_ = api_->schedule_asynchronous(&hd_trampoline, this, kHdMaxSchedulerPriority);
  scheduled_ = true;
  api_->start_scheduler();
  e = api_->get_error();
  if (e.errorCode != 0) {
    const std::string err = hd_error_text(e);
    stop(0);
    throw InputError(what + ": the HD scheduler did not start: " + err);
  }
}

unsigned int OpenHapticsDevice::servo_callback() noexcept {
  api_->begin_frame(handle_);
  double p[3] = {}, v[3] = {};
  int buttons = 0;
  api_->get_doublev(kHdCurrentPosition, p);
  api_->get_doublev(kHdCurrentVelocity, v);
  api_->get_integerv(kHdCurrentButtons, &buttons);
  Sample s;
  s.position = hd_mm_to_device_m({p[0], p[1], p[2]});
  s.velocity = hd_mm_to_device_m({v[0], v[1], v[2]});
  s.buttons = static_cast<std::uint32_t>(buttons);
  const bool running = running_.load(std::memory_order_acquire);
  const Command& c = commands_.read();
  Eigen::Vector3d f = c.force;
  if (!running) {
    f.setZero();
  } else if (steady_ns() - c.wall_ns > static_cast<std::int64_t>(params_.command_timeout * 1e9)) {
    f.setZero();
    stale_.fetch_add(1, std::memory_order_relaxed);
  }
  api_->set_doublev(kHdCurrentForce, f.data());
  api_->end_frame(handle_);
  if (api_->get_error().errorCode != 0) {
    hd_errors_.fetch_add(1, std::memory_order_relaxed);
  } else {
    samples_.write(s);  // a frame with an error delivers no sample: the runtime's watchdog decides
  }
  callbacks_.fetch_add(1, std::memory_order_relaxed);
  if (!running) {
    zero_applied_.store(true, std::memory_order_release);
    return kHdCallbackDone;
  }
  return kHdCallbackContinue;
}

DeviceSample OpenHapticsDevice::read(Nanos now) noexcept {
  Sample s;
  if (samples_.read_if_new(s)) {
    last_.sequence += 1;
    last_.stamp = now;
    last_.position = s.position;
    last_.velocity = s.velocity;
    last_.buttons = s.buttons;
  }
  return last_;
}

void OpenHapticsDevice::write(const Wrench& wrench, Nanos) noexcept {
  commands_.write(Command{device_force_to_hd(wrench.force), steady_ns()});
}

void OpenHapticsDevice::stop(Nanos) noexcept {
  if (handle_ == kHdInvalidHandle) return;
  commands_.write(Command{Eigen::Vector3d::Zero(), steady_ns()});
  if (running_.exchange(false, std::memory_order_acq_rel) && scheduled_) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(50);
    while (!zero_applied_.load(std::memory_order_acquire) && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  api_->stop_scheduler();
  if (scheduled_) api_->unschedule(schedule_);
  scheduled_ = false;
  api_->disable_device(handle_);
  handle_ = kHdInvalidHandle;
}

}  // namespace gshaptics
