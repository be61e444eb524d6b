// libFuzzer target for one scene reader, chosen at compile time with -DGSHAPTICS_FUZZ_<FORMAT>.
// A reader may reject input only with gshaptics::InputError; anything else (another exception,
// a crash, a sanitizer report, a hang, an allocation past -rss_limit_mb) is a finding.

#include <cstddef>
#include <cstdint>
#include <span>

#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  try {
#if defined(GSHAPTICS_FUZZ_PLY)
    (void)gshaptics::read_inria_ply(bytes, "fuzz.ply");
#elif defined(GSHAPTICS_FUZZ_COMPRESSED_PLY)
    (void)gshaptics::read_compressed_ply(bytes, "fuzz.compressed.ply");
#elif defined(GSHAPTICS_FUZZ_SPLAT)
    (void)gshaptics::read_splat(bytes, "fuzz.splat");
#elif defined(GSHAPTICS_FUZZ_SPZ)
    (void)gshaptics::read_spz(bytes, "fuzz.spz");
#else
#error "define one of GSHAPTICS_FUZZ_{PLY,COMPRESSED_PLY,SPLAT,SPZ}"
#endif
  } catch (const gshaptics::InputError&) {
  }
  return 0;
}
