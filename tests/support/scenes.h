#pragma once
// Paths of the real scenes used by tests, and small helpers to write test files.

#include <cstdint>
#include <string>
#include <vector>

#include "gshaptics/collision/collision_world.h"

namespace gshaptics::test {

/// The bundled Truck (data/truck.splat) registered by data/truck.registration.json with the
/// default WorldConfig, built once per test binary and shared (immutable).
const CollisionWorld& truck_world();

/// Full path of a scene in ../shared/data/scenes.
std::string scene_path(const std::string& name);
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
