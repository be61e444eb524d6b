// The proxy's work-saving paths give the plain computation's answers (issue 38). The sweep's
// bounds (bounding-sphere capsule, slab, members of the family: the one exact along the offset
// and each Gaussian's last maximiser; candidates past the best contact so far never queued), its
// one-pass floater filter and its warm-started searches (each Gaussian's lambda search starts at
// its last maximiser, by Newton's method for spheres) against the plain computation: a cold
// sweep_time() of every Gaussian of the world, the smallest time among those the filter does not
// let pass. On the bundled Truck (near-surface tools, random motions) and on fidelity scenes (a
// cube edge, a sphere with floaters). The bounds alone are exact; the warm start moves the
// first-contact time by the search's tolerance (1e-12 of the motion here); a sweep with a
// tolerance reports a contact at most that much later than the first. Near lists (the
// candidates of a resting compound tool's sweeps from its parts' last lists) give the BVH's
// contacts. The shaded normal with working memory is bit-identical to the plain two-pass one.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <limits>
#include <memory>
#include <random>

#include "gshaptics/collision/sweep_query.h"
#include "gshaptics/fidelity/analytic_shape.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/force/shaded_normal.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/sim/pose_sampler.h"
#include "support/gaussian_worlds.h"

namespace gshaptics {
namespace {

constexpr std::size_t kMaxToolPartsForTest = 8;

// A filter that lets every third slot (by a hash of it) pass: exercised in both paths.
bool every_third_blocks(void*, std::uint32_t slot) noexcept { return (slot * 2654435761u) % 3 != 0; }
// Half of those it lets pass, known beforehand (BlockFilter::known_to_pass: not searched).
bool half_known_to_pass(void*, std::uint32_t slot) noexcept { return !every_third_blocks(nullptr, slot) && slot % 2 == 0; }

// The plain computation: every Gaussian's exact first-contact time, the smallest among those
// that block.
double plain_first_contact(const CollisionWorld& w, const ToolEllipsoid& tool, const Eigen::Vector3d& motion,
                           bool filtered) {
  double best = std::numeric_limits<double>::infinity();
  for (std::uint32_t k = 0; k < w.size(); ++k) {
    const double t = sweep_time(w.gaussians()[k], tool, motion);
    if (t <= 1.0 && (!filtered || every_third_blocks(nullptr, k))) best = std::min(best, t);
  }
  return best;
}

// Runs `n` sweeps drawn by `draw` both ways and counts the hits (so a test can check that it
// exercised contact at all). Each sweep runs twice, the second warm-started by the first.
template <typename Draw>
int expect_same_first_contacts(const CollisionWorld& w, int n, Draw&& draw) {
  SweepQuery sweep(w);
  int hits = 0;
  for (int i = 0; i < n; ++i) {
    const auto [tool, motion] = draw(i);
    for (const bool filtered : {false, true}) {
      BlockFilter f;
      if (filtered) {
        f.blocks = &every_third_blocks;
        f.known_to_pass = &half_known_to_pass;
      }
      (void)sweep.first_contact(tool, motion, {}, {}, f);  // fills the warm starts
      const SweepHit hit = sweep.first_contact(tool, motion, {}, {}, f);
      const double plain = plain_first_contact(w, tool, motion, filtered);
      if (!std::isfinite(plain)) {
        EXPECT_FALSE(hit.hit) << "sweep " << i << (filtered ? " filtered" : "");
        EXPECT_FALSE(sweep.first_contact(tool, motion, {}, {}, f, 1.0, 1e-2).hit) << "sweep " << i;
        continue;
      }
      ++hits;
      EXPECT_TRUE(hit.hit) << "sweep " << i;
      EXPECT_NEAR(hit.t, plain, 1e-12) << "sweep " << i << (filtered ? " filtered" : "");
      if (filtered) {
        EXPECT_TRUE(every_third_blocks(nullptr, hit.slot)) << "a passing Gaussian was reported";
      }
      // With hints (the contact itself, which then bounds the traversal to the box swept up to
      // it, and an arbitrary other Gaussian): the same contact.
      const std::uint32_t hints[2] = {hit.slot, std::uint32_t((hit.slot * 7919u + 13u) % w.size())};
      for (std::size_t nh : {std::size_t(1), std::size_t(2)}) {
        const SweepHit hh = sweep.first_contact(tool, motion, {}, {hints, nh}, f);
        EXPECT_TRUE(hh.hit) << "sweep " << i << " hints " << nh;
        EXPECT_NEAR(hh.t, plain, 1e-12) << "sweep " << i << " hints " << nh;
      }
      // With a tolerance: a contact no earlier than the first and at most the tolerance later.
      for (const double tol : {1e-4, 1e-2}) {
        const SweepHit ht = sweep.first_contact(tool, motion, {}, {}, f, 1.0, tol);
        EXPECT_TRUE(ht.hit) << "sweep " << i << " tolerance " << tol;
        EXPECT_GE(ht.t, plain - 1e-12) << "sweep " << i << " tolerance " << tol;
        EXPECT_LE(ht.t, plain + tol + 1e-12) << "sweep " << i << " tolerance " << tol;
        // It is a real contact of the Gaussian it names.
        EXPECT_NEAR(sweep_time(w.gaussians()[ht.slot], tool, motion), ht.t, 1e-12) << "sweep " << i;
      }
    }
    if (::testing::Test::HasFailure()) break;  // one sweep's report is enough
  }
  return hits;
}

// The bundled Truck, registered as `gshaptics simulate` does (null when the file is absent);
// built once for the tests below.
const CollisionWorld* truck() {
  static const std::unique_ptr<CollisionWorld> w = [] {
    const std::string scene = std::string(GSHAPTICS_DATA_DIR) + "/truck.splat";
    if (!std::filesystem::exists(scene)) return std::unique_ptr<CollisionWorld>();
    WorldConfig cfg;
    cfg.registration = load_registration_file(std::string(GSHAPTICS_DATA_DIR) + "/truck.registration.json");
    return std::make_unique<CollisionWorld>(CollisionWorld::build(load_scene(scene).scene, cfg));
  }();
  return w.get();
}

// Tool poses near the Truck's surface (PoseSampler; `anisotropic`: ellipsoidal tools too).
std::vector<ToolEllipsoid> truck_poses(std::size_t count, std::uint64_t seed, bool anisotropic = false) {
  PoseSamplerParams pp;
  pp.count = count;
  pp.seed = seed;
  pp.anisotropic = anisotropic;
  return sample_poses(*truck(), pp);
}

TEST(SweepBounds, TruckNearSurfaceSweepsMatchThePlainComputation) {
  if (truck() == nullptr) GTEST_SKIP() << "the bundled truck.splat was not found";
  const CollisionWorld& w = *truck();
  // Ellipsoidal tools too (the lambda = 1/2 bound is for spheres only).
  const std::vector<ToolEllipsoid> tools = truck_poses(60, 11, true);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01;
  const int hits = expect_same_first_contacts(w, int(tools.size()), [&](int i) {
    ToolEllipsoid t = tools[std::size_t(i)];
    if (i % 2 == 0) t.semi_axes.setConstant(t.semi_axes.maxCoeff());  // and spheres
    const double r = t.semi_axes.maxCoeff();
    const Eigen::Vector3d m = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized() * r * (0.05 + 2.0 * (i % 5) / 4.0);
    t.center -= m * 0.5;  // start half a motion back, so that some sweeps begin free
    return std::pair(t, m);
  });
  EXPECT_GT(hits, 40);
}

// A rigid compound tool in one sweep (first_contact over a span of parts: one traversal, one
// sorted list, one bar) and each part's own contact (first_contacts) against the plain
// computation per part, on random compound tools (2-6 ellipsoids and spheres, random offsets
// and rotations) near the Truck's surface, with and without a filter, each sweep run twice (the
// second warm-started by the first).
TEST(SweepBounds, CompoundToolSweepsMatchThePlainComputationPerPart) {
  if (truck() == nullptr) GTEST_SKIP() << "the bundled truck.splat was not found";
  const CollisionWorld& w = *truck();
  const std::vector<ToolEllipsoid> poses = truck_poses(24, 5);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-1, 1), s(0.3, 1.0);
  SweepQuery sweep(w);
  int hits = 0, parts_hit = 0, later_parts = 0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const double r = poses[i].semi_axes.maxCoeff();
    std::vector<ToolEllipsoid> parts(2 + i % 5);
    for (std::size_t j = 0; j < parts.size(); ++j) {
      ToolEllipsoid& t = parts[j];
      t.center = poses[i].center + Eigen::Vector3d(u(rng), u(rng), u(rng)) * r;
      t.semi_axes = j % 2 == 0 ? Eigen::Vector3d(Eigen::Vector3d::Constant(s(rng) * r)) : Eigen::Vector3d(Eigen::Vector3d(s(rng), s(rng), s(rng)) * r);
      t.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(3.0 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()));
    }
    const Eigen::Vector3d m = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized() * r * (0.1 + 1.5 * double(i % 4) / 3.0);
    for (ToolEllipsoid& t : parts) t.center -= m * 0.5;  // some sweeps begin free
    for (const bool filtered : {false, true}) {
      BlockFilter f;
      if (filtered) {
        f.blocks = &every_third_blocks;
        f.known_to_pass = &half_known_to_pass;
      }
      std::vector<double> plain(parts.size());
      double first = std::numeric_limits<double>::infinity();
      for (std::size_t j = 0; j < parts.size(); ++j) first = std::min(first, plain[j] = plain_first_contact(w, parts[j], m, filtered));
      (void)sweep.first_contact(parts, m, {}, {}, f);  // fills the warm starts
      const SweepHit hit = sweep.first_contact(parts, m, {}, {}, f);
      ASSERT_EQ(hit.hit, std::isfinite(first)) << "tool " << i;
      if (hit.hit) {
        ++hits;
        EXPECT_NEAR(hit.t, first, 1e-12) << "tool " << i;
        ASSERT_LT(std::size_t(hit.part), parts.size());
        EXPECT_NEAR(sweep_time(w.gaussians()[hit.slot], parts[std::size_t(hit.part)], m), hit.t, 1e-12) << "tool " << i;
        later_parts += hit.part > 0;
        const SweepHit ht = sweep.first_contact(parts, m, {}, {}, f, 1.0, 1e-3);
        EXPECT_TRUE(ht.hit);
        EXPECT_GE(ht.t, first - 1e-12);
        EXPECT_LE(ht.t, first + 1e-3 + 1e-12);
        const std::uint32_t hint = hit.slot;  // the contact as a hint: the same contact
        const SweepHit hh = sweep.first_contact(parts, m, {}, {&hint, 1}, f);
        EXPECT_TRUE(hh.hit);
        EXPECT_NEAR(hh.t, first, 1e-12) << "tool " << i << " with a hint";
      }
      std::vector<SweepHit> each(parts.size());
      sweep.first_contacts(parts, m, each, {}, f);  // fills the warm starts
      std::uint32_t part_hints[kMaxToolPartsForTest];
      std::size_t n_part_hints = 0;
      for (const SweepHit& e : each)
        if (e.hit && n_part_hints < kMaxToolPartsForTest) part_hints[n_part_hints++] = e.slot;
      sweep.first_contacts(parts, m, each, {part_hints, n_part_hints}, f);  // each part's contact as a hint
      for (std::size_t j = 0; j < parts.size(); ++j) {
        ASSERT_EQ(each[j].hit, std::isfinite(plain[j])) << "tool " << i << " part " << j;
        if (!each[j].hit) continue;
        ++parts_hit;
        EXPECT_EQ(each[j].part, int(j));
        EXPECT_NEAR(each[j].t, plain[j], 1e-12) << "tool " << i << " part " << j;
      }
      // With a tolerance: each part still hits exactly when it touches, at most that much late.
      sweep.first_contacts(parts, m, each, {part_hints, n_part_hints}, f, 1e-3);
      for (std::size_t j = 0; j < parts.size(); ++j) {
        ASSERT_EQ(each[j].hit, std::isfinite(plain[j])) << "tool " << i << " part " << j << ", tolerance";
        if (!each[j].hit) continue;
        EXPECT_GE(each[j].t, plain[j] - 1e-12) << "tool " << i << " part " << j << ", tolerance";
        EXPECT_LE(each[j].t, plain[j] + 1e-3 + 1e-12) << "tool " << i << " part " << j << ", tolerance";
      }
    }
    if (::testing::Test::HasFailure()) break;
  }
  EXPECT_GT(hits, 20);
  EXPECT_GT(parts_hit, 2 * hits);  // several parts touch on most motions
  EXPECT_GT(later_parts, 5);       // and the first contact is not always the first part's
}

// Near lists (SweepQuery's reuse margin) against the BVH: compound tools (elongated parts,
// whose core is their axis, and round ones, whose core is their centre) near the Gaussians sweep
// short motions from poses drifting toward the Gaussians for six sweeps and back for six
// (toward: against the last contact's normal), so that the first contact is often a Gaussian that
// was out of reach where its part's list was built; the last contact is the hint (so that lists
// are built); now and then the tool turns (the lists no longer fit) or jumps three tool sizes (it
// leaves their boxes). Each sweep, shared bar and per part, against the same sweep without
// lists and, every fifth, against the plain computation.
struct NearListWork {
  std::uint64_t sweeps = 0, hits = 0, part_hits = 0, reused = 0, rebuilt = 0;
};
void expect_near_lists_give_the_bvhs_contacts(const CollisionWorld& w, const std::vector<Eigen::Vector3d>& centres,
                                              double r, std::uint64_t seed, NearListWork& work) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1), s(0.4, 1.0);
  std::normal_distribution<double> n01;
  for (std::size_t i = 0; i < centres.size(); ++i) {
    std::vector<ToolEllipsoid> parts(2 + i % 3);
    std::vector<Eigen::Vector3d> offsets(parts.size());
    Eigen::Quaterniond q(Eigen::AngleAxisd(3.0 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()));
    for (std::size_t j = 0; j < parts.size(); ++j) {
      offsets[j] = Eigen::Vector3d(u(rng), u(rng), u(rng)) * r;
      const double a = s(rng) * r;
      parts[j].semi_axes = j % 2 == 0 ? Eigen::Vector3d(a, a / 3, a / 3.5) : Eigen::Vector3d(Eigen::Vector3d::Constant(a / 2));
    }
    const double margin = 0.5 * r;
    SweepQuery with(w, 4096, margin), without(w);
    Eigen::Vector3d centre = centres[i];
    std::vector<std::uint32_t> hint{0};
    Eigen::Vector3d toward = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized();
    for (int step = 0; step < 48; ++step) {
      const double sense = (step / 6) % 2 == 0 ? 1.0 : -1.0;
      if (step % 13 == 12) centre += Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized() * 3 * r;  // a jump
      else centre += toward * sense * 0.06 * margin + Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.01 * margin;
      if (step % 17 == 16) q = Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ())) * q;  // a turn
      for (std::size_t j = 0; j < parts.size(); ++j) {
        parts[j].center = centre + q * offsets[j];
        parts[j].rotation = q;
      }
      // Short motions (a resting tool's slides and contact probes; two in three toward the
      // Gaussians) and now and then a long one.
      const double len = step % 7 == 6 ? 2.0 * r : (step % 2 == 0 ? 0.2 : 0.45) * margin * (0.1 + 0.9 * std::fabs(u(rng)));
      const Eigen::Vector3d dir = step % 3 == 2 ? Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized()
                                                : Eigen::Vector3d((toward + 0.3 * Eigen::Vector3d(u(rng), u(rng), u(rng))).normalized());
      const Eigen::Vector3d m = dir * len;
      const SweepHit a = with.first_contact(parts, m, {}, hint), b = without.first_contact(parts, m, {}, hint);
      ++work.sweeps;
      work.reused += with.counts().reused;
      work.rebuilt += with.counts().rebuilt;
      ASSERT_EQ(a.hit, b.hit) << "tool " << i << " step " << step;
      if (a.hit) {
        ++work.hits;
        EXPECT_NEAR(a.t, b.t, 1e-12) << "tool " << i << " step " << step;
        EXPECT_NEAR(sweep_time(w.gaussians()[a.slot], parts[std::size_t(a.part)], m), a.t, 1e-12)
            << "tool " << i << " step " << step << " slot " << a.slot << " part " << a.part << " normal "
            << a.normal.transpose() << " motion " << m.transpose() << " (reverse motion: t "
            << sweep_time(w.gaussians()[a.slot], parts[std::size_t(a.part)], -m) << ")";
        hint[0] = a.slot;
        toward = -a.normal;
      }
      if (step % 5 == 0) {
        double first = std::numeric_limits<double>::infinity();
        for (const ToolEllipsoid& t : parts) first = std::min(first, plain_first_contact(w, t, m, false));
        EXPECT_EQ(a.hit, std::isfinite(first)) << "tool " << i << " step " << step;
        if (a.hit) {
          EXPECT_NEAR(a.t, first, 1e-12) << "tool " << i << " step " << step;
        }
      }
      // Each part's own contact (a contact probe: a bar a part).
      std::vector<SweepHit> ea(parts.size()), eb(parts.size());
      with.first_contacts(parts, m, ea, hint);
      without.first_contacts(parts, m, eb, hint);
      work.reused += with.counts().reused;
      work.rebuilt += with.counts().rebuilt;
      for (std::size_t j = 0; j < parts.size(); ++j) {
        ASSERT_EQ(ea[j].hit, eb[j].hit) << "tool " << i << " step " << step << " part " << j;
        if (!ea[j].hit) continue;
        ++work.part_hits;
        EXPECT_NEAR(ea[j].t, eb[j].t, 1e-12) << "tool " << i << " step " << step << " part " << j;
      }
    }
    if (::testing::Test::HasFailure()) return;
  }
}

// On the Truck (large, round Gaussians) and on a fidelity cube's top face and edges (flat discs
// at 4 mm, where the clearances are tight). The reuse must show: lists built, and most sweeps
// served by them.
TEST(SweepBounds, NearListsGiveTheBvhsContacts) {
  std::vector<std::pair<std::string, NearListWork>> runs;
  if (truck() != nullptr) {
    std::vector<Eigen::Vector3d> centres;
    double r = 0;
    for (const ToolEllipsoid& t : truck_poses(8, 21)) centres.push_back(t.center), r = std::max(r, t.semi_axes.maxCoeff());
    NearListWork work;
    expect_near_lists_give_the_bvhs_contacts(*truck(), centres, r, 4, work);
    runs.emplace_back("truck", work);
  }
  {
    SynthParams sp;
    sp.spacing = 0.004;
    const CollisionWorld w = CollisionWorld::build(make_synthetic_scene(AnalyticShape(ShapeKind::kCube), sp).scene, WorldConfig{});
    std::mt19937_64 rng(8);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<Eigen::Vector3d> centres;
    for (int i = 0; i < 16; ++i) centres.emplace_back(0.1 * u(rng), 0.1 * u(rng), 0.1 + 0.012 + 0.004 * u(rng));
    NearListWork work;
    expect_near_lists_give_the_bvhs_contacts(w, centres, 0.01, 5, work);
    runs.emplace_back("cube", work);
  }
  for (const auto& [name, work] : runs) {
    EXPECT_GT(work.hits, 60u) << name;
    EXPECT_GT(work.part_hits, work.hits) << name;
    EXPECT_GT(work.rebuilt, 20u) << name;              // built after jumps, turns and drifts
    EXPECT_GT(work.reused, 2 * work.sweeps) << name;  // most parts of most sweeps served by their lists
    RecordProperty(name + "_reused_parts", std::to_string(work.reused));
    RecordProperty(name + "_rebuilt", std::to_string(work.rebuilt));
    RecordProperty(name + "_hits", std::to_string(work.hits));
  }
}

// A part's list follows its drift and its motion: a part (a stylus-like part lying flat, whose
// core is its axis, or a ball, whose core is its centre) 0.4 margins above a layer of flat discs
// builds its list there (a short sweep with a hint, no contact), drifts 0.2 margins down (its
// list still fits) and sweeps 0.3 margins down: it touches 2/3 of the way, a disc that was
// beyond its list's reach where the list was built. The list serves that sweep and gives the
// BVH's contact, both as the shared bar and per part; a list that left out the drift or the
// motion would miss it.
TEST(SweepBounds, NearListsFollowTheirPartsDriftAndMotion) {
  // Discs of radius 1 mm and half-thickness 0.05 mm, 4 mm apart: only those right under the
  // part's lowest line are touched first.
  std::vector<test::GaussianSpec> gs;
  for (float x = -0.1f; x <= 0.1f; x += 0.004f)
    for (float y = -0.1f; y <= 0.1f; y += 0.004f)
      gs.emplace_back(Eigen::Vector3f(x, y, 0), Eigen::Vector3f(0.001f, 0.001f, 0.00005f), Eigen::Quaternionf::Identity());
  const CollisionWorld w = test::world_of(gs);
  const double margin = 0.005, thick = w.gaussians()[0].semi_axes[2];
  for (const Eigen::Vector3d& axes : {Eigen::Vector3d(0.03, 0.005, 0.005), Eigen::Vector3d(0.005, 0.005, 0.005)}) {
    for (const bool per_part : {false, true}) {
      ToolEllipsoid part;
      part.semi_axes = axes;
      part.center = Eigen::Vector3d(0.0005, 0, thick + axes.z() + 0.4 * margin);
      SweepQuery with(w, 4096, margin), without(w);
      const std::uint32_t hint = 0;
      const auto sweep = [&](SweepQuery& q, const Eigen::Vector3d& m) {
        SweepHit h;
        if (per_part) q.first_contacts({&part, 1}, m, {&h, 1}, {&hint, 1});
        else h = q.first_contact({&part, 1}, m, {}, {&hint, 1});
        return h;
      };
      EXPECT_FALSE(sweep(with, Eigen::Vector3d(0, 0, -0.1 * margin)).hit);
      EXPECT_EQ(with.counts().rebuilt, 1u);
      part.center.z() -= 0.2 * margin;
      const Eigen::Vector3d m(0, 0, -0.3 * margin);
      const SweepHit a = sweep(with, m), b = sweep(without, m);
      EXPECT_EQ(with.counts().reused, 1u) << "the list served the sweep";
      EXPECT_EQ(with.counts().rebuilt, 0u);
      ASSERT_TRUE(b.hit);
      EXPECT_NEAR(b.t, 2.0 / 3.0, 0.01);  // (the part's curvature over the disc's 0.5 mm offset)
      ASSERT_TRUE(a.hit) << "axes " << axes.transpose() << (per_part ? " per part" : "");
      EXPECT_NEAR(a.t, b.t, 1e-12);
    }
  }
}

TEST(SweepBounds, FidelityScenesMatchThePlainComputation) {
  for (const ShapeKind kind : {ShapeKind::kCube, ShapeKind::kSphere}) {
    const AnalyticShape shape(kind);
    SynthParams sp;
    sp.spacing = 0.008;
    sp.floater_share = 0.05;
    const CollisionWorld w = CollisionWorld::build(make_synthetic_scene(shape, sp).scene, WorldConfig{});
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    const int hits = expect_same_first_contacts(w, 150, [&](int i) {
      // Near the top face / top of the sphere (both 0.1 m up), across the cube's edges.
      const double r = i % 3 == 0 ? 0.010 : 0.005;
      const Eigen::Vector3d c(0.1 * u(rng), 0.1 * u(rng), 0.1 + r + 0.01 * u(rng));
      const Eigen::Vector3d m = Eigen::Vector3d(u(rng), u(rng), u(rng) - 0.5) * 0.02;
      return std::pair(ToolEllipsoid::sphere(c, r), m);
    });
    EXPECT_GT(hits, 60) << to_string(kind);
  }
}

TEST(ShadingScratch, TruckReadingsAreBitIdenticalToThePlainTwoPassOnes) {
  if (truck() == nullptr) GTEST_SKIP() << "the bundled truck.splat was not found";
  const CollisionWorld& w = *truck();
  const std::vector<ToolEllipsoid> tools = truck_poses(40, 5);
  ShadingScratch roomy;         // holds every reading here
  ShadingScratch tight(16);     // overflows: the plain second pass
  int overflowed = 0, held = 0, nonzero = 0;
  for (const ToolEllipsoid& t : tools) {
    for (const double kernel : {0.25, 0.5}) {
      const double r = t.semi_axes.maxCoeff();
      const Eigen::Vector3d plain = shaded_normal(w, t.center, r, kernel);
      const Eigen::Vector3d a = shaded_normal(w, t.center, r, kernel, roomy);
      const Eigen::Vector3d b = shaded_normal(w, t.center, r, kernel, tight);
      // Bitwise: the same terms summed in the same order.
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(a[k], plain[k]);
        EXPECT_EQ(b[k], plain[k]);
      }
      held += !roomy.last_overflow() && roomy.last_terms() > 16;
      overflowed += tight.last_overflow();
      nonzero += plain.squaredNorm() > 0;
    }
  }
  EXPECT_GT(held, 10);        // the one-traversal path ran with real neighbourhoods
  EXPECT_GT(overflowed, 10);  // and the fallback too
  EXPECT_GT(nonzero, 40);
}

}  // namespace
}  // namespace gshaptics
