#pragma once
/// @file
/// Finding a haptic vendor's device library at run time (dlopen), so nothing proprietary is needed
/// at build time, and saying exactly why when it is not there: the file searched for, where, and
/// what to install.

#include <string>
#include <vector>

namespace gshaptics {

/// What probing one vendor library found.
struct VendorLibraryProbe {
  std::string kind;            ///< "dhd", "openhaptics"
  std::string library;         ///< the file searched for ("libdhd.so")
  bool available = false;      ///< loaded, and every symbol gshaptics needs is in it
  std::string path;            ///< what was loaded (the override or the bare name dlopen resolved)
  std::vector<std::string> missing_symbols;
  int devices = -1;            ///< devices the library reports; -1: its API has no count
  /// When not available: the file, the places searched (the override variable, LD_LIBRARY_PATH,
  /// the ld.so cache and default directories, as dlopen(3) searches) and what to install.
  std::string why;
  /// The dlopen handle when available (kept loaded for the life of the process: vendor libraries
  /// start threads that must not outlive their code); nullptr otherwise.
  void* handle = nullptr;
};

/// Force Dimension's DHD library: $GSHAPTICS_DHD_LIBRARY, else "libdhd.so" through dlopen's
/// search. Needs the functions DhdDevice calls (vendor_devices.h; C linkage, Force Dimension SDK
/// dhdc.h); calls dhdGetDeviceCount() for `devices`.
[[nodiscard]] VendorLibraryProbe probe_dhd_library();

/// 3D Systems' OpenHaptics HD library: $GSHAPTICS_HD_LIBRARY, else "libHD.so". Needs the
/// functions OpenHapticsDevice calls (vendor_devices.h; OpenHaptics HDAPI, hd.h). The HD API has
/// no device count: `devices` stays -1.
[[nodiscard]] VendorLibraryProbe probe_openhaptics_library();

}  // namespace gshaptics
