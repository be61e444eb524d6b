// Vendor device libraries found at run time: a stand-in libdhd.so loads and reports its devices;
// a missing library and a library without the symbols are explained (file, places, install).

#include "gshaptics/device/vendor_library.h"

#include <gtest/gtest.h>

#include <cstdlib>

namespace gshaptics {
namespace {

TEST(VendorLibrary, FakeDhdLoadsAndCountsDevices) {
  ::setenv("GSHAPTICS_DHD_LIBRARY", GSHAPTICS_FAKE_DHD, 1);
  const VendorLibraryProbe p = probe_dhd_library();
  ::unsetenv("GSHAPTICS_DHD_LIBRARY");
  EXPECT_TRUE(p.available) << p.why;
  EXPECT_EQ(p.devices, 2);
  EXPECT_EQ(p.path, GSHAPTICS_FAKE_DHD);
}

TEST(VendorLibrary, MissingLibraryNamesFilePlacesAndInstall) {
  ::setenv("GSHAPTICS_DHD_LIBRARY", "/nonexistent/libdhd.so", 1);
  const VendorLibraryProbe p = probe_dhd_library();
  ::unsetenv("GSHAPTICS_DHD_LIBRARY");
  EXPECT_FALSE(p.available);
  EXPECT_NE(p.why.find("libdhd.so not found"), std::string::npos) << p.why;
  EXPECT_NE(p.why.find("GSHAPTICS_DHD_LIBRARY=/nonexistent/libdhd.so"), std::string::npos) << p.why;
  EXPECT_NE(p.why.find("Force Dimension SDK"), std::string::npos) << p.why;
  // Without an override: dlopen's own search, with LD_LIBRARY_PATH named.
  const VendorLibraryProbe hd = probe_openhaptics_library();
  if (!hd.available) {
    EXPECT_NE(hd.why.find("libHD.so not found"), std::string::npos) << hd.why;
    EXPECT_NE(hd.why.find("LD_LIBRARY_PATH"), std::string::npos) << hd.why;
    EXPECT_NE(hd.why.find("OpenHaptics"), std::string::npos) << hd.why;
  }
}

TEST(VendorLibrary, WrongLibraryListsTheMissingSymbols) {
  ::setenv("GSHAPTICS_HD_LIBRARY", GSHAPTICS_FAKE_DHD, 1);  // a real library, but not HD
  const VendorLibraryProbe p = probe_openhaptics_library();
  ::unsetenv("GSHAPTICS_HD_LIBRARY");
  EXPECT_FALSE(p.available);
  EXPECT_EQ(p.missing_symbols.size(), 16u);  // every HD function the driver calls
  EXPECT_NE(p.why.find("lacks hdInitDevice"), std::string::npos) << p.why;
}

}  // namespace
}  // namespace gshaptics
