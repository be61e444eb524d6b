#pragma once
/// @file
/// The world cache: a built CollisionWorld (the filtered, registered records in BVH order plus
/// the BVH) in one file, opened with mmap so that a large scene starts without loading, filtering
/// or building, and processes that open the same cache share its pages.
///
/// A cache is keyed by the scene's content (XXH3-64 of the file's bytes, and its size) and by
/// every build parameter (WorldConfig: opacity threshold, sigma, up axis, registration, leaf
/// size) plus the format version. Opening checks, before trusting anything: the header's magic and
/// version, that the file is as long as the header says (a truncated file), XXH3-64 of the
/// header block (a flipped byte in the header), the key (another scene, changed parameters), the
/// layout's bounds, and XXH3-64 of the whole payload (a flipped byte in the records, the nodes or
/// the padding). Any failure returns no world and says why; the caller rebuilds.
///
/// File layout (little-endian, this machine's float formats): a 4096-byte header, the records
/// (64 bytes each) at 4096, the BVH nodes (32 bytes each) after them at a 4096-aligned offset.

#include <cstdint>
#include <optional>
#include <string>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics {

/// What a cached world was built from.
struct WorldCacheKey {
  std::uint64_t scene_hash = 0;   ///< XXH3-64 of the scene's bytes (or of what made an in-memory scene)
  std::uint64_t scene_bytes = 0;  ///< the scene file's size
  std::uint64_t params_hash = 0;  ///< world_config_hash() of the build parameters
  bool operator==(const WorldCacheKey&) const = default;
};

/// XXH3-64 of the build parameters and the cache format version.
[[nodiscard]] std::uint64_t world_config_hash(const WorldConfig& config) noexcept;
/// Hash of a byte range (the scene-content half of a key, and the cache's payload check): the
/// XXH3-64 of every 8 MiB chunk, computed on up to `threads` threads (0: every core, at most 8),
/// then the XXH3-64 of those digests and the size. The value does not depend on the thread
/// count. In parallel because the first pass over freshly mapped pages is what a cache open costs
/// on a virtual machine (bench/RESULTS.md). Throws std::bad_alloc only.
[[nodiscard]] std::uint64_t content_hash(const void* data, std::size_t bytes, unsigned threads = 0);
/// The key of `scene_path` (memory-mapped and hashed: ~0.1 s per GB from the page cache) built
/// with `config`. Throws InputError naming the file when it cannot be read.
[[nodiscard]] WorldCacheKey world_cache_key(const std::string& scene_path, const WorldConfig& config);
/// `dir`/<scene file stem>-<scene hash>-<params hash>.gshworld
[[nodiscard]] std::string world_cache_file(const std::string& dir, const std::string& scene_path,
                                           const WorldCacheKey& key);

/// A world opened from a cache, with what loading its scene had reported (format, version,
/// counts; `path`, `ignored_properties` empty).
struct CachedWorld {
  CollisionWorld world;
  LoadReport source;
};

/// Writes `world` under `key` to `path` (a temporary name, then rename: no partial file), with
/// the scalar fields of `source` (the scene's load report). Throws InputError naming the file
/// when it cannot be written (a read-only folder, a full disk).
void write_world_cache(const CollisionWorld& world, const WorldCacheKey& key, const std::string& path,
                       const LoadReport& source = {});

/// Maps `path` and checks it against `key` (see the file comment). Returns the world, whose
/// records and nodes stay in the mapping (shared, read-only), or nullopt with `why` set
/// ("no cache file", "truncated: ...", "corrupt: payload hash ...", "stale: built from another
/// scene", ...). Never throws for a bad file.
[[nodiscard]] std::optional<CachedWorld> open_world_cache(const std::string& path, const WorldCacheKey& key,
                                                          std::string* why = nullptr);

}  // namespace gshaptics
