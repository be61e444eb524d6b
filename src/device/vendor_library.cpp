#include "gshaptics/device/vendor_library.h"

#include <dlfcn.h>

#include <cstdlib>

namespace gshaptics {

namespace {

struct Spec {
  const char* kind;
  const char* library;
  const char* env;
  std::vector<const char*> symbols;
  const char* install;
};

VendorLibraryProbe probe(const Spec& spec, void* (*opened)(void*, VendorLibraryProbe&)) {
  VendorLibraryProbe p;
  p.kind = spec.kind;
  p.library = spec.library;
  const char* override_path = std::getenv(spec.env);
  p.path = override_path != nullptr && *override_path ? override_path : spec.library;
  dlerror();
  void* h = dlopen(p.path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (h == nullptr) {
    const char* err = dlerror();
    const char* ld = std::getenv("LD_LIBRARY_PATH");
    p.why = std::string(spec.library) + " not found" +
            (override_path ? std::string(" at ") + spec.env + "=" + override_path : std::string()) +
            " (searched " + (override_path ? "that path" : std::string("LD_LIBRARY_PATH=") + (ld ? ld : "(unset)") +
            ", the ld.so cache, /lib and /usr/lib") + "; dlopen: " + (err ? err : "?") + "). " + spec.install;
    return p;
  }
  for (const char* s : spec.symbols)
    if (dlsym(h, s) == nullptr) p.missing_symbols.push_back(s);
  if (!p.missing_symbols.empty()) {
    p.why = p.path + " lacks";
    for (const std::string& s : p.missing_symbols) p.why += " " + s;
    p.why += ": not the expected vendor library, or too old a version. " + std::string(spec.install);
    dlclose(h);
    return p;
  }
  p.available = true;
  p.handle = h;
  if (opened != nullptr) opened(h, p);
  // Kept loaded: vendor libraries start threads that must not outlive their code.
  return p;
}

void* count_dhd(void* h, VendorLibraryProbe& p) {
  using Count = int (*)();
  if (auto f = reinterpret_cast<Count>(dlsym(h, "dhdGetDeviceCount"))) p.devices = f();
  return h;
}

}  // namespace

VendorLibraryProbe probe_dhd_library() {
  return probe({"dhd", "libdhd.so", "GSHAPTICS_DHD_LIBRARY",
                {"dhdGetDeviceCount", "dhdOpenID", "dhdClose", "dhdGetPosition", "dhdGetLinearVelocity",
                 "dhdSetForce", "dhdGetButton", "dhdEnableForce", "dhdGetStatus", "dhdGetSystemName",
                 "dhdGetSystemType", "dhdErrorGetLastStr"},
                "Install the Force Dimension SDK (forcedimension.com, Linux x86_64) and put its "
                "lib/release/lin-x86_64-gcc on LD_LIBRARY_PATH, or set GSHAPTICS_DHD_LIBRARY to libdhd.so."},
               count_dhd);
}

VendorLibraryProbe probe_openhaptics_library() {
  return probe({"openhaptics", "libHD.so", "GSHAPTICS_HD_LIBRARY",
                {"hdInitDevice", "hdDisableDevice", "hdGetError", "hdBeginFrame", "hdEndFrame",
                 "hdGetDoublev", "hdGetIntegerv", "hdSetDoublev", "hdEnable", "hdCheckCalibration",
                 "hdUpdateCalibration", "hdStartScheduler", "hdStopScheduler", "hdScheduleAsynchronous",
                 "hdScheduleSynchronous", "hdUnschedule"},
                "Install 3D Systems' OpenHaptics for Linux and the Touch device driver (libHD.so in "
                "/usr/lib), or set GSHAPTICS_HD_LIBRARY to libHD.so."},
               nullptr);
}

}  // namespace gshaptics
