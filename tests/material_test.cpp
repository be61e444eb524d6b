// Materials by region (force/material.h): the map's parsing and errors, the field's regions, the
// blend's continuity across a border, and the proxy reading stiffness and friction under it.

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/error.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/force/compound_proxy.h"
#include "gshaptics/force/material.h"
#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/scene/opacity_filter.h"

namespace gshaptics {
namespace {

// Two materials side by side on the plane: x < 0 "soft", x >= 0 "hard" (the scene's frame).
nlohmann::json two_materials() {
  return nlohmann::json::parse(R"({
    "materials": [{"name": "soft", "stiffness": 600, "mu_s": 0.4, "mu_k": 0.3},
                  {"name": "hard", "stiffness": 1500, "mu_s": 0.8, "mu_k": 0.6, "viscosity": 0}],
    "regions": [{"material": "soft", "box": {"min": [-1, -1, -1], "max": [0, 1, 1]}},
                {"material": "hard", "box": {"min": [0, -1, -1], "max": [1, 1, 1]}}]})");
}

CollisionWorld plane_world(double spacing = 0.004) {
  SynthParams p;
  p.spacing = spacing;
  p.seed = 5;
  p.floater_share = 0;
  return CollisionWorld::build(make_synthetic_scene(AnalyticShape(ShapeKind::kPlane), p).scene, WorldConfig{});
}

std::string error_of(const std::string& text) {
  try {
    (void)MaterialMap::parse(nlohmann::json::parse(text), "map.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(MaterialMap, RefusesWhatIsWrongNamingTheFile) {
  EXPECT_NE(error_of(R"({"materials": [{"name": "a", "stifness": 3}], "regions": []})").find("unknown key \"stifness\""),
            std::string::npos);
  EXPECT_NE(error_of(R"({"materials": [{"stiffness": 3}], "regions": []})").find("needs a \"name\""), std::string::npos);
  EXPECT_NE(error_of(R"({"materials": [{"name": "a", "vibration": 1.5}], "regions": []})").find("a level in [0, 1]"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"materials": [{"name": "a", "stiffness": 0}], "regions": []})").find("\"stiffness\" must be > 0"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"materials": [{"name": "a"}], "regions": [{"material": "b", "indices": [1]}]})")
                .find("no material named \"b\""),
            std::string::npos);
  EXPECT_NE(error_of(R"({"materials": [{"name": "a"}], "regions": [{"material": "a", "box": {"min": [0,0,0], "max": [1,0,1]}}]})")
                .find("min must be below max"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"materials": [{"name": "a"}], "regions": [{"material": "a"}]})").find("exactly one of"),
            std::string::npos);
  EXPECT_EQ(error_of(R"({"materials": [{"name": "a"}], "regions": [{"material": "a"}]})").rfind("map.json", 0), 0u);
  // A file that is not JSON, and one that does not exist.
  const std::string path = (std::filesystem::temp_directory_path() / "gshaptics_material_test.json").string();
  std::ofstream(path) << "{\"materials\": [";
  try {
    (void)MaterialMap::load(path);
    ADD_FAILURE() << "a truncated map loaded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": not valid JSON"), std::string::npos);
  }
  std::filesystem::remove(path);
  EXPECT_THROW((void)MaterialMap::load(path), InputError);
}

// A corrupt map never escapes as anything but InputError: every value of a valid map replaced,
// one at a time, by values of every JSON type (and out-of-range numbers).
TEST(MaterialMap, AnyValueAnywhereIsRefusedWithInputErrorOrTaken) {
  const nlohmann::json base = nlohmann::json::parse(R"({"frame": "scene",
    "materials": [{"name": "a", "stiffness": 10, "damping": 1, "mu_s": 0.5, "mu_k": 0.4, "viscosity": 1,
                   "texture_gain": 1, "vibration": 0, "texture": {"grating": {"wavelength": 0.001, "amplitude": 0.0001,
                   "direction": [1, 0, 0]}}},
                  {"name": "b", "texture": {"noise": {"amplitude": 0.001, "wavelength_min": 0.001, "wavelength_max": 0.002,
                   "seed": 3}}}],
    "regions": [{"material": "a", "box": {"min": [0, 0, 0], "max": [1, 1, 1]}},
                {"material": "b", "sphere": {"center": [0, 0, 0], "radius": 1}},
                {"material": "a", "indices": [1, 2, 3]},
                {"material": "b", "colour": {"rgb": [0.5, 0.2, 0.1], "tolerance": 0.2}},
                {"material": "a", "colour": {"rgb": [0.1, 0.2, 0.3], "clusters": 4}, "sphere": {"center": [0, 0, 0], "radius": 1}}]})");
  const std::vector<nlohmann::json> values = {
      nullptr, true, -1, 0, 1e300, -1e300, 4294967296ull, 18446744073709551615ull, "x", "", nlohmann::json::array(),
      nlohmann::json::array({1, 2}), nlohmann::json::array({"a", nullptr, 3}), nlohmann::json::object(),
      nlohmann::json::parse(R"({"min": 1})")};
  int tried = 0;
  const nlohmann::json flat_base = base.flatten();  // (items() of a temporary would dangle)
  for (const auto& item : flat_base.items()) {
    for (const nlohmann::json& v : values) {
      nlohmann::json flat = flat_base;
      flat[item.key()] = v;
      nlohmann::json j;
      try {
        j = flat.unflatten();
      } catch (const nlohmann::json::exception&) {
        continue;  // (a value that cannot stand there in JSON at all)
      }
      ++tried;
      try {
        (void)MaterialMap::parse(j, "map.json");
      } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()).rfind("map.json", 0), 0u) << item.key();
      } catch (const std::exception& e) {
        ADD_FAILURE() << item.key() << " = " << v.dump() << ": " << e.what();
      }
    }
  }
  EXPECT_GT(tried, 300);
}

TEST(MaterialField, RegionsClaimTheGaussiansAndALeftOutPropertyIsTheProxysOwn) {
  const CollisionWorld world = plane_world();
  nlohmann::json j = two_materials();
  j["materials"][0].erase("stiffness");
  ProxyParams base;
  base.stiffness = 800;
  const auto field = MaterialField::resolve(MaterialMap::parse(j, "map"), world, base);
  std::size_t soft = 0, hard = 0;
  for (std::size_t k = 0; k < world.size(); ++k) {
    const double x = world.gaussians()[k].center[0];
    const int id = field->material_of(k);
    EXPECT_EQ(id, x <= 0 ? 1 : 2) << "x " << x;
    (id == 1 ? soft : hard) += 1;
  }
  EXPECT_EQ(field->counts()[1], soft);
  EXPECT_EQ(field->counts()[2], hard);
  EXPECT_GT(soft, 100u);
  EXPECT_GT(hard, 100u);
  // Far from the border each side's own properties; "soft" left its stiffness to the proxy.
  const MaterialBlend left = field->at(world, Eigen::Vector3d(-0.05, 0, 0.004), 0.005);
  const MaterialBlend right = field->at(world, Eigen::Vector3d(0.05, 0, 0.004), 0.005);
  EXPECT_DOUBLE_EQ(left.stiffness, 800);
  EXPECT_DOUBLE_EQ(left.mu_k, 0.3);
  EXPECT_EQ(field->name(left.dominant), "soft");
  EXPECT_DOUBLE_EQ(right.stiffness, 1500);
  EXPECT_DOUBLE_EQ(right.mu_s, 0.8);
  EXPECT_EQ(field->name(right.dominant), "hard");
  // Nothing near: the proxy's own.
  const MaterialBlend none = field->at(world, Eigen::Vector3d(0, 0, 1.0), 0.005);
  EXPECT_DOUBLE_EQ(none.stiffness, 800);
  EXPECT_EQ(none.dominant, 0);
}

// Property: across the border the blend moves in small steps for small moves (no jump), from
// one side's value to the other's.
TEST(MaterialField, TheBlendNeverJumpsAcrossABorder) {
  const CollisionWorld world = plane_world();
  const auto field = MaterialField::resolve(MaterialMap::parse(two_materials(), "map"), world, ProxyParams{});
  for (double r : {0.0025, 0.005, 0.01}) {
    const double step = r / 50;
    double last = field->at(world, Eigen::Vector3d(-6 * r, 0.001, r), r).stiffness, largest = 0;
    EXPECT_NEAR(last, 600, 1e-6);
    for (double x = -6 * r + step; x <= 6 * r; x += step) {
      const double k = field->at(world, Eigen::Vector3d(x, 0.001, r), r).stiffness;
      largest = std::max(largest, std::abs(k - last));
      last = k;
    }
    EXPECT_NEAR(last, 1500, 1e-6) << "r " << r;
    // 900 N/m over 12 r in 600 steps: a step of 3 % of the difference is a smooth ramp.
    EXPECT_LT(largest, 0.03 * 900) << "r " << r;
  }
}

// The blend from the BVH's per-node moments against a direct sum over every Gaussian.
TEST(MaterialField, TheBlendMatchesADirectSumOverEveryGaussian) {
  const CollisionWorld world = plane_world(0.002);
  nlohmann::json j = two_materials();
  j["regions"].push_back(nlohmann::json::parse(R"({"material": "hard", "sphere": {"center": [-0.02, 0.01, 0], "radius": 0.006}})"));
  const auto field = MaterialField::resolve(MaterialMap::parse(j, "map"), world, ProxyParams{});
  const double k_of[3] = {ProxyParams{}.stiffness, 600, 1500};
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> uni(-1, 1);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Vector3d c(0.04 * uni(rng), 0.04 * uni(rng), 0.006 + 0.004 * uni(rng));
    const double r = 0.003 + 0.002 * uni(rng), rho2 = 4 * r * r;
    double w = 0, wk = 0;
    for (std::size_t k = 0; k < world.size(); ++k) {
      const CollisionGaussian& g = world.gaussians()[k];
      const double d2 = (Eigen::Vector3d(g.center[0], g.center[1], g.center[2]) - c).squaredNorm();
      if (d2 >= rho2) continue;
      w += g.opacity * (1 - d2 / rho2);
      wk += g.opacity * (1 - d2 / rho2) * k_of[field->material_of(k)];
    }
    const double expected = w > 0 ? wk / w : ProxyParams{}.stiffness;
    EXPECT_NEAR(field->at(world, c, r).stiffness, expected, 1e-6 * expected) << "trial " << trial;
  }
}

// Pressed at x (the plane's z = 0) from 3 mm above to 5 mm in at 1 cm/s: the slope of F_z between
// 1 and 5 mm of depth, N/m.
double press_stiffness(ProxyRenderer& proxy, double x, double r) {
  proxy.reset();
  double f1 = 0, f5 = 0;
  for (int i = 0; i <= 800; ++i) {
    const double delta = -0.003 + 1e-5 * i;
    const RenderOutput o = proxy.render(ToolEllipsoid::sphere(Eigen::Vector3d(x, 0, r - delta), r),
                                        Eigen::Vector3d(0, 0, -0.01), 1e-3);
    if (std::abs(delta - 0.001) < 5e-6) f1 = o.force.z();
    if (std::abs(delta - 0.005) < 5e-6) f5 = o.force.z();
  }
  return (f5 - f1) / 0.004;
}

// Pressed in 2 mm at x = -4 cm, then slid 2 mm deep at 5 cm/s to x = +4 cm: the friction against
// the motion over the normal force (mean -F_x over mean F_z) on each side, farther than 3 r from
// the border and past the start. `held` (optional): F_z > 0 on every tick of the slide.
std::array<double, 2> slide_ratios(ProxyRenderer& proxy, double r, bool* held = nullptr) {
  const double dt = 1e-3;
  proxy.reset();
  for (int i = 0; i <= 300; ++i) {
    const double delta = std::min(0.002, -0.001 + 1e-5 * i);
    (void)proxy.render(ToolEllipsoid::sphere(Eigen::Vector3d(-0.04, 0, r - delta), r), Eigen::Vector3d(0, 0, -0.01), dt);
  }
  double ft[2] = {0, 0}, fn[2] = {0, 0};
  if (held) *held = true;
  for (int i = 0; i <= 1600; ++i) {
    const double x = -0.04 + 5e-5 * i;
    const RenderOutput o = proxy.render(ToolEllipsoid::sphere(Eigen::Vector3d(x, 0, r - 0.002), r),
                                        Eigen::Vector3d(0.05, 0, 0), dt);
    if (held && !(o.force.z() > 0)) *held = false;
    if (std::abs(x) < 3 * r || std::abs(x) > 0.035) continue;  // the blend near the border; the start
    ft[x > 0] += -o.force.x();
    fn[x > 0] += o.force.z();
  }
  return {ft[0] / fn[0], ft[1] / fn[1]};
}

// The proxy presses each side with that side's stiffness, and slides with its kinetic friction.
TEST(MaterialProxy, EachSideHasItsStiffnessAndFriction) {
  const CollisionWorld world = plane_world();
  const double r = 0.005;
  ProxyRenderer proxy(world, ProxyParams{});
  proxy.set_materials(MaterialField::resolve(MaterialMap::parse(two_materials(), "map"), world, ProxyParams{}));
  for (const auto& [x, k] : {std::pair{-0.04, 600.0}, std::pair{0.04, 1500.0}})
    EXPECT_NEAR(press_stiffness(proxy, x, r), k, 0.05 * k) << "x " << x;
  const std::array<double, 2> ratio = slide_ratios(proxy, r);
  EXPECT_NEAR(ratio[0], 0.3, 0.05 * 0.3);
  EXPECT_NEAR(ratio[1], 0.6, 0.05 * 0.6);
  EXPECT_EQ(proxy.materials()->name(proxy.material().dominant), "hard");
}

// Property: sliding across the border at constant depth, the force never steps: its largest
// change in a tick is no larger than where the tool slides over one material.
TEST(MaterialProxy, CrossingABorderNeverStepsTheForce) {
  const CollisionWorld world = plane_world();
  const double r = 0.005, dt = 1e-3;
  for (double speed : {0.02, 0.1}) {
    ProxyRenderer proxy(world, ProxyParams{});
    proxy.set_materials(MaterialField::resolve(MaterialMap::parse(two_materials(), "map"), world, ProxyParams{}));
    for (int i = 0; i <= 300; ++i)
      (void)proxy.render(ToolEllipsoid::sphere(Eigen::Vector3d(-0.04, 0, r - std::min(0.002, -0.001 + 1e-5 * i)), r),
                         Eigen::Vector3d::Zero(), dt);
    Eigen::Vector3d last = Eigen::Vector3d::Zero();
    double border = 0, away = 0, k_mid = 0;
    for (double x = -0.04; x <= 0.04; x += speed * dt) {
      const RenderOutput o = proxy.render(ToolEllipsoid::sphere(Eigen::Vector3d(x, 0, r - 0.002), r),
                                          Eigen::Vector3d(speed, 0, 0), dt);
      const double step = last.isZero() ? 0.0 : (o.force - last).norm();
      last = o.force;
      if (std::abs(x) < 2 * r) border = std::max(border, step);
      else if (x > -0.035) away = std::max(away, step);
      if (std::abs(x - r) < speed * dt) k_mid = proxy.material().stiffness;
    }
    EXPECT_LT(border, std::max(2 * away, 0.05)) << "speed " << speed;
    EXPECT_GT(k_mid, 600) << "speed " << speed;  // blended, past the border
    EXPECT_NEAR(proxy.material().stiffness, 1500, 1.0) << "speed " << speed;  // 8 radii of path: e^-8 of the way left
  }
}

// The 2 mm plane as the seen solid's world keeps it (its faint Gaussians too).
CollisionWorld seen_plane_world() {
  SynthParams sp;
  sp.spacing = 0.002;
  sp.seed = 5;
  sp.floater_share = 0;
  WorldConfig config;
  config.min_opacity = kSeenMinOpacity;
  return CollisionWorld::build(make_synthetic_scene(AnalyticShape(ShapeKind::kPlane), sp).scene, config);
}

// The proxy on the seen solid reads the material from the layers that make the seen surface
// (SeenSolid::visit_hit_layers): each side's stiffness, and its kinetic friction while sliding
// (the friction cone moves the proxy across the contact's axis). The plane keeps its faint
// Gaussians, as the seen solid's world does; 2 mm spacing (at 4-8 mm the seen normal's tilt
// along one path biases F_t / F_n by up to 0.02: bench/RESULTS.md, forty-sixth session).
TEST(MaterialProxy, OnTheSeenSurfaceEachSideHasItsStiffnessAndFriction) {
  const CollisionWorld world = seen_plane_world();
  ProxyParams seen;
  seen.surface = ProxySurface::kSeen;
  const double r = 0.005;
  ProxyRenderer proxy(world, seen);
  proxy.set_materials(MaterialField::resolve(MaterialMap::parse(two_materials(), "map"), world, seen));
  for (const auto& [x, k] : {std::pair{-0.04, 600.0}, std::pair{0.04, 1500.0}})
    EXPECT_NEAR(press_stiffness(proxy, x, r), k, 0.05 * k) << "x " << x;
  bool held = false;
  const std::array<double, 2> ratio = slide_ratios(proxy, r, &held);
  EXPECT_TRUE(held);
  EXPECT_NEAR(ratio[0], 0.3, 0.05 * 0.3);
  EXPECT_NEAR(ratio[1], 0.6, 0.05 * 0.6);
  EXPECT_EQ(proxy.materials()->name(proxy.material().dominant), "hard");
}

// A stylus (the compound proxy) pressed tip-first into each side feels that side's stiffness: the
// force's slope between 4 and 8 mm of travel past the touch (the same path on both sides, so the
// discs' jitter cancels in the slope).
TEST(MaterialProxy, AStylusFeelsEachSidesStiffness) {
  const CollisionWorld world = plane_world();
  const auto field = MaterialField::resolve(MaterialMap::parse(two_materials(), "map"), world, ProxyParams{});
  const CompoundTool stylus = parse_tool_spec("stylus:0.06,0.004");
  // The stylus points up from its tip (the TCP): identity orientation, the tip lowered onto z = 0.
  for (const auto& [x, k] : {std::pair{-0.04, 600.0}, std::pair{0.04, 1500.0}}) {
    CompoundProxy proxy(world, stylus, ProxyParams{});
    proxy.set_materials(field);
    double f4 = 0, f8 = 0, touch = NAN;
    for (int i = 0; i <= 1500; ++i) {
      const double z = 0.006 - 1e-5 * i;  // 6 mm above the plane to 9 mm below
      const RenderOutput o = proxy.render(Eigen::Vector3d(x, 0.001, z), Eigen::Quaterniond::Identity(),
                                          Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 1e-3);
      if (std::isnan(touch) && o.force.norm() > 0) touch = z;
      if (!std::isnan(touch) && std::abs(touch - z - 0.004) < 5e-6) f4 = o.force.norm();
      if (!std::isnan(touch) && std::abs(touch - z - 0.008) < 5e-6) f8 = o.force.norm();
    }
    ASSERT_FALSE(std::isnan(touch)) << "x " << x;
    EXPECT_NEAR((f8 - f4) / 0.004, k, 0.05 * k) << "x " << x;
    ASSERT_NE(proxy.material(), nullptr);
    EXPECT_NEAR(proxy.material()->stiffness, k, 1e-9);
  }
}


// One tick of an upright stylus (identity orientation: its parts above its tip, the TCP) through
// ProxyRenderer::render_compound, as the servo step drives a tool with a shape.
RenderOutput stylus_tick(ProxyRenderer& proxy, const CompoundTool& stylus, const Eigen::Vector3d& tip,
                         const Eigen::Vector3d& velocity) {
  std::array<ToolEllipsoid, kMaxToolParts> parts{};
  const int n = stylus.posed(tip, Eigen::Quaterniond::Identity(), parts);
  return proxy.render_compound(std::span<const ToolEllipsoid>(parts.data(), std::size_t(n)), tip, velocity,
                               Eigen::Vector3d::Zero(), 1e-3);
}

// The stylus on the seen solid (SeenCompoundProxy) reads the materials from the layers under its
// touching parts: pressed tip-first into each side, that side's stiffness (the slope between 1 and
// 5 mm past the touch); slid 2 mm deep at 5 cm/s from side to side, each side's kinetic friction;
// across the border no step in force above twice the largest away from it (at least 0.05 N:
// without the blend the spring's 2 mm would step by 1.8 N), ending on the hard side's stiffness.
TEST(MaterialProxy, OnTheSeenSurfaceAStylusHasEachSidesStiffnessAndFriction) {
  const CollisionWorld world = seen_plane_world();
  ProxyParams seen;
  seen.surface = ProxySurface::kSeen;
  const CompoundTool stylus = parse_tool_spec("stylus:0.06,0.004");
  ProxyRenderer proxy(world, seen);
  proxy.set_tool(stylus);
  proxy.set_materials(MaterialField::resolve(MaterialMap::parse(two_materials(), "map"), world, seen));
  ASSERT_NE(proxy.seen_compound(), nullptr);
  for (const auto& [x, k] : {std::pair{-0.04, 600.0}, std::pair{0.04, 1500.0}}) {
    proxy.reset();
    double touch = NAN, f1 = 0, f5 = 0;
    for (int i = 0; i <= 1000; ++i) {
      const double z = 0.003 - 1e-5 * i;  // 3 mm above the plane to 7 mm below
      const RenderOutput o = stylus_tick(proxy, stylus, Eigen::Vector3d(x, 0.001, z), Eigen::Vector3d(0, 0, -0.01));
      if (std::isnan(touch) && o.force.z() > 0) touch = z;
      if (!std::isnan(touch) && std::abs(touch - z - 0.001) < 5e-6) f1 = o.force.z();
      if (!std::isnan(touch) && std::abs(touch - z - 0.005) < 5e-6) f5 = o.force.z();
    }
    ASSERT_FALSE(std::isnan(touch)) << "x " << x;
    EXPECT_NEAR((f5 - f1) / 0.004, k, 0.05 * k) << "x " << x;
    EXPECT_EQ(proxy.materials()->name(proxy.material().dominant), x < 0 ? "soft" : "hard");
  }
  proxy.reset();
  for (int i = 0; i <= 300; ++i)
    (void)stylus_tick(proxy, stylus, Eigen::Vector3d(-0.04, 0.001, -std::min(0.002, -0.001 + 1e-5 * i)),
                      Eigen::Vector3d(0, 0, -0.01));
  double ft[2] = {0, 0}, fn[2] = {0, 0}, border = 0, away = 0;
  Eigen::Vector3d last = Eigen::Vector3d::Zero();
  bool held = true;
  for (int i = 0; i <= 1600; ++i) {
    const double x = -0.04 + 5e-5 * i;
    const RenderOutput o = stylus_tick(proxy, stylus, Eigen::Vector3d(x, 0.001, -0.002), Eigen::Vector3d(0.05, 0, 0));
    held = held && o.force.z() > 0;
    const double step = last.isZero() ? 0.0 : (o.force - last).norm();
    last = o.force;
    if (std::abs(x) < 0.008) border = std::max(border, step);
    else if (x > -0.035) away = std::max(away, step);
    if (std::abs(x) < 0.012 || std::abs(x) > 0.035) continue;  // the blend near the border; the start
    ft[x > 0] += -o.force.x();
    fn[x > 0] += o.force.z();
  }
  EXPECT_TRUE(held);
  EXPECT_NEAR(ft[0] / fn[0], 0.3, 0.05 * 0.3);
  EXPECT_NEAR(ft[1] / fn[1], 0.6, 0.05 * 0.6);
  EXPECT_LT(border, std::max(2 * away, 0.05));
  EXPECT_NEAR(proxy.material().stiffness, 1500, 1.0);
}

// Colour regions: the tolerance against a direct test of every Gaussian's colour, k-means
// clusters picking a whole colour group, a box with a colour holding their intersection, and a
// map that selects by colour refused until it is resolved on colours.
TEST(MaterialColour, RegionsSelectTheGaussiansOfAColour) {
  const std::array<Eigen::Vector3d, 3> groups = {Eigen::Vector3d(0.8, 0.15, 0.1), Eigen::Vector3d(0.2, 0.7, 0.25),
                                                 Eigen::Vector3d(0.15, 0.2, 0.85)};
  constexpr double kC0 = 0.28209479177387814;
  GaussianScene scene;
  std::vector<Eigen::Vector3d> rgb;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> pos(-1, 1);
  std::normal_distribution<double> jitter(0, 0.04);
  for (int i = 0; i < 900; ++i) {
    const Eigen::Vector3d c = (groups[std::size_t(i % 3)] + Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng)))
                                  .cwiseMax(0.0).cwiseMin(1.0);
    scene.push_back(Eigen::Vector3f(float(pos(rng)), float(pos(rng)), 0.f), {0.01f, 0.01f, 0.01f}, {1, 0, 0, 0}, 0.9f,
                    std::uint32_t(1000 + i));
    scene.colors_dc.push_back(((c.array() - 0.5) / kC0).cast<float>().matrix());
    rgb.push_back(c);
  }
  const MaterialMap map = MaterialMap::parse(nlohmann::json::parse(R"({"materials": [{"name": "red"}, {"name": "blue"},
      {"name": "green"}],
      "regions": [{"material": "red", "colour": {"rgb": [0.8, 0.15, 0.1], "tolerance": 0.06}},
                  {"material": "blue", "colour": {"rgb": [0.1, 0.1, 1.0], "clusters": 3}},
                  {"material": "green", "colour": {"rgb": [0.2, 0.7, 0.25], "clusters": 3},
                   "box": {"min": [-2, -2, -1], "max": [0, 2, 1]}}]})"), "map.json");
  EXPECT_TRUE(map.needs_colours());
  const CollisionWorld world = CollisionWorld::build(scene, WorldConfig{});
  EXPECT_THROW((void)MaterialField::resolve(map, world, ProxyParams{}), InputError);
  std::vector<std::size_t> selected;
  const MaterialMap resolved = resolve_colour_regions(map, scene, &selected);
  EXPECT_FALSE(resolved.needs_colours());
  const auto field = MaterialField::resolve(resolved, world, ProxyParams{});
  std::size_t by_tolerance = 0;
  for (std::size_t slot = 0; slot < world.size(); ++slot) {
    const std::uint32_t i = world.gaussians()[slot].source_index - 1000;
    const double x = world.gaussians()[slot].center[0];
    // The last region that holds a Gaussian gives its material (ids: 0 none, 1 red, 2 blue, 3 green).
    int expected = (rgb[i] - groups[0]).norm() <= 0.06 ? 1 : 0;
    by_tolerance += expected == 1;
    if (i % 3 == 2) expected = 2;                 // the blue group is one cluster
    if (i % 3 == 1 && x <= 0) expected = 3;       // the green group, within the box
    EXPECT_EQ(int(field->material_of(slot)), expected) << "Gaussian " << i;
  }
  EXPECT_EQ(selected[0], by_tolerance);
  EXPECT_GT(by_tolerance, 50u);
  EXPECT_LT(by_tolerance, 300u);  // a tight tolerance takes part of the red group only
  EXPECT_EQ(selected[1], 300u);
  EXPECT_EQ(selected[2], 300u);
  // A scene without colour is refused, naming the map.
  GaussianScene grey = scene;
  grey.colors_dc.clear();
  try {
    (void)resolve_colour_regions(map, grey);
    ADD_FAILURE() << "a scene without colour was taken";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("map.json", 0), 0u) << e.what();
    EXPECT_NE(std::string(e.what()).find("no colour"), std::string::npos) << e.what();
  }
  EXPECT_NE(error_of(R"({"materials": [{"name": "a"}], "regions": [{"material": "a", "colour": {"rgb": [2, 0, 0]}}]})")
                .find("must lie in [0, 1]"), std::string::npos);
  EXPECT_NE(error_of(R"({"materials": [{"name": "a"}], "regions": [{"material": "a", "colour": {"rgb": [1, 0, 0],
                "clusters": 2.5}}]})").find("whole number"), std::string::npos);
  EXPECT_NE(error_of(R"({"materials": [{"name": "a"}], "regions": [{"material": "a", "colour": {"rgb": [1, 0, 0]},
                "indices": [1]}]})").find("exactly one of"), std::string::npos);
}

}  // namespace
}  // namespace gshaptics
