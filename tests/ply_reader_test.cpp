// INRIA PLY reader: real scenes (values from ../shared/data/scenes/SOURCES.md) and made-up
// files exercising every header variant and failure this issue names.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "gshaptics/error.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/scene/scene_stats.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

using test::scene_path;

struct Expect {
  const char* file;
  std::uint64_t count;
  Eigen::Vector3d lo, hi;
  double above_02;  // fraction with opacity > 0.2
  int sh_degree;
};

void PrintTo(const Expect& e, std::ostream* os) { *os << e.file; }

class RealPly : public ::testing::TestWithParam<Expect> {};

TEST_P(RealPly, CountsBoundsAndOpacityMatchSources) {
  GSHAPTICS_REQUIRE_SCENES();
  const Expect& e = GetParam();
  const LoadedScene s = load_scene(scene_path(e.file));
  EXPECT_EQ(s.report.format, SceneFormat::kInriaPly);
  EXPECT_EQ(s.report.in_file, e.count);
  EXPECT_EQ(s.report.loaded + s.report.skipped(), e.count);
  EXPECT_EQ(s.report.skipped(), 0u);
  EXPECT_EQ(s.report.sh_degree, e.sh_degree);
  const SceneStats st = compute_scene_stats(s.scene);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(st.bbox_min[k], e.lo[k], 1e-3 * std::max(1.0, std::fabs(e.lo[k])));
    EXPECT_NEAR(st.bbox_max[k], e.hi[k], 1e-3 * std::max(1.0, std::fabs(e.hi[k])));
  }
  EXPECT_NEAR(st.opacity_above[1], e.above_02, 2e-3);
  for (const auto& q : s.scene.rotations) ASSERT_NEAR(q.norm(), 1.0f, 1e-5f);
  for (std::size_t i = 0; i < s.scene.size(); ++i) ASSERT_EQ(s.scene.source_index[i], i);
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, RealPly,
    ::testing::Values(
        Expect{"donut.ply", 45624, {-0.1032, -0.0976, -0.0091}, {0.1053, 0.1095, 0.0862}, 0.8057, 0},
        Expect{"fruitdrops.ply", 4721, {0.4861, -0.0116, -2.249}, {1.0022, 0.2497, -2.02}, 0.2557, 3},
        Expect{"biker.ply", 152746, {-0.6213, -3.1801, -0.5323}, {0.4144, 0.0, 0.6133}, 0.4467, 0},
        Expect{"unicorn.ply", 49602, {-0.5781, -1.0544, -0.6499}, {0.6016, 0.675, 0.945}, 0.6764, 3},
        Expect{"halo.ply", 345217, {-1.8099, -1.3221, -1.1498}, {2.1699, 1.8716, 1.1495}, 0.8124, 0},
        Expect{"firepit.ply", 561997, {-3.5026, 0.548, -4.3995}, {4.4809, 2.8613, 3.5982}, 0.879, 0},
        Expect{"karangkidul_crop.ply", 957195, {-206.2481, -181.6692, -131.6697},
               {143.7407, 182.8719, 218.3246}, 0.9243, 0}),
    [](const auto& param_info) {
      std::string n = param_info.param.file;
      return n.substr(0, n.find('.'));
    });

TEST(PlyReader, RawTrainerQuaternionsAreNormalisedAndExtrasReported) {
  GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene s = load_scene(scene_path("fruitdrops.ply"));
  ASSERT_EQ(s.report.ignored_properties, std::vector<std::string>{"transform"});
  const LoadedScene d = load_scene(scene_path("donut.ply"));
  EXPECT_TRUE(d.report.ignored_properties.empty());
}

TEST(PlyReader, CompressedPlyIsDispatchedToItsReader) {
  GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene s = read_inria_ply(test::read_bytes(scene_path("guitar.compressed.ply")), "guitar");
  EXPECT_EQ(s.report.format, SceneFormat::kCompressedPly);
  EXPECT_EQ(s.scene.size(), 90854u);
}

// ---- made-up files ----------------------------------------------------------------------

struct Prop {
  std::string name, type;
};

std::vector<std::uint8_t> make_ply(const std::string& pre_header, const std::vector<Prop>& props,
                                   const std::vector<std::vector<double>>& rows,
                                   const std::string& format = "binary_little_endian",
                                   const std::string& eol = "\n",
                                   const std::vector<std::uint8_t>& pre_data = {},
                                   std::uint64_t declared = std::numeric_limits<std::uint64_t>::max()) {
  std::string h = "ply" + eol + "format " + format + " 1.0" + eol + "comment made by a test" + eol +
                  pre_header;
  h += "element vertex " + std::to_string(declared == std::numeric_limits<std::uint64_t>::max() ? rows.size() : declared) + eol;
  for (const auto& p : props) h += "property " + p.type + " " + p.name + eol;
  h += "end_header" + eol;
  std::vector<std::uint8_t> out(h.begin(), h.end());
  out.insert(out.end(), pre_data.begin(), pre_data.end());
  for (const auto& row : rows) {
    for (std::size_t i = 0; i < props.size(); ++i) {
      if (props[i].type == "double") {
        const double v = row[i];
        const auto* b = reinterpret_cast<const std::uint8_t*>(&v);
        out.insert(out.end(), b, b + 8);
      } else if (props[i].type == "uchar") {
        out.push_back(std::uint8_t(row[i]));
      } else {
        const float v = float(row[i]);
        const auto* b = reinterpret_cast<const std::uint8_t*>(&v);
        out.insert(out.end(), b, b + 4);
      }
    }
  }
  return out;
}

std::vector<Prop> standard_props(const std::string& type = "float") {
  std::vector<Prop> p;
  for (const char* n : {"x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0",
                        "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    p.push_back({n, type});
  return p;
}

// x y z, f_dc x3, opacity logit, log-scales x3, quaternion (w, x, y, z, unnormalised)
std::vector<double> row(double x, double logit, double log_s, double qw = 2, double qx = 0) {
  return {x, 2 * x, 3 * x, 0, 0, 0, logit, log_s, log_s - 1, log_s - 2, qw, qx, 0, 0};
}

std::string save(const std::vector<std::uint8_t>& bytes, const std::string& suffix = ".ply") {
  const std::string p = test::temp_path(suffix);
  test::write_bytes(p, bytes);
  return p;
}

TEST(PlyReader, DecodesSigmoidExpAndNormalises) {
  const std::string p = save(make_ply("", standard_props(), {row(1, 0, std::log(0.5)), row(2, 40, 0, 0, 3)}));
  const LoadedScene s = load_scene(p);
  ASSERT_EQ(s.scene.size(), 2u);
  EXPECT_FLOAT_EQ(s.scene.means[0].y(), 2.f);
  EXPECT_FLOAT_EQ(s.scene.opacities[0], 0.5f);
  EXPECT_NEAR(s.scene.opacities[1], 1.0f, 1e-6f);
  EXPECT_NEAR(s.scene.scales[0].x(), 0.5f, 1e-6f);
  EXPECT_NEAR(s.scene.scales[0].y(), 0.5f * std::exp(-1.f), 1e-6f);
  EXPECT_EQ(s.scene.rotations[0], Eigen::Vector4f(1, 0, 0, 0));
  EXPECT_EQ(s.scene.rotations[1], Eigen::Vector4f(0, 1, 0, 0));
}

TEST(PlyReader, DoublePropertiesExtraElementsAndCrlfHeader) {
  // A 2-record element of 8 bytes each before 'vertex', an element after it, double storage,
  // a trailing unknown property and CRLF line ends.
  auto props = standard_props("double");
  props.push_back({"transform", "uchar"});
  std::vector<std::vector<double>> rows = {row(1, 1, -3), row(-1, -1, -4)};
  for (auto& r : rows) r.push_back(7);
  const std::vector<std::uint8_t> pre(16, 0xAB);
  auto bytes = make_ply("element camera 2\r\nproperty double focal\r\n", props, rows,
                        "binary_little_endian", "\r\n", pre);
  // Insert the trailing element's declaration is not needed for reading: extra data after
  // the vertices must simply be ignored.
  bytes.insert(bytes.end(), {1, 2, 3, 4});
  const LoadedScene s = load_scene(save(bytes));
  ASSERT_EQ(s.scene.size(), 2u);
  EXPECT_FLOAT_EQ(s.scene.means[1].z(), -3.f);
  EXPECT_NEAR(s.scene.scales[1].x(), std::exp(-4.f), 1e-7f);
  EXPECT_EQ(s.report.ignored_properties, std::vector<std::string>{"transform"});
}

TEST(PlyReader, InvalidGaussiansAreSkippedAndCounted) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  // ok, NaN position, zero quaternion, log-scale -inf, logit +inf, log-scale -200 (exp
  // underflows to a zero scale), ok.
  std::vector<std::vector<double>> rows = {row(1, 0, -3),   row(nan, 0, -3), row(2, 0, -3, 0, 0),
                                           row(3, 0, -inf), row(4, inf, -3), row(5, 0, -200),
                                           row(6, 0, -3)};
  const LoadedScene s = load_scene(save(make_ply("", standard_props(), rows)));
  EXPECT_EQ(s.report.in_file, 7u);
  EXPECT_EQ(s.report.loaded, 2u);
  EXPECT_EQ(s.report.skipped_non_finite, 3u);
  EXPECT_EQ(s.report.skipped_zero_quaternion, 1u);
  EXPECT_EQ(s.report.skipped_bad_scale, 1u);
  EXPECT_EQ(s.scene.source_index, (std::vector<std::uint32_t>{0, 6}));
  EXPECT_EQ(s.report.loaded + s.report.skipped(), s.report.in_file);
}

TEST(PlyReader, AllInvalidIsAnError) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::string p = save(make_ply("", standard_props(), {row(nan, 0, 0), row(nan, 0, 0)}));
  EXPECT_NE(test::load_error(p).find("no valid Gaussian"), std::string::npos) << test::load_error(p);
}

std::vector<std::uint8_t> to_ascii(const std::vector<Prop>& props, const std::vector<std::vector<double>>& rows,
                                   const std::string& pre = "", const std::string& pre_data = "") {
  std::string t = "ply\nformat ascii 1.0\n" + pre + "element vertex " + std::to_string(rows.size()) + "\n";
  for (const auto& p : props) t += "property " + p.type + " " + p.name + "\n";
  t += "end_header\n" + pre_data;
  char buf[64];
  for (const auto& r : rows) {
    for (std::size_t i = 0; i < r.size(); ++i) {
      std::snprintf(buf, sizeof buf, i ? " %.9g" : "%.9g", r[i]);
      t.append(buf);
    }
    t += "\n";
  }
  return {t.begin(), t.end()};
}

std::vector<std::uint8_t> to_big_endian(const std::vector<Prop>& props, const std::vector<std::vector<double>>& rows) {
  std::vector<std::uint8_t> le = make_ply("", props, rows, "binary_big_endian");
  // Byte-swap every value after the header (all float or double here).
  const std::string text(le.begin(), le.end());
  std::size_t off = text.find("end_header\n") + 11;
  for (const auto& r : rows) {
    for (std::size_t i = 0; i < r.size(); ++i) {
      const std::size_t n = props[i].type == "double" ? 8 : 4;
      std::reverse(le.begin() + std::ptrdiff_t(off), le.begin() + std::ptrdiff_t(off + n));
      off += n;
    }
  }
  return le;
}

TEST(PlyReader, AsciiAndBigEndianGiveTheSameGaussiansAsLittleEndian) {
  std::vector<std::vector<double>> rows;
  for (int i = 0; i < 50; ++i) rows.push_back(row(0.01 * i - 0.2, 0.1 * i - 2, -3 - 0.02 * i, 1 + 0.01 * i, 0.3));
  const LoadedScene le = load_scene(save(make_ply("", standard_props(), rows)));
  const LoadedScene as = load_scene(save(to_ascii(standard_props(), rows, "element camera 2\nproperty list uchar float k\n", "3 1 2 3\n1 7\n")));
  const LoadedScene be = load_scene(save(to_big_endian(standard_props("double"), rows)));
  EXPECT_EQ(as.report.format, SceneFormat::kAsciiPly);
  EXPECT_EQ(be.report.format, SceneFormat::kBigEndianPly);
  ASSERT_EQ(le.scene.size(), 50u);
  ASSERT_EQ(as.scene.size(), 50u);
  ASSERT_EQ(be.scene.size(), 50u);
  for (std::size_t i = 0; i < 50; ++i) {
    EXPECT_NEAR((as.scene.means[i] - le.scene.means[i]).norm(), 0, 1e-6);
    EXPECT_NEAR((be.scene.means[i] - le.scene.means[i]).norm(), 0, 1e-6);
    EXPECT_NEAR((as.scene.scales[i] - le.scene.scales[i]).norm(), 0, 1e-6);
    EXPECT_NEAR((be.scene.rotations[i] - le.scene.rotations[i]).norm(), 0, 1e-6);
    EXPECT_NEAR(as.scene.opacities[i], le.scene.opacities[i], 1e-6);
  }
}

TEST(PlyReader, AsciiErrorsNameTheVertexAndValue) {
  std::vector<std::vector<double>> rows = {row(1, 0, -3), row(2, 0, -3)};
  auto bytes = to_ascii(standard_props(), rows);
  std::string t(bytes.begin(), bytes.end());
  t[t.rfind('\n', t.size() - 2) + 1] = 'x';  // garbage at the start of the last line
  const std::string p = save(std::vector<std::uint8_t>(t.begin(), t.end()));
  EXPECT_NE(test::load_error(p).find("ASCII vertex 1"), std::string::npos) << test::load_error(p);
  auto cut = to_ascii(standard_props(), rows);
  std::string c(cut.begin(), cut.end());
  c.resize(c.rfind("\n", c.size() - 2) + 1);  // drop the last line
  const std::string p2 = save(std::vector<std::uint8_t>(c.begin(), c.end()));
  EXPECT_NE(test::load_error(p2).find("truncated"), std::string::npos) << test::load_error(p2);
}

TEST(PlyReader, MissingPropertyIsNamed) {
  auto props = standard_props();
  props.erase(props.begin() + 8);  // scale_1
  std::vector<double> r = row(1, 0, 0);
  r.erase(r.begin() + 8);
  const std::string p = save(make_ply("", props, {r}));
  EXPECT_NE(test::load_error(p).find("'scale_1'"), std::string::npos) << test::load_error(p);
}

TEST(PlyReader, HugeDeclaredCountIsAnErrorNotAnAllocation) {
  const std::string p = save(make_ply("", standard_props(), {row(1, 0, 0)}, "binary_little_endian",
                                      "\n", {}, 1000000000000ull));
  const std::string e = test::load_error(p);
  EXPECT_NE(e.find("truncated"), std::string::npos) << e;
  EXPECT_NE(e.find("1000000000000"), std::string::npos) << e;
}

TEST(PlyReader, TruncatedRealFileNamesFileAndSizes) {
  GSHAPTICS_REQUIRE_SCENES();
  auto bytes = test::read_bytes(scene_path("donut.ply"));
  ASSERT_GT(bytes.size(), 1000u);
  bytes.resize(bytes.size() - 37);
  const std::string p = save(bytes);
  const std::string e = test::load_error(p);
  EXPECT_NE(e.find(p), std::string::npos) << e;
  EXPECT_NE(e.find("truncated"), std::string::npos) << e;
}

TEST(PlyReader, HeaderOnlyCutIsAnError) {
  GSHAPTICS_REQUIRE_SCENES();
  auto bytes = test::read_bytes(scene_path("donut.ply"));
  bytes.resize(100);  // inside the header
  const std::string e = test::load_error(save(bytes));
  EXPECT_NE(e.find("end_header"), std::string::npos) << e;
}

TEST(PlyReader, MalformedHeaderLinesAreReported) {
  const std::string p1 = save(make_ply("element\n", standard_props(), {row(1, 0, 0)}));
  EXPECT_NE(test::load_error(p1).find("expected 'element <name> <count>'"), std::string::npos) << test::load_error(p1);
  std::vector<std::uint8_t> weird = make_ply("", standard_props(), {row(1, 0, 0)});
  const std::string text(weird.begin(), weird.end());
  const std::string bad_type = std::string(text).replace(text.find("property float x"), 16, "property quux x");
  const std::string p2 = save(std::vector<std::uint8_t>(bad_type.begin(), bad_type.end()));
  EXPECT_NE(test::load_error(p2).find("unknown property type 'quux'"), std::string::npos) << test::load_error(p2);
}

}  // namespace
}  // namespace gshaptics
