// Writes small, valid seed files for the fuzzers, cut out of the real scenes in
// ../shared/data/scenes: a few Gaussians per format, so that libFuzzer starts from inputs that
// reach the decoders rather than only the header checks.
// Usage: make_seeds SCENES_DIR OUT_DIR

#include <zlib.h>
#include <zstd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "gshaptics/io/scene_loader.h"
#include "gshaptics/io/scene_writer.h"

using namespace gshaptics;
namespace fs = std::filesystem;

static std::vector<std::uint8_t> read_file(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
static void write_file(const fs::path& p, const std::vector<std::uint8_t>& b) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}
static GaussianScene first(const GaussianScene& s, std::size_t n) {
  GaussianScene out;
  out.sh_rest_count = s.sh_rest_count;
  for (std::size_t i = 0; i < n && i < s.size(); ++i) out.push_back_from(s, i);
  return out;
}
// Replaces "element NAME COUNT" in a PLY header and cuts the data to `data_bytes`.
static std::vector<std::uint8_t> cut_ply(std::vector<std::uint8_t> b, const std::vector<std::pair<std::string, std::string>>& counts,
                                         std::size_t data_bytes) {
  std::string t(b.begin(), b.end());
  const std::size_t end = t.find("end_header\n") + 11;
  std::string head = t.substr(0, end);
  for (const auto& [from, to] : counts) head.replace(head.find(from), from.size(), to);
  std::string data = t.substr(end, data_bytes);
  const std::string all = head + data;
  return {all.begin(), all.end()};
}

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: make_seeds SCENES_DIR OUT_DIR\n");
    return 2;
  }
  const std::string in = argv[1];
  const fs::path out = argv[2];
  for (const char* d : {"ply", "compressed_ply", "splat", "spz"}) fs::create_directories(out / d);

  // PLY: binary LE (SH3 + extra property, and SH0), then ASCII and big-endian versions.
  const LoadedScene fruit = load_scene(in + "/fruitdrops.ply");
  write_inria_ply((out / "ply" / "fruit_le.ply").string(), first(fruit.scene, 12));
  const LoadedScene donut = load_scene(in + "/donut.ply");
  write_inria_ply((out / "ply" / "donut_le.ply").string(), first(donut.scene, 12));
  const auto raw = read_file(in + "/fruitdrops.ply");
  write_file(out / "ply" / "fruit_raw.ply", cut_ply(raw, {{"element vertex 4721", "element vertex 6"}}, 6 * 252));
  std::string ascii = "ply\nformat ascii 1.0\nelement camera 1\nproperty list uchar float k\nelement vertex 3\n";
  for (const char* p : {"x", "y", "z", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    ascii += std::string("property float ") + p + "\n";
  ascii += "end_header\n2 1.5 2.5\n0 0 0 1 -3 -3 -3 1 0 0 0\n1 2 3 -1 -4 -5 -6 0.5 0.5 0.5 0.5\nnan 1 1 0 -2 -2 -2 1 0 0 0\n";
  write_file(out / "ply" / "ascii.ply", std::vector<std::uint8_t>(ascii.begin(), ascii.end()));
  std::vector<std::uint8_t> be = read_file((out / "ply" / "donut_le.ply").string());
  {
    std::string t(be.begin(), be.end());
    const std::size_t end = t.find("end_header\n") + 11;
    t.replace(t.find("binary_little_endian"), 20, "binary_big_endian");
    const std::size_t shift = std::string("binary_big_endian").size() - std::string("binary_little_endian").size();
    be.assign(t.begin(), t.end());
    for (std::size_t o = end + shift; o + 4 <= be.size(); o += 4) std::swap(be[o], be[o + 3]), std::swap(be[o + 1], be[o + 2]);
  }
  write_file(out / "ply" / "donut_be.ply", be);

  // Compressed PLY: one chunk of 256.
  const auto comp = read_file(in + "/guitar.compressed.ply");
  write_file(out / "compressed_ply" / "guitar_1chunk.ply",
             cut_ply(comp, {{"element chunk 355", "element chunk 1"}, {"element vertex 90854", "element vertex 256"}}, 18 * 4));
  {  // the chunk record, then the first 256 vertices, which follow all 355 chunk records
    std::string t(comp.begin(), comp.end());
    const std::size_t end = t.find("end_header\n") + 11;
    std::vector<std::uint8_t> b = cut_ply(comp, {{"element chunk 355", "element chunk 1"}, {"element vertex 90854", "element vertex 256"}}, 18 * 4);
    b.insert(b.end(), comp.begin() + std::ptrdiff_t(end + 355 * 72), comp.begin() + std::ptrdiff_t(end + 355 * 72 + 256 * 16));
    write_file(out / "compressed_ply" / "guitar_1chunk.ply", b);
  }

  // .splat: 16 records of each real file.
  for (const char* f : {"truck", "skull"}) {
    const auto b = read_file(in + "/" + f + ".splat");
    write_file(out / "splat" / (std::string(f) + ".splat"), std::vector<std::uint8_t>(b.begin(), b.begin() + 16 * 32));
  }

  // SPZ: the first 64 points of biker.spz as v4 (zstd streams) and v3 (gzip).
  const auto spz = read_file(in + "/biker.spz");
  std::uint32_t n_all, toc;
  std::memcpy(&n_all, spz.data() + 8, 4);
  std::memcpy(&toc, spz.data() + 16, 4);
  const std::uint32_t n = 64;
  const std::size_t per[5] = {9, 1, 3, 3, 4};
  std::vector<std::vector<std::uint8_t>> streams;
  std::uint64_t off = toc + 16ull * spz[15];
  for (int k = 0; k < 5; ++k) {
    std::uint64_t c, u;
    std::memcpy(&c, spz.data() + toc + 16 * k, 8);
    std::memcpy(&u, spz.data() + toc + 16 * k + 8, 8);
    std::vector<std::uint8_t> full(u);
    ZSTD_decompress(full.data(), u, spz.data() + off, c);
    off += c;
    streams.emplace_back(full.begin(), full.begin() + std::ptrdiff_t(per[k] * n));
  }
  std::vector<std::uint8_t> v4(spz.begin(), spz.begin() + 32);
  std::memcpy(v4.data() + 8, &n, 4);
  v4[15] = 5;
  std::vector<std::uint8_t> tocb(80), data;
  for (int k = 0; k < 5; ++k) {
    std::vector<std::uint8_t> c(ZSTD_compressBound(streams[k].size()));
    const std::size_t cs = ZSTD_compress(c.data(), c.size(), streams[k].data(), streams[k].size(), 3);
    const std::uint64_t cs64 = cs, us64 = streams[k].size();
    std::memcpy(tocb.data() + 16 * k, &cs64, 8);
    std::memcpy(tocb.data() + 16 * k + 8, &us64, 8);
    data.insert(data.end(), c.begin(), c.begin() + std::ptrdiff_t(cs));
  }
  v4.insert(v4.end(), tocb.begin(), tocb.end());
  v4.insert(v4.end(), data.begin(), data.end());
  write_file(out / "spz" / "biker64_v4.spz", v4);
  std::vector<std::uint8_t> v3raw(16, 0);
  const std::uint32_t magic = 0x5053474e, ver = 3;
  std::memcpy(v3raw.data(), &magic, 4);
  std::memcpy(v3raw.data() + 4, &ver, 4);
  std::memcpy(v3raw.data() + 8, &n, 4);
  v3raw[13] = spz[13];
  for (const auto& s : streams) v3raw.insert(v3raw.end(), s.begin(), s.end());
  std::vector<std::uint8_t> gz(compressBound(uLong(v3raw.size())) + 64);
  z_stream zs{};
  deflateInit2(&zs, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
  zs.next_in = v3raw.data();
  zs.avail_in = uInt(v3raw.size());
  zs.next_out = gz.data();
  zs.avail_out = uInt(gz.size());
  deflate(&zs, Z_FINISH);
  gz.resize(zs.total_out);
  deflateEnd(&zs);
  write_file(out / "spz" / "biker64_v3.spz", gz);
  std::printf("seeds written to %s\n", out.c_str());
  (void)n_all;
  return 0;
}
