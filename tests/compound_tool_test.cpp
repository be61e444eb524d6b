// Compound tools (issue 36, item 1): the presets' geometry, the JSON file's errors, posing in the
// world, and the paper model summed part by part: per-part contacts and forces against a
// reference built from ContactQuery and ForceModel directly, zero torque for a symmetric tool
// pressed symmetrically, mirrored torques for mirrored set-ups, and the lever arm.

#include "gshaptics/collision/compound_tool.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>

#include "gshaptics/error.h"
#include "gshaptics/force/force_renderer.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/servo/collision_worker.h"
#include "support/gaussian_worlds.h"

namespace gshaptics {
namespace {

using test::add_layer;
using test::GaussianSpec;
using test::world_of;

std::string write_temp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

std::string error_of(std::string_view spec) {
  try {
    (void)parse_tool_spec(spec);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(CompoundTool, PresetsHaveTheirStatedGeometry) {
  const CompoundTool s = parse_tool_spec("sphere:0.01");
  ASSERT_EQ(s.count, 1);
  EXPECT_EQ(s.parts[0].semi_axes, Eigen::Vector3d::Constant(0.01));
  EXPECT_EQ(s.parts[0].offset, Eigen::Vector3d::Zero());

  const CompoundTool e = parse_tool_spec("ellipsoid:0.01,0.02,0.03");
  ASSERT_EQ(e.count, 1);
  EXPECT_EQ(e.parts[0].semi_axes, Eigen::Vector3d(0.01, 0.02, 0.03));

  const CompoundTool d = parse_tool_spec("disc:0.02,0.004");
  ASSERT_EQ(d.count, 1);
  EXPECT_EQ(d.parts[0].semi_axes, Eigen::Vector3d(0.02, 0.02, 0.002));

  // A stylus: its tip at the TCP, its end at z = L, its parts overlapping along +z.
  const double L = 0.12, R = 0.004;
  const CompoundTool st = parse_tool_spec("stylus:0.12,0.004");
  ASSERT_EQ(st.count, 4);
  double lowest = 1, highest = -1;
  for (int i = 0; i < st.count; ++i) {
    const ToolPart& p = st.parts[std::size_t(i)];
    EXPECT_NEAR(p.offset.x(), 0, 1e-15);
    EXPECT_NEAR(p.offset.y(), 0, 1e-15);
    EXPECT_EQ(p.semi_axes.x(), R);
    lowest = std::min(lowest, p.offset.z() - p.semi_axes.z());
    highest = std::max(highest, p.offset.z() + p.semi_axes.z());
    if (i > 0) {
      const ToolPart& q = st.parts[std::size_t(i - 1)];
      EXPECT_LT(p.offset.z() - p.semi_axes.z(), q.offset.z() + q.semi_axes.z()) << "parts " << i - 1 << ", " << i;
    }
  }
  EXPECT_NEAR(lowest, 0.0, 1e-12);
  EXPECT_NEAR(highest, L, 1e-12);
  EXPECT_NEAR(st.reach(), L, 1e-12);
  EXPECT_NEAR(st.largest_semi_axis(), L / 6, 1e-15);
}

TEST(CompoundTool, BadSpecsAreClearErrors) {
  EXPECT_NE(error_of("cube:1").find("unknown tool 'cube'"), std::string::npos);
  EXPECT_NE(error_of("sphere:-1").find("not a positive number"), std::string::npos);
  EXPECT_NE(error_of("sphere:abc").find("'abc'"), std::string::npos);
  EXPECT_NE(error_of("ellipsoid:1,2").find("expected 3 numbers"), std::string::npos);
  EXPECT_NE(error_of("stylus:0.01,0.03").find("longer than its diameter"), std::string::npos);
  EXPECT_NE(error_of("stylus").find("expected sphere:R"), std::string::npos);
  EXPECT_NE(error_of("/nonexistent/tool.json").find("/nonexistent/tool.json: cannot open"), std::string::npos);
  EXPECT_NE(error_of(write_temp("bad.json", "{not json")).find("not valid JSON"), std::string::npos);
  EXPECT_NE(error_of(write_temp("noparts.json", "{\"tool\": 1}")).find("\"parts\""), std::string::npos);
  EXPECT_NE(error_of(write_temp("empty.json", "{\"parts\": []}")).find("empty"), std::string::npos);
  EXPECT_NE(error_of(write_temp("axes.json", "{\"parts\": [{\"semi_axes\": [1, 0, 1]}]}")).find("part 0: semi-axes"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("axes2.json", "{\"parts\": [{\"semi_axes\": [1, 1]}]}")).find("parts[0].semi_axes"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("rot.json", "{\"parts\": [{\"semi_axes\": [1, 1, 1], \"rotation\": [0, 0, 0, 0]}]}"))
                .find("parts[0].rotation"),
            std::string::npos);
  std::string nine = "{\"parts\": [";
  for (int i = 0; i < 9; ++i) nine += std::string(i ? "," : "") + "{\"semi_axes\": [1, 1, 1]}";
  EXPECT_NE(error_of(write_temp("nine.json", nine + "]}")).find("at most 8"), std::string::npos);
}

TEST(CompoundTool, JsonFileWithRotationsPosesInTheWorld) {
  const std::string path = write_temp(
      "tool.json",
      R"({"parts": [{"center": [0, 0, 0], "semi_axes": [0.01, 0.01, 0.01]},
                    {"center": [0.05, 0, 0], "semi_axes": [0.02, 0.005, 0.005], "rotation": [0.7071067811865476, 0, 0, 0.7071067811865476]}]})");
  const CompoundTool t = parse_tool_spec(path);
  ASSERT_EQ(t.count, 2);
  // The tool turned 90 deg about world z and placed at (1, 2, 3): the second part sits at
  // (1, 2.05, 3) with its long axis along world -x (tool x -> world y, then the part's own turn).
  const Eigen::Quaterniond q(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  std::array<ToolEllipsoid, kMaxToolParts> out;
  ASSERT_EQ(t.posed({1, 2, 3}, q, out), 2);
  EXPECT_LT((out[0].center - Eigen::Vector3d(1, 2, 3)).norm(), 1e-12);
  EXPECT_LT((out[1].center - Eigen::Vector3d(1, 2.05, 3)).norm(), 1e-12);
  const Eigen::Vector3d long_axis = out[1].rotation * Eigen::Vector3d::UnitX();
  EXPECT_LT((long_axis - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-12);
  // A single part at the TCP is the plain ellipsoid; anything else stays compound.
  // A sphere at the TCP is the plain tool; one disc at the TCP stays compound (its rim contact has a torque).
  EXPECT_EQ(tool_shape_for(parse_tool_spec("sphere:0.01")).compound.count, 0);
  EXPECT_EQ(tool_shape_for(parse_tool_spec("sphere:0.01")).semi_axes, Eigen::Vector3d::Constant(0.01));
  EXPECT_EQ(tool_shape_for(parse_tool_spec("disc:0.02,0.004")).compound.count, 1);
  EXPECT_EQ(tool_shape_for(t).compound.count, 2);
}

// A plane of flat Gaussians at z = 0 on a grid symmetric about x = 0 and y = 0.
const CollisionWorld& plane() {
  static const CollisionWorld w = [] {
    std::vector<GaussianSpec> gs;
    add_layer(gs, 0.0f, 0.004f, 0.2f);
    return world_of(gs);
  }();
  return w;
}

TEST(PaperCompound, SumsThePartsAndTagsTheirContacts) {
  // A stylus tilted 50 deg about y, pressed tip-first 3 mm into the plane, moving and turning.
  const CompoundTool stylus = parse_tool_spec("stylus:0.1,0.006");
  const Eigen::Quaterniond q(Eigen::AngleAxisd(50 * M_PI / 180, Eigen::Vector3d::UnitY()));
  const Eigen::Vector3d tcp(0.0013, -0.0021, -0.003), v(0.01, 0.0, -0.02), omega(0.0, 0.5, 0.1);
  std::array<ToolEllipsoid, kMaxToolParts> parts;
  const int n = stylus.posed(tcp, q, parts);
  ForceParams fp;
  fp.tau_normal = 0;  // no filter memory: one tick is the whole answer
  fp.tau_opacity = 0;
  fp.tau_velocity = 0;
  PaperRenderer r(plane(), fp);
  ASSERT_TRUE(r.renders_compound());
  const RenderOutput out = r.render_compound({parts.data(), std::size_t(n)}, tcp, v, omega, 1e-3);
  ASSERT_EQ(out.status, QueryStatus::kOk);

  // The reference: each part queried and modelled on its own.
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
  std::size_t contacts = 0;
  int parts_touching = 0;
  for (int j = 0; j < n; ++j) {
    ContactQuery cq(plane());
    ASSERT_EQ(cq.run(parts[std::size_t(j)]), QueryStatus::kOk);
    ForceModel m(fp);
    const Eigen::Vector3d vj = v + omega.cross(parts[std::size_t(j)].center - tcp);
    const ForceOutput f = m.update(cq.result().contacts(), parts[std::size_t(j)].center, vj, 1e-3);
    force += f.force;
    if (f.contacts > 0) {
      torque += (f.centroid - tcp).cross(f.force);
      ++parts_touching;
    }
    std::size_t tagged = 0;
    for (const Contact& c : r.contacts()) tagged += c.part == j;
    EXPECT_EQ(tagged, cq.result().contacts().size()) << "part " << j;
    contacts += cq.result().contacts().size();
  }
  EXPECT_GE(parts_touching, 1);
  EXPECT_EQ(r.contacts().size(), contacts);
  EXPECT_EQ(out.counts.contacts, contacts);
  EXPECT_GT(out.force.norm(), 0.0);
  EXPECT_LT((out.force - force).norm(), 1e-12 * force.norm());
  EXPECT_LT((out.torque - torque).norm(), 1e-12 * std::max(1e-9, torque.norm()));
  EXPECT_GT(out.torque.norm(), 0.0);  // a tilted stylus touching with its tip side is turned
}

TEST(PaperCompound, SymmetricToolPressedSymmetricallyHasNoTorqueAndMirrorsMirror) {
  // A dumbbell: two spheres 6 cm apart on the tool's x axis, pressed level onto the plane.
  const std::string path = write_temp(
      "dumbbell.json",
      R"({"parts": [{"center": [-0.03, 0, 0], "semi_axes": [0.01, 0.01, 0.01]},
                    {"center": [0.03, 0, 0], "semi_axes": [0.01, 0.01, 0.01]}]})");
  const CompoundTool bell = parse_tool_spec(path);
  std::array<ToolEllipsoid, kMaxToolParts> parts;
  const auto render = [&](const Eigen::Vector3d& tcp, const Eigen::Quaterniond& q) {
    PaperRenderer r(plane());
    const int n = bell.posed(tcp, q, parts);
    return r.render_compound({parts.data(), std::size_t(n)}, tcp, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                             1e-3);
  };
  const RenderOutput level = render({0, 0, 0.008}, Eigen::Quaterniond::Identity());
  ASSERT_GT(level.force.z(), 0.0);
  EXPECT_LT(level.torque.norm(), 1e-9 * level.force.norm() * 0.03);
  // Tilted about y by +20 deg and by -20 deg: the lower sphere is the other one; the torques
  // about y are opposite, and both turn the tool back toward level.
  const Eigen::Quaterniond plus(Eigen::AngleAxisd(20 * M_PI / 180, Eigen::Vector3d::UnitY()));
  const Eigen::Quaterniond minus(Eigen::AngleAxisd(-20 * M_PI / 180, Eigen::Vector3d::UnitY()));
  const RenderOutput a = render({0, 0, 0.017}, plus), b = render({0, 0, 0.017}, minus);
  ASSERT_GT(a.force.z(), 0.0);
  // (The grid's float coordinates are symmetric to about 1e-7 m, hence 1e-5 relative.)
  EXPECT_NEAR(a.force.z(), b.force.z(), 1e-5 * a.force.z());
  EXPECT_NEAR(a.torque.y(), -b.torque.y(), 1e-5 * std::abs(a.torque.y()));
  EXPECT_NEAR(a.torque.x(), b.torque.x(), 1e-12);
  // +20 deg about y takes the tool's +x part down to the plane (at world x = +0.028); the upward
  // push there gives r x F = (+x) x (+z) = -y: back toward level.
  EXPECT_LT(a.torque.y(), 0.0);
  // The lever arm: the torque is the force times about 3 cm (the parts' offset).
  EXPECT_NEAR(std::abs(a.torque.y()) / a.force.norm(), 0.03 * std::cos(20 * M_PI / 180), 0.004);
}

TEST(PaperCompound, ABadPartRendersNothingAndAdvancesNoPartsFilters) {
  // A stylus pressed into the plane for 20 ticks, with one tick in the middle whose last part is
  // NaN: that tick is invalid with no force, and the ticks after it are bit-identical to a run
  // without the bad tick (no earlier part's filters moved on it).
  const CompoundTool stylus = parse_tool_spec("stylus:0.1,0.006");
  const Eigen::Quaterniond q(Eigen::AngleAxisd(40 * M_PI / 180, Eigen::Vector3d::UnitY()));
  std::array<ToolEllipsoid, kMaxToolParts> parts;
  const auto run = [&](bool with_bad_tick) {
    PaperRenderer r(plane());
    RenderOutput last;
    for (int k = 0; k < 20; ++k) {
      const Eigen::Vector3d tcp(0.001, 0.002, 0.002 - 0.0002 * k);
      const int n = stylus.posed(tcp, q, parts);
      if (with_bad_tick && k == 10) {
        parts[std::size_t(n - 1)].center.x() = NAN;
        const RenderOutput bad = r.render_compound({parts.data(), std::size_t(n)}, tcp, {0, 0, -0.2},
                                                   Eigen::Vector3d::Zero(), 1e-3);
        EXPECT_EQ(bad.status, QueryStatus::kInvalidTool);
        EXPECT_EQ(bad.force.norm(), 0.0);
        continue;
      }
      if (!with_bad_tick && k == 10) continue;
      last = r.render_compound({parts.data(), std::size_t(n)}, tcp, {0, 0, -0.2}, Eigen::Vector3d::Zero(), 1e-3);
    }
    return last;
  };
  const RenderOutput a = run(true), b = run(false);
  ASSERT_GT(b.force.norm(), 0.0);
  EXPECT_EQ(a.force, b.force);
  EXPECT_EQ(a.torque, b.torque);
}

// A renderer of one ellipsoid (a caller's own): the worker refuses to hand it a compound tool.
class OneEllipsoid final : public ForceRenderer {
 public:
  std::string_view name() const noexcept override { return "one"; }
  RenderOutput render(const ToolEllipsoid& t, const Eigen::Vector3d&, double) noexcept override {
    RenderOutput o;
    o.proxy = t.center;
    return o;
  }
  std::span<const Contact> contacts() const noexcept override { return {}; }
  void reset() noexcept override {}
};

TEST(CompoundWorker, RenderersOfOneEllipsoidRefuseCompoundToolsTheOthersTakeThem) {
  const CompoundTool stylus = parse_tool_spec("stylus:0.1,0.006");
  ManualClock clock(0);
  try {
    CollisionWorker w(tool_shape_for(stylus), std::make_unique<OneEllipsoid>(), 1e-3, clock);
    ADD_FAILURE() << "a one-ellipsoid renderer took a stylus";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("one ellipsoid"), std::string::npos) << e.what();
  }
  for (const RendererSpec& spec : {RendererSpec(PaperModelSpec{}), RendererSpec(ProxyModelSpec{})}) {
    CollisionWorker w(tool_shape_for(stylus), make_force_renderer(spec, plane()), 1e-3, clock);
    EXPECT_TRUE(w.renderer().renders_compound()) << renderer_name(spec);
  }
  // One part at the TCP is the plain ellipsoid, which any renderer takes.
  EXPECT_NO_THROW(CollisionWorker(tool_shape_for(parse_tool_spec("disc:0.02,0.004")), std::make_unique<OneEllipsoid>(),
                                  1e-3, clock));
}

}  // namespace
}  // namespace gshaptics
