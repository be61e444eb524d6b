// libFuzzer target for one parser of the peers' WebSocket messages (peer_messages.h), chosen at
// compile time with -DGSHAPTICS_FUZZ_<TARGET>. The parsers are noexcept: any throw (which ends
// the process through std::terminate), crash, sanitizer report or hang is a finding.

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "gshaptics/device/peer_messages.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
#if defined(GSHAPTICS_FUZZ_VIEWER_MESSAGE)
  (void)gshaptics::parse_viewer_tool_message(text);
#elif defined(GSHAPTICS_FUZZ_HAPLY_MESSAGE)
  // The first byte picks the device index (0-3), so short lists and missing devices are reached.
  const int index = size > 0 ? data[0] % 4 : 0;
  (void)gshaptics::parse_haply_state(size > 0 ? text.substr(1) : text, index);
#else
#error "define one of GSHAPTICS_FUZZ_{VIEWER_MESSAGE,HAPLY_MESSAGE}"
#endif
  return 0;
}
