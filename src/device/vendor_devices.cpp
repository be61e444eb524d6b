#include "gshaptics/device/vendor_devices.h"

#include <dlfcn.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <thread>

#include "gshaptics/error.h"
#include "gshaptics/device/vendor_library.h"

namespace gshaptics {

// ---- frames ------------------------------------------------------------------------------------

Eigen::Vector3d dhd_to_device(const Eigen::Vector3d& v) noexcept { return {v.y(), -v.x(), v.z()}; }
Eigen::Vector3d device_to_dhd(const Eigen::Vector3d& v) noexcept { return {-v.y(), v.x(), v.z()}; }
Eigen::Matrix3d dhd_axes_in_device() noexcept {
  Eigen::Matrix3d m;
  m << 0, 1, 0, -1, 0, 0, 0, 0, 1;  // the columns: the DHD axes in the device frame (dhd_to_device)
  return m;
}
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
  int (*get_system_type)(char id);                                  // DHD_DEVICE_*
  double (*get_max_force)(char id);   // N; < 0: no software limit set. Optional (newer SDKs)
  double (*get_max_torque)(char id);  // N m; < 0: no software limit set. Optional (newer SDKs)
  const char* (*error_last)();
  // 6-DoF (optional: older SDKs and 3-DoF-only builds may lack them).
  bool (*has_active_wrist)(char id);                                // the wrist renders torque
  int (*set_force_and_torque)(double, double, double, double, double, double, char id);  // N, N m
  int (*get_orientation_frame)(double (*)[3], char id);             // wrist frame, rows of a 3x3
};

namespace {
constexpr unsigned char kDhdOn = 1, kDhdOff = 0;
// dhdGetStatus indices (dhdc.h; unchanged since SDK 3.2; DHD_MAX_STATUS has grown from 12 to 17,
// so the call gets a buffer larger than any version writes).
constexpr int kDhdStatusPower = 0, kDhdStatusConnected = 1, kDhdStatusReset = 3, kDhdStatusError = 9;
constexpr int kDhdStatusBuffer = 64;
constexpr int kDhdButtons = 4;
constexpr int kDhdMotorSaturated = 2;  // dhdSetForce: the force was saturated by the device
constexpr double kDhdRateCap = 8000;   // the DHD USB loop's highest rate, Hz

}  // namespace

const DhdDeviceType& dhd_device_type(int system_type) noexcept {
  // Force Dimension's and Novint's rated translational force and translational workspace
  // (a cylinder: diameter x height) per device family; dhdc.h's DHD_DEVICE_* codes.
  static const DhdDeviceType kTypes[] = {
      {33, "omega.3", 12.0, 0.160, 0.110, 0.0},         {34, "omega.6", 12.0, 0.160, 0.110, 0.0},
      {36, "omega.6 (left)", 12.0, 0.160, 0.110, 0.0},  {35, "omega.7", 12.0, 0.160, 0.110, 0.0},
      {37, "omega.7 (left)", 12.0, 0.160, 0.110, 0.0},  {63, "delta.3", 20.0, 0.400, 0.260, 0.0},
      {64, "delta.6", 20.0, 0.400, 0.260, 0.2},         {104, "sigma.7", 20.0, 0.190, 0.130, 0.2},
      {105, "sigma.7 (left)", 20.0, 0.190, 0.130, 0.2}, {60, "Novint Falcon", 8.9, 0.1016, 0.1016, 0.0},
  };
  // An unknown type gets the lowest ratings and the smallest workspace of the family (an active
  // wrist of unknown type: the lowest wrist rating, 0.2 N m).
  static const DhdDeviceType kUnknown{-1, "unknown DHD device", 8.9, 0.1016, 0.1016, 0.2};
  for (const DhdDeviceType& t : kTypes)
    if (t.system_type == system_type) return t;
  return kUnknown;
}

namespace {

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
    a.get_system_type = symbol<decltype(a.get_system_type)>(h, "dhdGetSystemType");
    a.get_max_force = symbol<decltype(a.get_max_force)>(h, "dhdGetMaxForce");  // may be null
    a.get_max_torque = symbol<decltype(a.get_max_torque)>(h, "dhdGetMaxTorque");  // may be null
    a.error_last = symbol<decltype(a.error_last)>(h, "dhdErrorGetLastStr");
    a.has_active_wrist = symbol<decltype(a.has_active_wrist)>(h, "dhdHasActiveWrist");        // may be null
    a.set_force_and_torque = symbol<decltype(a.set_force_and_torque)>(h, "dhdSetForceAndTorque");  // may be null
    a.get_orientation_frame = symbol<decltype(a.get_orientation_frame)>(h, "dhdGetOrientationFrame");  // may be null
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
  info_.max_rate_hz = kDhdRateCap;  // until start() measures it
  info_.rate_source = "DHD cap, not yet measured";
  info_.calibration = Calibration::kUnknown;
}

DhdDevice::~DhdDevice() {
  if (open_) stop(0);
}

void DhdDevice::start(Nanos) {
  const std::string what = "--device dhd:" + std::to_string(index_);
  if (open_) throw InputError(what + ": already started");
  const int id = api_->open_id(static_cast<char>(index_));
  if (id < 0) throw InputError(what + ": dhdOpenID failed: " + api_->error_last());
  id_ = static_cast<char>(id);
  open_ = true;
  const auto refuse = [&](const std::string& why) {
    api_->close(id_);
    open_ = false;
    throw InputError(what + ": " + why + "; no force was rendered");
  };
  // Status first (dhdGetStatus): no force to a device that is unpowered, in error, or not
  // calibrated (RESET mode).
  int st[kDhdStatusBuffer] = {};
  if (api_->get_status(st, id_) < 0) refuse(std::string("status unreadable: ") + api_->error_last());
  if (st[kDhdStatusPower] == 0) {
    info_.calibration = Calibration::kUnknown;
    refuse("the device is not powered: switch its controller on");
  }
  if (st[kDhdStatusConnected] == 0) refuse("the device is not connected: check the USB cable");
  if (st[kDhdStatusError] != 0) refuse("the device reports an error: power-cycle it");
  if (st[kDhdStatusReset] != 0) {
    info_.calibration = Calibration::kNeedsUser;
    refuse("the device is in RESET mode (not calibrated): calibrate it with the SDK's auto-"
           "calibration (drdAutoInit, or the SDK's 'autoinit' program), or move it to its "
           "calibration position and press the force button, then start again");
  }
  info_.calibration = Calibration::kCalibrated;
  status_ = "powered, connected, calibrated";
  // The device's own force limit: the rating of its type (dhdGetSystemType), lowered by a
  // software limit when one is set (dhdGetMaxForce > 0; < 0 means none).
  type_ = dhd_device_type(api_->get_system_type(id_));
  info_.max_force = type_.rated_force;
  info_.limit_source = "rating of " + type_.name + " (dhdGetSystemType)";
  if (api_->get_max_force != nullptr) {
    const double set = api_->get_max_force(id_);
    if (set > 0 && set < info_.max_force) {
      info_.max_force = set;
      info_.limit_source = "dhdGetMaxForce";
    }
  }
  const double r = type_.workspace_diameter / 2, hz = type_.workspace_height / 2;
  info_.workspace = Eigen::AlignedBox3d(Eigen::Vector3d(-r, -r, -hz), Eigen::Vector3d(r, r, hz));
  if (const char* name = api_->get_system_name(id_)) info_.name = std::string(name) + " (dhd:" + std::to_string(index_) + ")";
  // An active wrist (sigma.7, delta.6, omega.6/7 with the active option: dhdHasActiveWrist)
  // takes torque through dhdSetForceAndTorque, within its own limit (wrist_torque_limit).
  info_.renders_torque = api_->has_active_wrist != nullptr && api_->set_force_and_torque != nullptr &&
                         api_->has_active_wrist(id_);
  info_.max_torque = std::numeric_limits<double>::infinity();
  info_.torque_limit_source.clear();
  if (info_.renders_torque) wrist_torque_limit();
  zero_output();
  // The rate: measured, one tick's I/O (position, velocity, buttons, a zero force) timed 16 times
  // (median), capped at the DHD loop's 8 kHz.
  {
    double samples[16];
    for (double& t : samples) {
      const auto t0 = std::chrono::steady_clock::now();
      double p[3], v[3];
      api_->get_position(&p[0], &p[1], &p[2], id_);
      api_->get_linear_velocity(&v[0], &v[1], &v[2], id_);
      for (int b = 0; b < kDhdButtons; ++b) api_->get_button(b, id_);
      zero_output();
      t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    std::sort(std::begin(samples), std::end(samples));
    const double io = samples[8];
    info_.max_rate_hz = io > 0 ? std::min(kDhdRateCap, 1.0 / io) : kDhdRateCap;
    char b[96];
    std::snprintf(b, sizeof b, "measured: %.0f us of device I/O per tick (cap %.0f Hz)", io * 1e6, kDhdRateCap);
    info_.rate_source = b;
  }
  saturated_.store(0, std::memory_order_relaxed);
  if (api_->enable_force(kDhdOn, id_) < 0) {
    const std::string err = api_->error_last();
    refuse("dhdEnableForce failed: " + err);
  }
}

void DhdDevice::wrist_torque_limit() {
  // The rating of the type (an active wrist on a type rated 0 or unknown: the family's lowest
  // wrist rating), lowered by a software limit when one is set (dhdGetMaxTorque > 0).
  const double lowest = dhd_device_type(-1).rated_torque;
  info_.max_torque = type_.rated_torque > 0 ? type_.rated_torque : lowest;
  info_.torque_limit_source = type_.rated_torque > 0 ? "rating of " + type_.name + " (dhdGetSystemType)"
                                                     : "lowest DHD wrist rating (" + type_.name + " has none)";
  if (api_->get_max_torque != nullptr) {
    const double set = api_->get_max_torque(id_);
    if (set > 0 && set < info_.max_torque) {
      info_.max_torque = set;
      info_.torque_limit_source = "dhdGetMaxTorque";
    }
  }
}

std::string DhdDevice::status() const {
  if (status_.empty()) return {};
  char b[160];
  std::snprintf(b, sizeof b, ", %s rated %.3g N (limit %.3g N from %s)", type_.name.c_str(), type_.rated_force,
                info_.max_force, info_.limit_source.c_str());
  return status_ + b;
}

std::vector<DeviceCounter> DhdDevice::counters() const {
  return {{"saturated writes (DHD_MOTOR_SATURATED)", saturated_writes()}};
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
  if (api_->get_orientation_frame != nullptr) {
    // The wrist frame in the DHD base frame (identity on devices without a wrist), turned into
    // the device frame on both sides so the wrist's rest pose is the tool frame's identity.
    double m[3][3];
    if (api_->get_orientation_frame(m, id_) >= 0) {
      Eigen::Matrix3d r;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r(i, j) = m[i][j];
      const Eigen::Matrix3d turned = dhd_axes_in_device() * r * dhd_axes_in_device().transpose();
      const Eigen::Quaterniond q(turned);
      if (q.coeffs().allFinite() && std::abs(q.norm() - 1.0) < 1e-6) s.orientation = q.normalized();
    }
  }
  for (int b = 0; b < kDhdButtons; ++b)
    if (api_->get_button(b, id_) == kDhdOn) s.buttons |= 1u << b;
  last_ = s;
  return s;
}

void DhdDevice::write(const Wrench& wrench, Nanos) noexcept {
  const Eigen::Vector3d f = device_to_dhd(wrench.force);
  int ret;
  if (info_.renders_torque) {
    const Eigen::Vector3d t = device_to_dhd(wrench.torque);  // a rotation: torques turn as forces
    ret = api_->set_force_and_torque(f.x(), f.y(), f.z(), t.x(), t.y(), t.z(), id_);
  } else {
    ret = api_->set_force(f.x(), f.y(), f.z(), id_);
  }
  if (ret == kDhdMotorSaturated)
    saturated_.store(saturated_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

void DhdDevice::zero_output() noexcept {
  if (info_.renders_torque)
    api_->set_force_and_torque(0, 0, 0, 0, 0, 0, id_);
  else
    api_->set_force(0, 0, 0, id_);
}

void DhdDevice::stop(Nanos) noexcept {
  if (!open_) return;
  zero_output();
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
                 kHdUsableWorkspace = 0x2551, kHdOutputDof = 0x2554, kHdCalibrationStyle = 0x2555,
                 kHdUpdateRate = 0x2600, kHdNominalMaxStiffness = 0x2602, kHdNominalMaxForce = 0x2603,
                 kHdNominalMaxContinuousForce = 0x2604, kHdCurrentForce = 0x2700, kHdForceOutput = 0x4000;
constexpr HDenum kHdCalibrationOk = 0x5000, kHdCalibrationNeedsUpdate = 0x5001,
                 kHdCalibrationNeedsManual = 0x5002;
constexpr int kHdCalibrationEncoderReset = 1 << 0, kHdCalibrationAuto = 1 << 1, kHdCalibrationInkwell = 1 << 2;
constexpr unsigned int kHdCallbackDone = 0, kHdCallbackContinue = 1;
constexpr unsigned short kHdMaxSchedulerPriority = 0xFFFF;  // USHRT_MAX
constexpr unsigned short kHdDefaultSchedulerPriority = 0x7FFF;  // (max + min) / 2
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
  void (*schedule_synchronous)(HDCallback, void*, unsigned short priority);
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
    a.schedule_synchronous = symbol<decltype(a.schedule_synchronous)>(h, "hdScheduleSynchronous");
    a.unschedule = symbol<decltype(a.unschedule)>(h, "hdUnschedule");
    return a;
  }();
  return &api;
}
}  // namespace

OpenHapticsDevice::OpenHapticsDevice(const OpenHapticsParams& params)
    : api_(load_hd()), params_(params), link_(params.command_timeout) {
  if (!(params.command_timeout > 0)) throw InputError("openhaptics: command_timeout must be > 0");
  info_.name = "openhaptics" + (params.device_name.empty() ? std::string() : ":" + params.device_name);
  info_.max_rate_hz = 1000;  // the HD scheduler's default servo rate
}

OpenHapticsDevice::~OpenHapticsDevice() {
  if (handle_ != kHdInvalidHandle) stop(0);
}

namespace {
// Run on the HD scheduler thread through hdScheduleSynchronous, as the vendor's Calibration
// example does: the calibration state is read inside a frame, once the servo loop runs.
struct HdCalibrationCall {
  const OpenHapticsDevice::Api* api;
  HHD handle;
  int style;
  HDenum status;
};
unsigned int hd_calibration_status(void* p) {
  auto* c = static_cast<HdCalibrationCall*>(p);
  c->api->begin_frame(c->handle);
  c->status = c->api->check_calibration();
  c->api->end_frame(c->handle);
  return kHdCallbackDone;
}
unsigned int hd_calibration_update(void* p) {
  auto* c = static_cast<HdCalibrationCall*>(p);
  if (c->api->check_calibration() == kHdCalibrationNeedsUpdate) c->api->update_calibration(c->style);
  return kHdCallbackDone;
}
}  // namespace

void OpenHapticsDevice::start(Nanos) {
  const std::string what = "--device " + info_.name;
  if (handle_ != kHdInvalidHandle) throw InputError(what + ": already started");
  const HHD h = api_->init_device(params_.device_name.empty() ? nullptr : params_.device_name.c_str());
  HDErrorInfo e = api_->get_error();
  if (e.errorCode != 0 || h == kHdInvalidHandle)
    throw InputError(what + ": hdInitDevice failed: " + hd_error_text(e) +
                     " (is the device configured in Touch Setup, and its driver running?)");
  handle_ = h;
  // Every session starts afresh: a previous stop() left these set.
  zero_applied_.store(false, std::memory_order_release);
  double ws[6] = {};
  api_->get_doublev(kHdUsableWorkspace, ws);  // min x,y,z, max x,y,z, mm
  const Eigen::Vector3d a = hd_mm_to_device_m({ws[0], ws[1], ws[2]});
  const Eigen::Vector3d b = hd_mm_to_device_m({ws[3], ws[4], ws[5]});
  if ((a - b).norm() > 0) info_.workspace = Eigen::AlignedBox3d(a.cwiseMin(b), a.cwiseMax(b));
  // The device's own limits (N; stiffness N/mm): the safety layer takes min(these, --f-max).
  double peak = 0, continuous = 0, stiffness = 0;
  api_->get_doublev(kHdNominalMaxForce, &peak);
  api_->get_doublev(kHdNominalMaxContinuousForce, &continuous);
  api_->get_doublev(kHdNominalMaxStiffness, &stiffness);
  max_force_ = peak;
  info_.max_force = peak > 0 ? peak : std::numeric_limits<double>::infinity();
  info_.max_continuous_force = continuous > 0 ? continuous : std::numeric_limits<double>::infinity();
  info_.max_stiffness = stiffness > 0 ? stiffness * 1e3 : 0;
  info_.limit_source = "HD_NOMINAL_MAX_FORCE, HD_NOMINAL_MAX_CONTINUOUS_FORCE";
  int rate = 0, output_dof = 3, styles = 0;
  api_->get_integerv(kHdUpdateRate, &rate);
  if (rate > 0) {
    info_.max_rate_hz = rate;
    info_.rate_source = "vendor library (HD_UPDATE_RATE)";
  }
  api_->get_integerv(kHdOutputDof, &output_dof);
  info_.renders_torque = output_dof >= 6;
  api_->get_integerv(kHdCalibrationStyle, &styles);
  // The vendor's preference: auto, then inkwell, then encoder reset.
  const int style = (styles & kHdCalibrationAuto) ? kHdCalibrationAuto
                    : (styles & kHdCalibrationInkwell) ? kHdCalibrationInkwell
                                                        : kHdCalibrationEncoderReset;
  const auto fail = [&](const std::string& why) {
    api_->stop_scheduler();
    api_->disable_device(handle_);
    handle_ = kHdInvalidHandle;
    info_.calibration = Calibration::kNeedsUser;
    throw InputError(what + ": " + why);
  };

  // The OpenHaptics sequence (its Calibration and HelloHapticDevice examples): start the servo
  // loop, check the calibration inside a frame on it (inkwell calibration happens only while
  // it runs), update it when the device can, then schedule the servo callback and enable force.
  api_->start_scheduler();
  e = api_->get_error();
  if (e.errorCode != 0) fail("the HD scheduler did not start: " + hd_error_text(e));
  HdCalibrationCall cal{api_, handle_, style, 0};
  api_->schedule_synchronous(&hd_calibration_status, &cal, kHdDefaultSchedulerPriority);
  if (cal.status == kHdCalibrationNeedsUpdate) {
    api_->schedule_synchronous(&hd_calibration_update, &cal, kHdDefaultSchedulerPriority);
    api_->schedule_synchronous(&hd_calibration_status, &cal, kHdDefaultSchedulerPriority);
    status_ = "calibration updated";
  } else {
    status_ = "calibrated";
  }
  // Manual input (inkwell, reset position): the device calibrates once the user acts; wait for
  // it up to calibration_wait, polling as the vendor's example does.
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration<double>(std::max(0.0, params_.calibration_wait));
  while (cal.status == kHdCalibrationNeedsManual && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    api_->schedule_synchronous(&hd_calibration_status, &cal, kHdDefaultSchedulerPriority);
    if (cal.status == kHdCalibrationOk) status_ = "calibrated (after manual input)";
  }
  if (cal.status == kHdCalibrationNeedsManual)
    fail(style == kHdCalibrationEncoderReset
             ? "the device needs calibrating by hand: hold it at its reset position (all links "
               "orthogonal) and reset the encoders with Touch Diagnostic, then start again; no force was rendered"
             : "the device needs calibrating by hand: put the stylus in its inkwell, then start "
               "again (or run Touch Diagnostic); no force was rendered");
  if (cal.status != kHdCalibrationOk) {
    char code[16];
    std::snprintf(code, sizeof code, "0x%04x", cal.status);
    fail(std::string("the calibration could not be updated (HD status ") + code +
         "): run Touch Diagnostic; no force was rendered");
  }
  info_.calibration = Calibration::kCalibrated;

  link_.begin_session();
  running_.store(true, std::memory_order_release);
  schedule_ = api_->schedule_asynchronous(&hd_trampoline, this, kHdMaxSchedulerPriority);
  scheduled_ = true;
  api_->enable(kHdForceOutput);
  e = api_->get_error();
  if (e.errorCode != 0) {
    const std::string err = hd_error_text(e);
    stop(0);
    throw InputError(what + ": force output could not be enabled: " + err);
  }
}

unsigned int OpenHapticsDevice::servo_callback() noexcept {
  api_->begin_frame(handle_);
  double p[3] = {}, v[3] = {};
  int buttons = 0;
  api_->get_doublev(kHdCurrentPosition, p);
  api_->get_doublev(kHdCurrentVelocity, v);
  api_->get_integerv(kHdCurrentButtons, &buttons);
  LinkSample s;
  s.position = hd_mm_to_device_m({p[0], p[1], p[2]});
  s.velocity = hd_mm_to_device_m({v[0], v[1], v[2]});
  s.buttons = static_cast<std::uint32_t>(buttons);
  const bool running = running_.load(std::memory_order_acquire);
  // Stopping: zero. Otherwise the newest command, or zero when the servo thread stopped refreshing it.
  Eigen::Vector3d f = running ? link_.force_to_send() : Eigen::Vector3d::Zero();
  api_->set_doublev(kHdCurrentForce, f.data());
  api_->end_frame(handle_);
  if (api_->get_error().errorCode != 0) {
    hd_errors_.fetch_add(1, std::memory_order_relaxed);
  } else {
    link_.publish(s);  // a frame with an error delivers no sample: the runtime's watchdog decides
  }
  callbacks_.fetch_add(1, std::memory_order_relaxed);
  if (!running) {
    zero_applied_.store(true, std::memory_order_release);
    return kHdCallbackDone;
  }
  return kHdCallbackContinue;
}

std::string OpenHapticsDevice::status() const {
  if (status_.empty()) return {};
  char b[160];
  std::snprintf(b, sizeof b, ", nominal max force %.3g N, continuous %.3g N", max_force_,
                std::isfinite(info_.max_continuous_force) ? info_.max_continuous_force : 0.0);
  return status_ + b;
}

std::vector<DeviceCounter> OpenHapticsDevice::counters() const {
  return {{"stale commands zeroed by the HD callback", stale_commands()},
          {"HD frame errors", hd_errors_.load(std::memory_order_relaxed)},
          {"stops without a confirmed zero frame", unconfirmed_stops()}};
}

DeviceSample OpenHapticsDevice::read(Nanos now) noexcept { return link_.read(now); }

void OpenHapticsDevice::write(const Wrench& wrench, Nanos) noexcept { link_.command(device_force_to_hd(wrench.force)); }

void OpenHapticsDevice::stop(Nanos) noexcept {
  if (handle_ == kHdInvalidHandle) return;
  link_.command(Eigen::Vector3d::Zero());
  if (running_.exchange(false, std::memory_order_acq_rel) && scheduled_) {
    // The callback's last frame commands zero force and ends the callback.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(50);
    while (!zero_applied_.load(std::memory_order_acquire) && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    if (!zero_applied_.load(std::memory_order_acquire)) unconfirmed_stops_.fetch_add(1, std::memory_order_relaxed);
  }
  api_->stop_scheduler();
  if (scheduled_) api_->unschedule(schedule_);
  scheduled_ = false;
  api_->disable_device(handle_);
  handle_ = kHdInvalidHandle;
}

}  // namespace gshaptics
