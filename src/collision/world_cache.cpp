#include "gshaptics/collision/world_cache.h"

#include <sys/stat.h>
#include <xxhash.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <thread>
#include <vector>

#include "gshaptics/error.h"
#include "gshaptics/io/mapped_file.h"

namespace gshaptics {

namespace {

constexpr char kMagic[8] = {'G', 'S', 'H', 'W', 'O', 'R', 'L', 'D'};
constexpr std::uint32_t kVersion = 4;  // 2: 64-byte records with a quaternion; 3: chunked payload hash; 4: header hash
constexpr std::uint64_t kHeaderBytes = 4096;

// The header as stored (plain data, fixed layout, padded to kHeaderBytes in the file).
struct Header {
  char magic[8];
  std::uint32_t version;
  std::uint32_t record_bytes;  // sizeof(CollisionGaussian)
  std::uint32_t node_bytes;    // sizeof(BvhNode)
  std::int32_t depth;
  std::uint64_t scene_hash, scene_bytes, params_hash;
  std::uint64_t n_records, n_nodes;
  std::uint64_t records_offset, nodes_offset, file_bytes;
  std::uint64_t payload_hash;  // content_hash() of [kHeaderBytes, file_bytes)
  double scene_to_world[8];    // scale, rotation w x y z, translation x y z
  double up[3], lo[3], hi[3];
  // The build parameters, for information (the key holds their hash).
  float min_opacity;
  std::int32_t up_axis, leaf_size;
  double sigma;
  double registration[8];
  // The scene's load report (scalars).
  std::int32_t src_format, src_frame, src_version, src_sh_degree;
  std::uint64_t src_in_file, src_loaded, src_non_finite, src_zero_quaternion, src_bad_scale;
  // XXH3-64 of the whole kHeaderBytes block as stored, with this field zero: no byte of the
  // header (build parameters, frame, bounds, enums) is trusted unchecked.
  std::uint64_t header_hash;
};
static_assert(sizeof(Header) <= kHeaderBytes);
static_assert(std::is_trivially_copyable_v<Header>);

std::uint64_t align_up(std::uint64_t x) { return (x + kHeaderBytes - 1) / kHeaderBytes * kHeaderBytes; }

// Header::header_hash of a stored header block (kHeaderBytes bytes).
std::uint64_t header_block_hash(const std::uint8_t* block) {
  std::uint8_t copy[kHeaderBytes];
  std::memcpy(copy, block, kHeaderBytes);
  std::memset(copy + offsetof(Header, header_hash), 0, sizeof(Header::header_hash));
  return XXH3_64bits(copy, kHeaderBytes);
}

void put_transform(double out[8], const SimilarityTransform& t) {
  out[0] = t.scale;
  out[1] = t.rotation.w();
  out[2] = t.rotation.x();
  out[3] = t.rotation.y();
  out[4] = t.rotation.z();
  out[5] = t.translation.x();
  out[6] = t.translation.y();
  out[7] = t.translation.z();
}

SimilarityTransform get_transform(const double in[8]) {
  SimilarityTransform t;
  t.scale = in[0];
  t.rotation = Eigen::Quaterniond(in[1], in[2], in[3], in[4]);
  t.translation = Eigen::Vector3d(in[5], in[6], in[7]);
  return t;
}

}  // namespace

// Assembles a world from parts (CollisionWorld's friend).
struct WorldCacheAccess {
  static CollisionWorld assemble(const Header& h, std::shared_ptr<const MappedFile> file) {
    CollisionWorld w;
    const std::uint8_t* base = file->bytes().data();
    w.config_.min_opacity = h.min_opacity;
    w.config_.sigma = h.sigma;
    w.config_.up = static_cast<UpAxis>(h.up_axis);
    w.config_.registration = get_transform(h.registration);
    w.config_.leaf_size = h.leaf_size;
    w.scene_to_world_ = get_transform(h.scene_to_world);
    w.up_ = Eigen::Vector3d(h.up[0], h.up[1], h.up[2]);
    w.lo_ = Eigen::Vector3d(h.lo[0], h.lo[1], h.lo[2]);
    w.hi_ = Eigen::Vector3d(h.hi[0], h.hi[1], h.hi[2]);
    w.gaussians_ = std::span<const CollisionGaussian>(
        reinterpret_cast<const CollisionGaussian*>(base + h.records_offset), std::size_t(h.n_records));
    w.bvh_ = Bvh::from_nodes(std::span<const BvhNode>(reinterpret_cast<const BvhNode*>(base + h.nodes_offset),
                                                      std::size_t(h.n_nodes)),
                             h.depth, file);
    w.storage_ = std::move(file);
    return w;
  }
  static void fill(Header& h, const CollisionWorld& w) {
    put_transform(h.scene_to_world, w.scene_to_world_);
    for (int k = 0; k < 3; ++k) {
      h.up[k] = w.up_[k];
      h.lo[k] = w.lo_[k];
      h.hi[k] = w.hi_[k];
    }
    h.min_opacity = w.config_.min_opacity;
    h.up_axis = static_cast<std::int32_t>(w.config_.up);
    h.leaf_size = w.config_.leaf_size;
    h.sigma = w.config_.sigma;
    put_transform(h.registration, w.config_.registration);
  }
};

std::uint64_t content_hash(const void* data, std::size_t bytes, unsigned threads) {
  constexpr std::size_t kChunk = std::size_t(8) << 20;
  const std::size_t n = (bytes + kChunk - 1) / kChunk;
  std::vector<std::uint64_t> digest(n + 1);
  const auto* p = static_cast<const std::uint8_t*>(data);
  std::atomic<std::size_t> next{0};
  const auto work = [&] {
    for (std::size_t i = next.fetch_add(1); i < n; i = next.fetch_add(1))
      digest[i] = XXH3_64bits(p + i * kChunk, std::min(kChunk, bytes - i * kChunk));
  };
  std::size_t t = threads > 0 ? threads : std::max(1u, std::thread::hardware_concurrency());
  t = std::min<std::size_t>({t, 8, std::max<std::size_t>(n, 1)});
  std::vector<std::thread> helpers;
  try {
    for (std::size_t k = 1; k < t; ++k) helpers.emplace_back(work);
  } catch (const std::system_error&) {
    // No thread to be had: the chunks left are hashed on this one.
  }
  work();
  for (std::thread& h : helpers) h.join();
  digest[n] = bytes;
  return XXH3_64bits(digest.data(), digest.size() * sizeof(std::uint64_t));
}

std::uint64_t world_config_hash(const WorldConfig& c) noexcept {
  // Field by field (no padding bytes in the hash).
  double buf[16] = {};
  int n = 0;
  buf[n++] = double(kVersion);
  buf[n++] = double(c.min_opacity);
  buf[n++] = c.sigma;
  buf[n++] = double(static_cast<int>(c.up));
  put_transform(buf + n, c.registration);
  n += 8;
  buf[n++] = double(c.leaf_size);
  buf[n++] = double(sizeof(CollisionGaussian));
  buf[n++] = double(sizeof(BvhNode));
  return XXH3_64bits(buf, sizeof(double) * std::size_t(n));
}

WorldCacheKey world_cache_key(const std::string& scene_path, const WorldConfig& config) {
  const MappedFile file(scene_path);
  WorldCacheKey k;
  k.scene_bytes = file.bytes().size();
  k.scene_hash = content_hash(file.bytes().data(), file.bytes().size());
  k.params_hash = world_config_hash(config);
  return k;
}

std::string world_cache_file(const std::string& dir, const std::string& scene_path, const WorldCacheKey& key) {
  char hex[40];
  std::snprintf(hex, sizeof hex, "%016llx-%016llx", static_cast<unsigned long long>(key.scene_hash),
                static_cast<unsigned long long>(key.params_hash));
  return (std::filesystem::path(dir) / (std::filesystem::path(scene_path).stem().string() + "-" + hex + ".gshworld"))
      .string();
}

void write_world_cache(const CollisionWorld& world, const WorldCacheKey& key, const std::string& path,
                       const LoadReport& source) {
  Header h{};
  h.src_format = static_cast<std::int32_t>(source.format);
  h.src_frame = static_cast<std::int32_t>(source.frame);
  h.src_version = source.version;
  h.src_sh_degree = source.sh_degree;
  h.src_in_file = source.in_file;
  h.src_loaded = source.loaded;
  h.src_non_finite = source.skipped_non_finite;
  h.src_zero_quaternion = source.skipped_zero_quaternion;
  h.src_bad_scale = source.skipped_bad_scale;
  std::memcpy(h.magic, kMagic, sizeof kMagic);
  h.version = kVersion;
  h.record_bytes = sizeof(CollisionGaussian);
  h.node_bytes = sizeof(BvhNode);
  h.depth = world.bvh().depth();
  h.scene_hash = key.scene_hash;
  h.scene_bytes = key.scene_bytes;
  h.params_hash = key.params_hash;
  h.n_records = world.size();
  h.n_nodes = world.bvh().nodes().size();
  h.records_offset = kHeaderBytes;
  h.nodes_offset = align_up(h.records_offset + h.n_records * sizeof(CollisionGaussian));
  h.file_bytes = h.nodes_offset + h.n_nodes * sizeof(BvhNode);
  WorldCacheAccess::fill(h, world);
  const std::size_t pad = std::size_t(h.nodes_offset - (h.records_offset + h.n_records * sizeof(CollisionGaussian)));
  const std::string zeros(std::max<std::size_t>(pad, kHeaderBytes - sizeof(Header)), '\0');

  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  const auto discard = [&](const std::string& why) {  // nothing half-written is left behind
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw file_error(path, why);
  };
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw file_error(path, "cannot write the world cache here (" + std::string(std::strerror(errno)) + ")");
    out.write(reinterpret_cast<const char*>(&h), sizeof h);
    out.write(zeros.data(), std::streamsize(kHeaderBytes - sizeof h));
    out.write(reinterpret_cast<const char*>(world.gaussians().data()),
              std::streamsize(world.size() * sizeof(CollisionGaussian)));
    out.write(zeros.data(), std::streamsize(pad));
    out.write(reinterpret_cast<const char*>(world.bvh().nodes().data()),
              std::streamsize(world.bvh().nodes().size() * sizeof(BvhNode)));
    out.flush();
    if (!out) discard("writing the world cache failed (disk full?)");
  }
  // The payload hash over exactly the bytes written after the header (padding included), read
  // back from the file as open_world_cache will read them; then the header is written again.
  bool complete = false;
  try {
    const MappedFile written(tmp);
    complete = written.bytes().size() == h.file_bytes;
    if (complete) h.payload_hash = content_hash(written.bytes().data() + kHeaderBytes, h.file_bytes - kHeaderBytes);
  } catch (const InputError&) {
    complete = false;
  }
  if (!complete) discard("writing the world cache failed (the file read back is short: disk full?)");
  {
    // The final header block, hashed exactly as stored (padding bytes included).
    std::uint8_t block[kHeaderBytes] = {};
    h.header_hash = 0;
    std::memcpy(block, &h, sizeof h);
    h.header_hash = header_block_hash(block);
    std::memcpy(block + offsetof(Header, header_hash), &h.header_hash, sizeof h.header_hash);
    std::fstream out(tmp, std::ios::binary | std::ios::in | std::ios::out);
    out.write(reinterpret_cast<const char*>(block), sizeof block);
    out.flush();
    if (!out) discard("writing the world cache failed (disk full?)");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw file_error(path, "cannot rename the world cache into place: " + ec.message());
  }
}

std::optional<CachedWorld> open_world_cache(const std::string& path, const WorldCacheKey& key, std::string* why) {
  const auto fail = [why](const std::string& w) -> std::optional<CachedWorld> {
    if (why != nullptr) *why = w;
    return std::nullopt;
  };
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return fail("no cache file");
  std::shared_ptr<const MappedFile> file;
  try {
    file = std::make_shared<const MappedFile>(path);
  } catch (const std::exception& e) {
    return fail(std::string("unreadable: ") + e.what());
  }
  const std::span<const std::uint8_t> bytes = file->bytes();
  if (bytes.size() < kHeaderBytes) return fail("truncated: shorter than its header");
  Header h;
  std::memcpy(&h, bytes.data(), sizeof h);
  if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0) return fail("not a gshaptics world cache");
  if (h.version != kVersion) return fail("written by another cache format version");
  if (h.record_bytes != sizeof(CollisionGaussian) || h.node_bytes != sizeof(BvhNode))
    return fail("written by a build with other record layouts");
  if (h.file_bytes != bytes.size())
    return fail("truncated: " + std::to_string(bytes.size()) + " bytes of " + std::to_string(h.file_bytes));
  if (header_block_hash(bytes.data()) != h.header_hash) return fail("corrupt: header hash mismatch");
  if (h.scene_hash != key.scene_hash || h.scene_bytes != key.scene_bytes) return fail("stale: built from another scene");
  if (h.params_hash != key.params_hash) return fail("stale: built with other parameters");
  const bool layout_ok = h.records_offset == kHeaderBytes && h.n_records > 0 &&
                         h.n_records < (std::uint64_t(1) << 32) &&
                         h.records_offset + h.n_records * sizeof(CollisionGaussian) <= h.nodes_offset &&
                         h.nodes_offset % kHeaderBytes == 0 && h.n_nodes > 0 &&
                         h.nodes_offset + h.n_nodes * sizeof(BvhNode) == h.file_bytes && h.depth > 0 &&
                         h.depth < Bvh::kMaxDepth;
  if (!layout_ok) return fail("corrupt: inconsistent layout");
  if (content_hash(bytes.data() + kHeaderBytes, bytes.size() - kHeaderBytes) != h.payload_hash)
    return fail("corrupt: payload hash mismatch");
  // The header hash guards against damage, not against a file made to pass it: the values the
  // world uses as numbers are checked for finiteness too.
  for (double v : h.scene_to_world)
    if (!std::isfinite(v)) return fail("corrupt: header transform");
  LoadReport src;
  src.format = static_cast<SceneFormat>(h.src_format);
  src.frame = static_cast<SceneFrame>(h.src_frame);
  src.version = h.src_version;
  src.sh_degree = h.src_sh_degree;
  src.in_file = h.src_in_file;
  src.loaded = h.src_loaded;
  src.skipped_non_finite = h.src_non_finite;
  src.skipped_zero_quaternion = h.src_zero_quaternion;
  src.skipped_bad_scale = h.src_bad_scale;
  return CachedWorld{WorldCacheAccess::assemble(h, std::move(file)), src};
}

}  // namespace gshaptics
