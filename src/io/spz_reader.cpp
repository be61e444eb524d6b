// Niantic SPZ reader. v2/v3: the whole file is one gzip stream holding a 16-byte header and the
// attribute arrays; v4: an uncompressed 32-byte "NGSP" header, a table of contents of
// (compressed size, uncompressed size) pairs, then one zstd frame per attribute stream
// (positions, alphas, colours, scales, rotations, spherical harmonics). Layouts as checked on
// biker.spz in SOURCES.md and as published by Niantic (github.com/nianticlabs/spz). Coordinates
// are left in SPZ's own frame (x right, y up, z back).

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "detail/accept_gaussian.h"
#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"

namespace gshaptics {

namespace {

constexpr std::uint32_t kMagic = 0x5053474e;  // "NGSP" little-endian

std::uint32_t u32_at(const std::uint8_t* p) { std::uint32_t v; std::memcpy(&v, p, 4); return v; }
std::uint64_t u64_at(const std::uint8_t* p) { std::uint64_t v; std::memcpy(&v, p, 8); return v; }

int sh_coeffs(int degree) { return degree <= 0 ? 0 : degree == 1 ? 3 : degree == 2 ? 8 : 15; }

// Inflates a gzip stream into exactly `want` bytes (or fewer if the stream is shorter).
std::vector<std::uint8_t> gunzip(std::span<const std::uint8_t> in, std::size_t want,
                                 const std::string& path) {
  std::vector<std::uint8_t> out(want);
  z_stream zs{};
  if (inflateInit2(&zs, 16 + MAX_WBITS) != Z_OK) throw file_error(path, "zlib: cannot start inflate");
  zs.next_in = const_cast<Bytef*>(in.data());
  zs.avail_in = uInt(std::min<std::size_t>(in.size(), std::numeric_limits<uInt>::max()));
  zs.next_out = out.data();
  zs.avail_out = uInt(want);
  const int rc = inflate(&zs, Z_SYNC_FLUSH);
  const std::size_t got = want - zs.avail_out;
  inflateEnd(&zs);
  if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR)
    throw file_error(path, std::string("gzip stream is corrupt (zlib: ") + (zs.msg ? zs.msg : "error") + ")");
  out.resize(got);
  return out;
}

struct Streams {
  const std::uint8_t *positions, *alphas, *colors, *scales, *rotations;
  int rotation_bytes;
  const std::uint8_t* sh = nullptr;  // n * coefficients * 3 bytes (coefficient-major, RGB inner)
  int sh_coefficients = 0;           // per colour channel
};

void decode(const Streams& s, std::uint64_t n, int fractional_bits, const std::string& path,
            LoadedScene& out, const ProgressFn& progress, bool keep_color) {
  const float pos_scale = 1.0f / float(1u << fractional_bits);
  const std::uint64_t step = std::max<std::uint64_t>(1, n / 50);
  out.scene.reserve(n);
  if (keep_color && s.sh != nullptr) out.scene.sh_rest_count = 3 * s.sh_coefficients;
  for (std::uint64_t i = 0; i < n; ++i) {
    float pos[3], scale[3], q[4];
    for (int k = 0; k < 3; ++k) {
      const std::uint8_t* b = s.positions + 9 * i + 3 * std::size_t(k);
      std::int32_t v = std::int32_t(b[0] | (b[1] << 8) | (b[2] << 16));
      if (v & 0x800000) v -= 0x1000000;  // sign-extend 24 bits
      pos[k] = float(v) * pos_scale;
      scale[k] = std::exp(float(s.scales[3 * i + std::size_t(k)]) / 16.0f - 10.0f);
    }
    if (s.rotation_bytes == 4) {  // v3+: largest index in 2 bits, three signed 9-bit magnitudes
      std::uint32_t comp = u32_at(s.rotations + 4 * i);
      const int largest = int(comp >> 30);
      constexpr std::uint32_t kMask = (1u << 9) - 1;
      float xyzw[4] = {0, 0, 0, 0}, sum = 0;
      for (int k = 3; k >= 0; --k) {
        if (k == largest) continue;
        const float mag = 0.70710678f * float(comp & kMask) / float(kMask);
        xyzw[k] = ((comp >> 9) & 1u) ? -mag : mag;
        comp >>= 10;
        sum += xyzw[k] * xyzw[k];
      }
      xyzw[largest] = std::sqrt(std::max(0.f, 1.f - sum));
      q[0] = xyzw[3]; q[1] = xyzw[0]; q[2] = xyzw[1]; q[3] = xyzw[2];
    } else {  // v2: x, y, z as (b / 127.5 - 1), w >= 0 rebuilt from the norm
      const std::uint8_t* r = s.rotations + 3 * i;
      q[1] = float(r[0]) / 127.5f - 1.f;
      q[2] = float(r[1]) / 127.5f - 1.f;
      q[3] = float(r[2]) / 127.5f - 1.f;
      q[0] = std::sqrt(std::max(0.f, 1.f - (q[1] * q[1] + q[2] * q[2] + q[3] * q[3])));
    }
    if (detail::accept_gaussian(pos, scale, q, float(s.alphas[i]) / 255.f, std::uint32_t(i), out.scene, out.report) &&
        keep_color) {
      // SPZ stores colour as f_dc * 0.15 + 0.5, in bytes (Niantic's colorScale).
      const std::uint8_t* c = s.colors + 3 * i;
      out.scene.colors_dc.emplace_back((float(c[0]) / 255.f - 0.5f) / 0.15f, (float(c[1]) / 255.f - 0.5f) / 0.15f,
                                       (float(c[2]) / 255.f - 0.5f) / 0.15f);
      // Higher SH bands: bytes (v - 128) / 128, stored coefficient-major with RGB inner; INRIA's
      // f_rest is channel-major (f_rest_{c * K + k}).
      const int K = s.sh_coefficients;
      for (int ch = 0; ch < 3 && s.sh != nullptr; ++ch)
        for (int k = 0; k < K; ++k)
          out.scene.sh_rest.push_back((float(s.sh[(i * std::size_t(K) + std::size_t(k)) * 3 + std::size_t(ch)]) - 128.f) / 128.f);
    }
    if (progress && i % step == 0) progress(double(i) / double(n));
  }
  (void)path;
}

// One gzip member holding `data` (zlib, window 15 + 16 = gzip wrapper).
std::vector<std::uint8_t> gzip(const std::vector<std::uint8_t>& data, const std::string& path) {
  z_stream zs{};
  if (deflateInit2(&zs, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    throw file_error(path, "zlib: deflateInit2 failed");
  std::vector<std::uint8_t> out(deflateBound(&zs, uLong(data.size())) + 32);
  zs.next_in = const_cast<Bytef*>(data.data());
  zs.avail_in = uInt(data.size());
  zs.next_out = out.data();
  zs.avail_out = uInt(out.size());
  const int rc = deflate(&zs, Z_FINISH);
  out.resize(zs.total_out);
  deflateEnd(&zs);
  if (rc != Z_STREAM_END) throw file_error(path, "zlib: deflate did not finish");
  return out;
}

// The v4 layout: an uncompressed 32-byte header, a table of contents of (compressed size,
// uncompressed size) pairs, then one zstd frame per attribute stream. Validates the header and
// every stream it uses, and decompresses them.
struct V4Streams {
  std::uint32_t version = 0;
  std::uint64_t n = 0;
  int sh_degree = 0, frac = 0, used = 0;
  std::vector<std::uint8_t> data[6];
};

V4Streams read_v4_streams(std::span<const std::uint8_t> bytes, const std::string& path) {
  if (bytes.size() < 32) throw file_error(path, "SPZ v4: header truncated (" + std::to_string(bytes.size()) + " of 32 bytes)");
  const std::uint32_t version = u32_at(bytes.data() + 4);
  const std::uint64_t n = u32_at(bytes.data() + 8);
  const int sh_degree = bytes[12], frac = bytes[13], n_streams = bytes[15];
  const std::uint32_t toc = u32_at(bytes.data() + 16);
  if (version < 4) throw file_error(path, "SPZ: 'NGSP' header with version " + std::to_string(version) + " (expected 4)");
  if (version > 4) throw file_error(path, "SPZ version " + std::to_string(version) + " is not supported (up to 4)");
  if (sh_degree > 3 || frac > 24) throw file_error(path, "SPZ v4: bad header (SH degree " + std::to_string(sh_degree) + ", fractional bits " + std::to_string(frac) + ")");
  if (n_streams < 5) throw file_error(path, "SPZ v4: " + std::to_string(n_streams) + " streams, expected at least 5");
  if (n == 0) throw file_error(path, "SPZ declares 0 points");
  const std::uint64_t toc_end = std::uint64_t(toc) + 16ull * std::uint64_t(n_streams);
  if (toc < 32 || toc_end > bytes.size()) throw file_error_at(path, toc, "SPZ v4: table of contents outside the file");
  // Uncompressed sizes the header implies, per stream.
  const std::uint64_t want[6] = {9 * n, n, 3 * n, 3 * n, 4 * n, 3 * n * std::uint64_t(sh_coeffs(sh_degree))};
  const int used = sh_degree > 0 ? 6 : 5;
  if (n_streams < used) throw file_error(path, "SPZ v4: SH degree " + std::to_string(sh_degree) + " needs 6 streams, the file has " + std::to_string(n_streams));
  std::uint64_t offset = toc_end;
  std::vector<std::uint8_t> data[6];
  for (int k = 0; k < n_streams; ++k) {
    const std::uint64_t csize = u64_at(bytes.data() + toc + 16 * std::uint64_t(k));
    const std::uint64_t usize = u64_at(bytes.data() + toc + 16 * std::uint64_t(k) + 8);
    if (csize > bytes.size() || offset + csize > bytes.size())
      throw file_error_at(path, offset, "SPZ v4: stream " + std::to_string(k) + " (" + std::to_string(csize) + " bytes) runs past the end of the file (truncated?)");
    if (k < used) {
      if (usize != want[k])
        throw file_error(path, "SPZ v4: stream " + std::to_string(k) + " holds " + std::to_string(usize) +
                                   " bytes, " + std::to_string(n) + " points need " + std::to_string(want[k]));
      // Before allocating: a zstd frame that declares its size must declare this one, and no
      // frame decodes to more than 32768 bytes per compressed byte (an RLE block: 4 bytes for
      // 128 KB), so a crafted header cannot make the reader allocate what the file cannot hold.
      const unsigned long long declared = ZSTD_getFrameContentSize(bytes.data() + offset, csize);
      if (declared == ZSTD_CONTENTSIZE_ERROR || (declared != ZSTD_CONTENTSIZE_UNKNOWN && declared != usize) ||
          usize > 32768 * std::max<std::uint64_t>(csize, 1))
        throw file_error_at(path, offset, "SPZ v4: stream " + std::to_string(k) + " is corrupt (its " +
                                              std::to_string(csize) + " compressed bytes cannot hold " +
                                              std::to_string(usize) + ")");
      data[k].resize(usize);
      const std::size_t got = ZSTD_decompress(data[k].data(), data[k].size(), bytes.data() + offset, csize);
      if (ZSTD_isError(got) || got != usize)
        throw file_error_at(path, offset, "SPZ v4: stream " + std::to_string(k) + " is corrupt (zstd: " +
                                              (ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short") + ")");
    }
    offset += csize;
  }
  V4Streams v;
  v.version = version;
  v.n = n;
  v.sh_degree = sh_degree;
  v.frac = frac;
  v.used = used;
  for (int k = 0; k < 6; ++k) v.data[k] = std::move(data[k]);
  return v;
}

}  // namespace

std::vector<std::uint8_t> spz_as_gzip(std::span<const std::uint8_t> bytes, const std::string& path) {
  if (bytes.size() >= 2 && bytes[0] == 0x1f && bytes[1] == 0x8b)
    return std::vector<std::uint8_t>(bytes.begin(), bytes.end());
  if (bytes.size() < 4 || u32_at(bytes.data()) != kMagic)
    throw file_error(path, "not an SPZ file (neither an 'NGSP' header nor a gzip stream)");
  const V4Streams v = read_v4_streams(bytes, path);  // validates every stream it re-packs
  // v3: the same 16 header bytes with version 3 and byte 15 reserved (v4 keeps the stream count
  // there), then the attribute arrays in the v4 stream order.
  std::vector<std::uint8_t> raw(bytes.begin(), bytes.begin() + 16);
  const std::uint32_t v3 = 3;
  std::memcpy(raw.data() + 4, &v3, 4);
  raw[15] = 0;
  for (int k = 0; k < v.used; ++k) raw.insert(raw.end(), v.data[k].begin(), v.data[k].end());
  return gzip(raw, path);
}

LoadedScene read_spz(std::span<const std::uint8_t> bytes, const std::string& path,
    const LoadOptions& options) {
  const ProgressFn& progress = options.progress;
  LoadedScene out;
  out.report.path = path;
  out.report.format = SceneFormat::kSpz;
  out.report.frame = out.scene.frame = SceneFrame::kRub;
  if (bytes.size() >= 4 && u32_at(bytes.data()) == kMagic) {
    // v4: plain header + table of contents + zstd streams.
    V4Streams v = read_v4_streams(bytes, path);
    const std::uint64_t n = v.n;
    const int sh_degree = v.sh_degree, frac = v.frac;
    const std::uint32_t version = v.version;
    auto& data = v.data;
    out.report.version = int(version);
    out.report.sh_degree = sh_degree;
    out.report.in_file = n;
    decode({data[0].data(), data[1].data(), data[2].data(), data[3].data(), data[4].data(), 4,
            sh_degree > 0 ? data[5].data() : nullptr, sh_coeffs(sh_degree)},
           n, frac, path, out, progress, options.keep_color);
  } else {
    // v2/v3: gzip stream; read the 16-byte header, then exactly the size it implies.
    if (bytes.size() < 18 || bytes[0] != 0x1f || bytes[1] != 0x8b)
      throw file_error(path, "not an SPZ file (neither an 'NGSP' header nor a gzip stream)");
    const std::vector<std::uint8_t> head = gunzip(bytes, 16, path);
    if (head.size() < 16) throw file_error(path, "SPZ: gzip stream ends inside the 16-byte header");
    if (u32_at(head.data()) != kMagic) throw file_error(path, "SPZ: gzip content has no 'NGSP' magic");
    const std::uint32_t version = u32_at(head.data() + 4);
    const std::uint64_t n = u32_at(head.data() + 8);
    const int sh_degree = head[12], frac = head[13];
    if (version < 2 || version > 3) throw file_error(path, "SPZ version " + std::to_string(version) + " in a gzip stream is not supported (2 or 3)");
    if (sh_degree > 3 || frac > 24) throw file_error(path, "SPZ: bad header (SH degree " + std::to_string(sh_degree) + ")");
    if (n == 0) throw file_error(path, "SPZ declares 0 points");
    const int rot = version >= 3 ? 4 : 3;
    const std::uint64_t per_point = 9 + 1 + 3 + 3 + std::uint64_t(rot) + 3ull * std::uint64_t(sh_coeffs(sh_degree));
    // Deflate expands at most ~1032:1: a header claiming more points than that is an error,
    // not a huge allocation.
    if (n > (std::uint64_t(bytes.size()) * 1100) / per_point)
      throw file_error(path, "SPZ header claims " + std::to_string(n) + " points, more than a " +
                                 std::to_string(bytes.size()) + "-byte gzip stream can hold");
    const std::uint64_t base_size = 16 + n * per_point;
    const std::vector<std::uint8_t> all = gunzip(bytes, base_size, path);
    if (all.size() < base_size)
      throw file_error(path, "truncated: SPZ data ends after " + std::to_string(all.size()) + " of " +
                                 std::to_string(base_size) + " decompressed bytes");
    out.report.version = int(version);
    out.report.sh_degree = sh_degree;
    out.report.in_file = n;
    const std::uint8_t* p = all.data() + 16;
    decode({p, p + 9 * n, p + 10 * n, p + 13 * n, p + 16 * n, rot,
            sh_degree > 0 ? p + (16 + std::uint64_t(rot)) * n : nullptr, sh_coeffs(sh_degree)},
           n, frac, path, out, progress, options.keep_color);
  }
  detail::finish_load(out, path, out.report.in_file, progress);
  return out;
}

}  // namespace gshaptics
