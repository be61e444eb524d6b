// The device registry: every kind it lists opens, or fails with a one-line reason that names
// the device; unknown kinds and bad arguments are named with the known grammars; list() gives
// one row per kind or device found. Runs without any vendor library on the machine.

#include "gshaptics/device/device_registry.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <string>

#include "gshaptics/error.h"
#ifdef GSHAPTICS_HAVE_HAPLY
#include "gshaptics/device/haply_device.h"
#endif

namespace gshaptics {
namespace {

DeviceRegistry& registry() {
  // Nothing on the search path: the vendor kinds must say why they cannot open.
  ::unsetenv("GSHAPTICS_DHD_LIBRARY");
  ::unsetenv("GSHAPTICS_HD_LIBRARY");
#ifdef GSHAPTICS_HAVE_HAPLY
  register_haply_device();
  register_haply_device();  // idempotent
#endif
  return device_registry();
}

TEST(DeviceRegistry, EveryKindOpensOrSaysWhyInOneLine) {
  DeviceRegistry& r = registry();
  ASSERT_GE(r.kinds().size(), 3u);
  const std::string log = ::testing::TempDir() + "/registry_replay.csv";
  std::ofstream(log) << "time_s,x,y,z\n0,0,0,0\n0.1,0,0,0.01\n";
  for (const DeviceKind& k : r.kinds()) {
    ASSERT_FALSE(k.grammar.empty());
    ASSERT_FALSE(k.summary.empty()) << k.name;
    const std::string spec = k.name == "replay" ? "replay:" + log : k.name;
    try {
      const std::unique_ptr<HapticDevice> d = r.open(spec);
      ASSERT_NE(d, nullptr) << spec;
      EXPECT_FALSE(d->info().name.empty()) << spec;
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.find('\n'), std::string::npos) << spec << ": " << what;
      EXPECT_NE(what.find(k.name), std::string::npos) << "the reason names the device: " << what;
    }
  }
#ifdef GSHAPTICS_HAVE_HAPLY
  EXPECT_NE(r.find("haply:2"), nullptr);
#endif
  // Without the vendor libraries, the vendor kinds cannot open, and say what is missing.
  try {
    (void)r.open("dhd");
    ADD_FAILURE() << "libdhd.so should be missing here";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("libdhd.so"), std::string::npos) << e.what();
  }
}

TEST(DeviceRegistry, UnknownKindsAndBadArgumentsAreNamed) {
  DeviceRegistry& r = registry();
  try {
    r.check("glove:3");
    FAIL();
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'glove:3'"), std::string::npos) << what;
    EXPECT_NE(what.find("dhd[:N]"), std::string::npos) << what;
    EXPECT_NE(what.find("replay:FILE"), std::string::npos) << what;
  }
  EXPECT_THROW(r.check("dhd:x"), InputError);
  EXPECT_THROW(r.check("dhd:64"), InputError);
  EXPECT_NO_THROW(r.check("dhd:3"));
  EXPECT_THROW(r.check("replay"), InputError);
  EXPECT_EQ(r.find("dhdx"), nullptr);  // a prefix is not a kind
  EXPECT_EQ(device_index_arg("dhd:7", "7"), 7);
  DeviceKind dup;
  dup.name = "dhd";
  EXPECT_THROW(r.add(dup), InputError);
}

TEST(DeviceRegistry, ListGivesARowPerKindWithAReason) {
  DeviceRegistry& r = registry();
  DeviceOptions o;
  o.haply_url = "ws://127.0.0.1:1/";  // nothing listens there: Haply says so
  const std::vector<DeviceStatus> rows = r.list(o);
  ASSERT_GE(rows.size(), r.kinds().size());
  bool dhd = false;
  for (const DeviceStatus& s : rows) {
    EXPECT_FALSE(s.note.empty()) << s.spec;
    EXPECT_EQ(s.note.find('\n'), std::string::npos) << s.spec << ": " << s.note;
    if (s.spec.rfind("dhd", 0) == 0) {
      dhd = true;
      EXPECT_FALSE(s.available);
    }
  }
  EXPECT_TRUE(dhd);
}

}  // namespace
}  // namespace gshaptics
