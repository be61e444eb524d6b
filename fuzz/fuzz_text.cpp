// libFuzzer target for one parser of the text files a user hands the CLI, chosen at compile time
// with -DGSHAPTICS_FUZZ_<TARGET>. A parser may reject input only with gshaptics::InputError;
// anything else (another exception, a crash, a sanitizer report, a hang) is a finding.

#include <cstddef>
#include <cstdint>
#include <string>

#include "gshaptics/error.h"
#if defined(GSHAPTICS_FUZZ_REGISTRATION)
#include "gshaptics/scene/registration.h"
#elif defined(GSHAPTICS_FUZZ_POSE_LOG)
#include "gshaptics/device/replay_device.h"
#else
#error "define one of GSHAPTICS_FUZZ_{REGISTRATION,POSE_LOG}"
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
#if defined(GSHAPTICS_FUZZ_REGISTRATION)
    (void)gshaptics::parse_registration_json(text, "fuzz.registration.json");
#else
    (void)gshaptics::parse_pose_log(text, "fuzz_pose_log.csv");
#endif
  } catch (const gshaptics::InputError&) {
  }
  return 0;
}
