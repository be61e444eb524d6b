#include "support/scenes.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics::test {

std::string scene_path(const std::string& name) {
  if (name == "truck.splat") return data_path(name);
  return std::string(GSHAPTICS_SCENES_DIR) + "/" + name;
}

std::string missing_scenes_reason() {
  // One scene of each kind the tests read; the folder holds them all or none.
  for (const char* name : {"donut.ply", "biker.spz", "karangkidul_crop.ply"})
    if (!std::filesystem::exists(scene_path(name)))
      return "real scenes not found (no " + scene_path(name) +
             "): put the scenes (donut.ply, biker.*, karangkidul_crop.ply, ...) in " GSHAPTICS_SCENES_DIR
             " or configure with -DGSHAPTICS_SCENES_DIR=<folder>";
  return "";
}

LoadOptions with_color() {
  LoadOptions o;
  o.keep_color = true;
  return o;
}
std::string data_path(const std::string& name) { return std::string(GSHAPTICS_DATA_DIR) + "/" + name; }

std::string temp_path(const std::string& suffix) {
  static std::atomic<int> counter{0};
  return (std::filesystem::temp_directory_path() /
          ("gshaptics_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + suffix))
      .string();
}

void write_bytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

std::vector<std::uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string load_error(const std::string& path) {
  try {
    (void)load_scene(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

const CollisionWorld& truck_world() {
  static const CollisionWorld world = [] {
    const LoadedScene s = load_scene(data_path("truck.splat"));
    WorldConfig cfg;
    cfg.registration = load_registration_file(data_path("truck.registration.json"));
    return CollisionWorld::build(s.scene, cfg);
  }();
  return world;
}

}  // namespace gshaptics::test
