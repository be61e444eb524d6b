#pragma once
// Paths of the real scenes used by tests, and small helpers to write test files.

#include <cstdint>
#include <string>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics::test {

/// The bundled Truck (data/truck.splat) registered by data/truck.registration.json with the
/// default WorldConfig, built once per test binary and shared (immutable).
const CollisionWorld& truck_world();

/// Full path of a real scene in the scenes folder (GSHAPTICS_SCENES_DIR, by default
/// ../shared/data/scenes beside the repository); "truck.splat" is the bundled data/truck.splat.
std::string scene_path(const std::string& name);
/// Why the real scenes cannot be used ("" when the scenes folder has them): the message a test
/// that needs them skips with.
std::string missing_scenes_reason();
/// Load options that keep colour and SH bands.
LoadOptions with_color();

/// First line of a test that needs the real scenes: skips it, saying where to put them, when
/// they are not there. Tests on the bundled Truck need no such line and always run.
#define GSHAPTICS_REQUIRE_SCENES()                                                     \
  do {                                                                                 \
    if (const std::string why = ::gshaptics::test::missing_scenes_reason(); !why.empty()) \
      GTEST_SKIP() << why;                                                             \
  } while (0)
/// Full path of a file in the repository's data/ folder.
std::string data_path(const std::string& name);
/// A fresh temporary file path (not created) with the given suffix.
std::string temp_path(const std::string& suffix);
/// Writes bytes to a file; fails the test on error.
void write_bytes(const std::string& path, const std::vector<std::uint8_t>& bytes);
std::vector<std::uint8_t> read_bytes(const std::string& path);
/// The InputError message load_scene(path) throws, or "" when it loads.
std::string load_error(const std::string& path);

}  // namespace gshaptics::test
