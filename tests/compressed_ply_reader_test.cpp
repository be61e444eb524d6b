// PlayCanvas compressed PLY and SPZ against the INRIA PLY decoded from the same scene (biker):
// the same Gaussians index by index, within the formats' quantisation, after SPZ's frame flip.

#include <gtest/gtest.h>
#include <zlib.h>
#include <zstd.h>

#include <cmath>
#include <cstring>

#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

using test::scene_path;

struct Biker {
  LoadedScene ply = load_scene(scene_path("biker.ply"));
  LoadedScene compressed = load_scene(scene_path("biker.compressed.ply"));
  LoadedScene spz = load_scene(scene_path("biker.spz"));
};
const Biker& biker() {
  static const Biker b;
  return b;
}

// SPZ stores log-scales as byte / 16 - 10: values below -10 are clamped there.
constexpr float kSpzMinLogScale = -10.f;

void expect_same(const GaussianScene& a, const GaussianScene& b, bool flip_yz, float pos_tol,
                 float log_scale_tol, float quat_tol) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    Eigen::Vector3f m = a.means[i];
    Eigen::Vector4f q = a.rotations[i];
    if (flip_yz) {
      m.y() = -m.y(); m.z() = -m.z();
      q[2] = -q[2]; q[3] = -q[3];
    }
    ASSERT_LT((m - b.means[i]).cwiseAbs().maxCoeff(), pos_tol) << i;
    for (int k = 0; k < 3; ++k) {
      const float la = std::log(a.scales[i][k]), lb = std::log(b.scales[i][k]);
      if (flip_yz && la <= kSpzMinLogScale + 1e-4f && lb < kSpzMinLogScale) continue;
      ASSERT_NEAR(la, lb, log_scale_tol) << i;
    }
    ASSERT_GT(std::fabs(q.dot(b.rotations[i])), 1 - quat_tol) << i;
    ASSERT_NEAR(a.opacities[i], b.opacities[i], 1e-6f) << i;
    ASSERT_EQ(a.source_index[i], b.source_index[i]);
  }
}

TEST(CompressedPly, MatchesTheDecodedInriaPly) {
  GSHAPTICS_REQUIRE_SCENES();
  const Biker& b = biker();
  EXPECT_EQ(b.compressed.report.format, SceneFormat::kCompressedPly);
  EXPECT_EQ(b.compressed.report.in_file, 152746u);
  expect_same(b.compressed.scene, b.ply.scene, false, 1e-5f, 1e-5f, 1e-6f);
}

TEST(CompressedPly, GuitarLoadsWithSourcesStatistics) {
  GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene g = load_scene(scene_path("guitar.compressed.ply"));
  EXPECT_EQ(g.scene.size(), 90854u);
  Eigen::Vector3f lo = g.scene.means[0], hi = lo;
  for (const auto& m : g.scene.means) { lo = lo.cwiseMin(m); hi = hi.cwiseMax(m); }
  EXPECT_NEAR(lo.x(), -0.655, 2e-3);
  EXPECT_NEAR(hi.y(), 0.0861, 2e-3);
}

TEST(Spz, Version4MatchesCompressedPlyAfterTheFrameFlip) {
  GSHAPTICS_REQUIRE_SCENES();
  const Biker& b = biker();
  EXPECT_EQ(b.spz.report.version, 4);
  EXPECT_EQ(b.spz.report.frame, SceneFrame::kRub);
  // SOURCES.md: positions within 1.2e-4, log-scales within 0.03, |q.q'| > 0.99999, alphas equal.
  expect_same(b.spz.scene, b.compressed.scene, true, 1.3e-4f, 0.04f, 1e-5f);
}

// SPZ v2/v3 are one gzip stream; no real file is at hand, so build them from v4's streams.
std::vector<std::uint8_t> zstd_stream(const std::vector<std::uint8_t>& file, int k) {
  std::uint32_t toc;
  std::memcpy(&toc, file.data() + 16, 4);
  std::uint64_t offset = toc + 16ull * file[15];
  for (int j = 0; j < k; ++j) {
    std::uint64_t c;
    std::memcpy(&c, file.data() + toc + 16 * j, 8);
    offset += c;
  }
  std::uint64_t c, u;
  std::memcpy(&c, file.data() + toc + 16 * k, 8);
  std::memcpy(&u, file.data() + toc + 16 * k + 8, 8);
  std::vector<std::uint8_t> out(u);
  EXPECT_EQ(ZSTD_decompress(out.data(), u, file.data() + offset, c), u);
  return out;
}

std::vector<std::uint8_t> gzip(const std::vector<std::uint8_t>& raw) {
  z_stream zs{};
  EXPECT_EQ(deflateInit2(&zs, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY), Z_OK);
  std::vector<std::uint8_t> out(deflateBound(&zs, uLong(raw.size())) + 64);
  zs.next_in = const_cast<Bytef*>(raw.data());
  zs.avail_in = uInt(raw.size());
  zs.next_out = out.data();
  zs.avail_out = uInt(out.size());
  EXPECT_EQ(deflate(&zs, Z_FINISH), Z_STREAM_END);
  out.resize(zs.total_out);
  deflateEnd(&zs);
  return out;
}

std::vector<std::uint8_t> make_gzip_spz(int version, std::size_t limit = 0, int sh_degree = 0) {
  const auto v4 = test::read_bytes(scene_path("biker.spz"));
  std::uint32_t n;
  std::memcpy(&n, v4.data() + 8, 4);
  std::vector<std::uint8_t> raw(16, 0);
  const std::uint32_t magic = 0x5053474e, ver = std::uint32_t(version);
  std::memcpy(raw.data(), &magic, 4);
  std::memcpy(raw.data() + 4, &ver, 4);
  std::memcpy(raw.data() + 8, &n, 4);
  raw[12] = std::uint8_t(sh_degree);
  raw[13] = v4[13];  // fractional bits
  for (int k = 0; k < 4; ++k) {
    const auto s = zstd_stream(v4, k);
    raw.insert(raw.end(), s.begin(), s.end());
  }
  const auto rot = zstd_stream(v4, 4);  // v3 layout: smallest three, 4 bytes
  if (version == 3) {
    raw.insert(raw.end(), rot.begin(), rot.end());
  } else {  // v2: x, y, z bytes of the quaternion with w >= 0, from the loaded v4 rotations
    const LoadedScene s = load_scene(scene_path("biker.spz"));
    for (const auto& q : s.scene.rotations) {
      const float sign = q[0] < 0 ? -1.f : 1.f;
      for (int k = 1; k < 4; ++k)
        raw.push_back(std::uint8_t(std::lround(std::clamp((sign * q[k] + 1.f) * 127.5f, 0.f, 255.f))));
    }
  }
  if (sh_degree == 1)  // 3 coefficients x RGB per point: byte = (3 * k + channel + point) % 256
    for (std::uint32_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k)
        for (int ch = 0; ch < 3; ++ch) raw.push_back(std::uint8_t((3 * k + ch + int(i)) % 256));
  if (limit) raw.resize(limit);
  return gzip(raw);
}

TEST(Spz, GzipVersions3And2MatchVersion4) {
  GSHAPTICS_REQUIRE_SCENES();
  const Biker& b = biker();
  for (int version : {3, 2}) {
    const std::string p = test::temp_path(".spz");
    test::write_bytes(p, make_gzip_spz(version));
    const LoadedScene s = load_scene(p);
    EXPECT_EQ(s.report.version, version);
    EXPECT_EQ(s.report.frame, SceneFrame::kRub);
    expect_same(s.scene, b.spz.scene, false, 1e-7f, 1e-6f, version == 3 ? 1e-6f : 2e-3f);
  }
}

TEST(Spz, HigherShBandsAreKeptInInriaOrder) {
  GSHAPTICS_REQUIRE_SCENES();
  const std::string p = test::temp_path(".spz");
  test::write_bytes(p, make_gzip_spz(3, 0, 1));
  const LoadedScene s = load_scene(p, test::with_color());
  EXPECT_EQ(s.report.sh_degree, 1);
  ASSERT_EQ(s.scene.sh_rest_count, 9);
  ASSERT_EQ(s.scene.sh_rest.size(), 9 * s.scene.size());
  for (std::size_t i = 0; i < 5; ++i)
    for (int ch = 0; ch < 3; ++ch)
      for (int k = 0; k < 3; ++k) {
        const float want = (float((3 * k + ch + int(i)) % 256) - 128.f) / 128.f;
        ASSERT_EQ(s.scene.sh_rest[9 * i + std::size_t(3 * ch + k)], want) << i << " " << ch << " " << k;
      }
  // and the geometry is that of the same file without SH
  expect_same(s.scene, biker().spz.scene, false, 1e-7f, 1e-6f, 1e-6f);
}

std::string error_of(const std::vector<std::uint8_t>& bytes, const char* suffix) {
  const std::string p = test::temp_path(suffix);
  test::write_bytes(p, bytes);
  return test::load_error(p);
}

TEST(Spz, BrokenFilesAreNamedErrors) {
  GSHAPTICS_REQUIRE_SCENES();
  auto v4 = test::read_bytes(scene_path("biker.spz"));
  auto cut = v4;
  cut.resize(v4.size() / 2);
  EXPECT_NE(error_of(cut, ".spz").find("past the end"), std::string::npos) << error_of(cut, ".spz");
  auto bad = v4;
  bad[112] ^= 0xff;  // the first stream's zstd frame magic (after the 32-byte header and 5-entry TOC)
  EXPECT_NE(error_of(bad, ".spz").find("corrupt"), std::string::npos) << error_of(bad, ".spz");
  auto huge = v4;
  const std::uint32_t big = 0xffffffffu;
  std::memcpy(huge.data() + 8, &big, 4);
  EXPECT_NE(error_of(huge, ".spz").find("points need"), std::string::npos) << error_of(huge, ".spz");
  EXPECT_NE(error_of(make_gzip_spz(3, 5000), ".spz").find("truncated"), std::string::npos);
  // The header and the table of contents agree on a size the stream cannot hold (2^30 points: 9
  // GiB for the first stream): refused before anything is allocated (found by the SPZ fuzzer).
  auto crafted = v4;
  const std::uint32_t n = 1u << 30;
  const std::uint64_t usize = 9ull * n;
  std::memcpy(crafted.data() + 8, &n, 4);
  std::memcpy(crafted.data() + 32 + 8, &usize, 8);  // the TOC's first (compressed, uncompressed) pair
  EXPECT_NE(error_of(crafted, ".spz").find("cannot hold"), std::string::npos) << error_of(crafted, ".spz");
}

TEST(CompressedPly, TruncatedIsNamed) {
  GSHAPTICS_REQUIRE_SCENES();
  auto bytes = test::read_bytes(scene_path("guitar.compressed.ply"));
  bytes.resize(bytes.size() - 100);
  EXPECT_NE(error_of(bytes, ".ply").find("truncated"), std::string::npos) << error_of(bytes, ".ply");
}

}  // namespace
}  // namespace gshaptics
