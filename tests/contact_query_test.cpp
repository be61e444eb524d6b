// The whole collision query against the independent float64 brute-force reference on real
// scenes: identical contact sets except grazing pairs (|K_min| < 1e-5), K_min within 1e-5.

#include "gshaptics/collision/contact_query.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <cstring>
#include <random>

#include "gshaptics/io/scene_loader.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/sim/pose_sampler.h"
#include "gshaptics/sim/probe_run.h"
#include "gshaptics/sim/probe_trajectory.h"
#include "support/reference.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

constexpr double kTolerance = 1e-5;

struct Case {
  const char* scene;
  bool bundled_registration;
  double tool_min, tool_max;  // tool radius as a fraction of the scene's robust extent
  int poses;
};
void PrintTo(const Case& c, std::ostream* os) { *os << c.scene << " (" << c.poses << " poses)"; }

// Poses: half near the surface (within a tool radius of a kept Gaussian), half anywhere in the
// world's 1-99 percentile box; tools are ellipsoids with axis ratios down to 1/3, any orientation.
std::vector<ToolEllipsoid> make_poses(const CollisionWorld& w, const Case& c, std::uint64_t seed) {
  PoseSamplerParams p;
  p.count = std::size_t(c.poses / 2);
  p.seed = seed;
  p.radius_min = c.tool_min;
  p.radius_max = c.tool_max;
  p.anisotropic = true;
  std::vector<ToolEllipsoid> poses = sample_poses(w, p);
  p.near_surface = false;
  p.count = std::size_t(c.poses) - poses.size();
  for (const ToolEllipsoid& t : sample_poses(w, p)) poses.push_back(t);
  return poses;
}

// Compares one fast result with the reference; returns the number of contacts compared.
std::size_t expect_same_contacts(const std::vector<test::RefGaussian>& ref_world,
                                 const ToolEllipsoid& tool, const ContactSet& fast,
                                 const std::string& what) {
  const std::vector<test::RefContact> ref = test::reference_contacts(ref_world, tool);
  std::map<std::uint32_t, double> fast_k;
  for (const Contact& c : fast.contacts()) fast_k[c.index] = c.k_min;
  EXPECT_EQ(fast.counts.contacts, fast.contacts().size());
  EXPECT_LE(fast.counts.contacts, fast.counts.prefiltered);
  EXPECT_LE(fast.counts.prefiltered, fast.counts.candidates);
  for (const auto& r : ref) {
    const auto it = fast_k.find(r.index);
    if (it == fast_k.end()) {
      EXPECT_LT(r.k_min, kTolerance) << what << ": missed contact " << r.index << " K_min " << r.k_min;
      continue;
    }
    EXPECT_NEAR(it->second, r.k_min, kTolerance) << what << ": index " << r.index;
    fast_k.erase(it);
  }
  for (const auto& [index, k] : fast_k) {  // reported by us, not by the reference
    const double rk = test::reference_k_min_of(ref_world, tool, index);
    EXPECT_LT(std::fabs(rk), kTolerance) << what << ": extra contact " << index << " ref K_min " << rk;
  }
  return ref.size();
}

class AgainstReference : public ::testing::TestWithParam<Case> {};

TEST_P(AgainstReference, SameContactsAsBruteForceFloat64) {
  const Case& c = GetParam();
  if (std::string(c.scene) != "truck.splat") GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene s = load_scene(test::scene_path(c.scene));
  WorldConfig cfg;
  if (c.bundled_registration) cfg.registration = load_registration_file(test::data_path("truck.registration.json"));
  const CollisionWorld world = CollisionWorld::build(s.scene, cfg);
  const auto ref_world = test::reference_world(s.scene, cfg.min_opacity, cfg.sigma, cfg.registration);
  ASSERT_EQ(ref_world.size(), world.size());
  ContactQuery query(world);
  std::size_t total = 0, max_contacts = 0;
  for (const ToolEllipsoid& tool : make_poses(world, c, 17)) {
    ASSERT_EQ(query.run(tool), QueryStatus::kOk);
    const std::size_t n = expect_same_contacts(ref_world, tool, query.result(), c.scene);
    total += n;
    max_contacts = std::max(max_contacts, n);
  }
  EXPECT_GT(total, std::size_t(c.poses));  // the poses really touch things
  RecordProperty("reference_contacts", std::to_string(total));
  RecordProperty("max_contacts_per_pose", std::to_string(max_contacts));
}

INSTANTIATE_TEST_SUITE_P(
    RealScenes, AgainstReference,
    ::testing::Values(Case{"truck.splat", true, 0.01, 0.02, 60},
                      Case{"donut.ply", false, 0.02, 0.06, 60},
                      Case{"burger.splat", false, 0.01, 0.03, 40},
                      Case{"karangkidul_crop.ply", false, 0.005, 0.015, 24}),
    [](const auto& param_info) {
      std::string n = param_info.param.scene;
      return n.substr(0, n.find('.'));
    });

// The same scene moved 1e4 units away and rotated, with the poses moved alike, gives the same
// contacts: nothing in the query depends on absolute coordinates.
TEST(ContactQuery, TranslatedAndRotatedSceneGivesSameContacts) {
  const LoadedScene s = load_scene(test::scene_path("truck.splat"));
  WorldConfig base;
  const CollisionWorld w0 = CollisionWorld::build(s.scene, base);
  WorldConfig moved;
  moved.registration.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()));
  moved.registration.translation = Eigen::Vector3d(1e4, -1e4, 5e3);
  const CollisionWorld w1 = CollisionWorld::build(s.scene, moved);
  const auto ref1 = test::reference_world(s.scene, moved.min_opacity, moved.sigma, moved.registration);
  ContactQuery q0(w0), q1(w1);
  std::size_t compared = 0;
  for (ToolEllipsoid t : make_poses(w0, {"truck.splat", false, 0.01, 0.02, 40}, 23)) {
    ASSERT_EQ(q0.run(t), QueryStatus::kOk);
    ToolEllipsoid u = t;
    u.center = moved.registration.apply(t.center);
    u.rotation = moved.registration.rotation * t.rotation;
    ASSERT_EQ(q1.run(u), QueryStatus::kOk);
    std::map<std::uint32_t, double> a, b;
    for (const Contact& c : q0.result().contacts()) a[c.index] = c.k_min;
    for (const Contact& c : q1.result().contacts()) b[c.index] = c.k_min;
    for (const auto& [i, k] : a) {
      if (!b.count(i)) {
        EXPECT_LT(k, kTolerance) << "lost " << i;
        continue;
      }
      EXPECT_NEAR(b[i], k, kTolerance);
      ++compared;
    }
    for (const auto& [i, k] : b) {
      if (!a.count(i)) {
        EXPECT_LT(k, kTolerance) << "gained " << i;
      }
    }
    // and the far-away copy still matches its own float64 reference
    expect_same_contacts(ref1, u, q1.result(), "moved truck");
  }
  EXPECT_GT(compared, 100u);
}

// Regression: on these poses flat splats (thin axis ~1e-7 of the tool) started the float Newton
// search on a plateau where float second derivatives are noise, and it stopped there with K_min
// off by 2e-3. Spherical tools, the first 40 poses of gshaptics_bench's karangkidul set.
TEST(ContactQuery, FlatSplatPlateausStillGiveExactKMin) {
  GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene s = load_scene(test::scene_path("karangkidul_crop.ply"));
  const CollisionWorld world = CollisionWorld::build(s.scene, {});
  const auto ref_world = test::reference_world(s.scene, kDefaultMinOpacity, 1.0, {});
  const std::vector<ToolEllipsoid> poses =
      sample_poses(world, {.count = 2000, .radius_min = 0.005, .radius_max = 0.015});
  ContactQuery query(world);
  for (std::size_t i = 0; i < 40; ++i) {
    ASSERT_EQ(query.run(poses[i]), QueryStatus::kOk);
    expect_same_contacts(ref_world, poses[i], query.result(), "karangkidul pose " + std::to_string(i));
  }
}

TEST(ContactQuery, InvalidToolAndOverflowAreReportedNotThrown) {
  GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene s = load_scene(test::scene_path("donut.ply"));
  const CollisionWorld world = CollisionWorld::build(s.scene, {});
  ContactQuery q(world);
  ToolEllipsoid bad = ToolEllipsoid::sphere(Eigen::Vector3d(NAN, 0, 0), 0.01);
  EXPECT_EQ(q.run(bad), QueryStatus::kInvalidTool);
  EXPECT_EQ(q.result().counts.candidates, 0u);
  EXPECT_EQ(q.run(ToolEllipsoid::sphere(Eigen::Vector3d::Zero(), -1)), QueryStatus::kInvalidTool);

  QueryOptions small;
  small.max_contacts = 3;
  ContactQuery tiny(world, small);
  EXPECT_EQ(tiny.run(ToolEllipsoid::sphere(Eigen::Vector3d(0, 0, 0.04), 0.05)), QueryStatus::kContactOverflow);
  EXPECT_EQ(tiny.result().contacts().size(), 3u);
  EXPECT_GT(tiny.result().counts.contacts, 3u);  // the count still says how many there were
}

TEST(ContactQuery, GoldenSectionOptionAgreesOnContacts) {
  GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene s = load_scene(test::scene_path("donut.ply"));
  const CollisionWorld world = CollisionWorld::build(s.scene, {});
  QueryOptions golden;
  golden.narrow_phase = {Minimiser::kGoldenSection, 30, false};
  ContactQuery qn(world), qg(world, golden);
  std::size_t differ = 0, total = 0;
  for (const ToolEllipsoid& t : make_poses(world, {"donut.ply", false, 0.02, 0.05, 30}, 5)) {
    qn.run(t);
    qg.run(t);
    std::map<std::uint32_t, double> a;
    for (const Contact& c : qn.result().contacts()) a[c.index] = c.k_min;
    for (const Contact& c : qg.result().contacts()) {
      ++total;
      if (!a.count(c.index)) { ++differ; continue; }
      // Golden section never goes below the true minimum; the batched Newton value is within
      // ~1e-7 of it (float iterations, double evaluation).
      EXPECT_GE(c.k_min, a[c.index] - 1e-6);
    }
  }
  EXPECT_GT(total, 100u);
  EXPECT_LE(differ, total / 100);  // 30 golden steps can call a few grazing pairs wrongly
}

}  // namespace
}  // namespace gshaptics

namespace gshaptics {
namespace {

// The candidate cache must not change a single bit: same contacts (index, slot, opacity, K_min,
// centre) in the same order, same counts and status, whatever the sequence of tools.
void expect_bit_identical(const ContactSet& a, const ContactSet& b, const std::string& what) {
  ASSERT_EQ(a.contacts().size(), b.contacts().size()) << what;
  EXPECT_EQ(a.counts.candidates, b.counts.candidates) << what;
  EXPECT_EQ(a.counts.prefiltered, b.counts.prefiltered) << what;
  EXPECT_EQ(a.counts.contacts, b.counts.contacts) << what;
  for (std::size_t i = 0; i < a.contacts().size(); ++i) {
    const Contact& x = a.contacts()[i];
    const Contact& y = b.contacts()[i];
    ASSERT_EQ(x.index, y.index) << what << " #" << i;
    EXPECT_EQ(x.slot, y.slot) << what;
    EXPECT_EQ(x.opacity, y.opacity) << what;
    EXPECT_EQ(std::memcmp(&x.k_min, &y.k_min, sizeof(double)), 0) << what << ": K_min " << x.k_min << " vs " << y.k_min;
    EXPECT_EQ(x.center, y.center) << what;
  }
}

// Runs a tool sequence through a plain and a cached query; returns the cache's statistics.
CandidateCacheStats run_both(const CollisionWorld& world, const std::vector<ToolEllipsoid>& tools, double margin,
                             const std::string& what) {
  ContactQuery plain(world);
  QueryOptions o;
  o.cache_margin = margin;
  ContactQuery cached(world, o);
  for (std::size_t i = 0; i < tools.size(); ++i) {
    const QueryStatus sp = plain.run(tools[i]);
    const QueryStatus sc = cached.run(tools[i]);
    EXPECT_EQ(sp, sc) << what << " tick " << i;
    expect_bit_identical(plain.result(), cached.result(), what + " tick " + std::to_string(i));
    if (::testing::Test::HasFailure()) break;
  }
  return cached.cache_stats();
}

TEST(CandidateCache, ReplayedProbeTrajectoryIsBitIdenticalAndMostlyHits) {
  const CollisionWorld& world = test::truck_world();
  ProbeParams pp;
  pp.tool_radius = 0.01 * robust_extent(world);
  pp.approach_speed = 2 * pp.tool_radius;
  pp.travel_speed = 8 * pp.tool_radius;
  pp.sites = 3;
  const ProbeTrajectory traj = generate_probe_trajectory(world, pp);
  const ProbeRunResult run = run_probe(world, traj, {});
  std::vector<ToolEllipsoid> tools;
  for (const TickRecord& r : run.ticks) tools.push_back(ToolEllipsoid::sphere(r.position, pp.tool_radius));
  ASSERT_GT(tools.size(), 1000u);
  const CandidateCacheStats s = run_both(world, tools, 0.25 * pp.tool_radius, "truck probe");
  EXPECT_EQ(s.hits + s.refills, tools.size());
  EXPECT_GT(double(s.hits), 0.8 * double(tools.size()));  // 1 kHz ticks move far less than the margin
}

TEST(CandidateCache, RandomJumpsAndShapesLeavingTheMarginAreBitIdentical) {
  const CollisionWorld& world = test::truck_world();
  // A random walk with small steps, large jumps, and changes of tool shape and orientation.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  const std::vector<ToolEllipsoid> anchors = sample_poses(world, {.count = 200, .seed = 3, .anisotropic = true});
  std::vector<ToolEllipsoid> tools;
  for (const ToolEllipsoid& a : anchors) {
    ToolEllipsoid t = a;
    for (int k = 0; k < 10; ++k) {  // small moves around the anchor, some beyond the margin
      t.center += Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.2 * a.semi_axes.maxCoeff();
      if (k == 5) t.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(u(rng) * 3, Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()));
      if (k == 7) t.semi_axes *= 0.6;
      tools.push_back(t);
    }
  }
  const CandidateCacheStats s = run_both(world, tools, 0.1 * anchors[0].semi_axes.maxCoeff(), "truck walk");
  EXPECT_GT(s.hits, 0u);
  EXPECT_GT(s.refills, anchors.size());  // every jump to a new anchor refilled
}

// Level-order and depth-first traversals give the same contacts, K_min and order to the last
// bit, plain and cached, on both real scenes; tools up to 20x larger overflow the level scratch
// and finish depth first.
TEST(ContactQuery, LevelOrderAndDepthFirstTraversalsAreBitIdentical) {
  GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene s = load_scene(test::scene_path("karangkidul_crop.ply"));
  const CollisionWorld crop = CollisionWorld::build(s.scene, {});
  for (const CollisionWorld* world : {&test::truck_world(), &crop}) {
    const bool is_truck = world == &test::truck_world();
    PoseSamplerParams p;
    p.count = 150;
    p.seed = 5;
    p.anisotropic = true;
    p.radius_min = is_truck ? 0.01 : 0.005;
    p.radius_max = is_truck ? 0.02 : 0.015;
    std::vector<ToolEllipsoid> tools = sample_poses(*world, p);
    for (std::size_t i = 0; i < 30; ++i) {  // big tools: thousands of leaves
      ToolEllipsoid t = tools[i];
      t.semi_axes *= 2.0 + double(i) * 0.6;
      tools.push_back(t);
    }
    for (const double margin : {0.0, 0.1 * tools[0].semi_axes.maxCoeff()}) {
      QueryOptions depth_first, level_order;
      depth_first.traversal = Traversal::kDepthFirst;
      level_order.traversal = Traversal::kLevelOrder;
      depth_first.cache_margin = level_order.cache_margin = margin;
      ContactQuery a(*world, depth_first), b(*world, level_order);
      ASSERT_FALSE(a.level_order());
      ASSERT_TRUE(b.level_order());
      std::uint64_t leaves_max = 0;
      for (std::size_t i = 0; i < tools.size(); ++i) {
        EXPECT_EQ(a.run(tools[i]), b.run(tools[i]));
        expect_bit_identical(a.result(), b.result(), std::string(is_truck ? "truck" : "crop") + " pose " + std::to_string(i));
        leaves_max = std::max<std::uint64_t>(leaves_max, a.result().counts.candidates / 8);
        if (::testing::Test::HasFailure()) return;
      }
      EXPECT_GT(leaves_max, 2048u);  // some query overflowed the level scratch (2 x 2048)
    }
  }
}

TEST(ContactQuery, AutomaticTraversalFollowsTheL2Cache) {
  const CollisionWorld& world = test::truck_world();
  ContactQuery q(world);
  EXPECT_EQ(q.level_order(), world.bvh().nodes().size_bytes() > l2_cache_bytes());
  EXPECT_GE(l2_cache_bytes(), 1024u);
}

TEST(CandidateCache, RealSceneAndATinyCacheThatOverflows) {
  GSHAPTICS_REQUIRE_SCENES();
  const LoadedScene s = load_scene(test::scene_path("karangkidul_crop.ply"));
  const CollisionWorld world = CollisionWorld::build(s.scene, {});
  std::vector<ToolEllipsoid> tools;
  for (const ToolEllipsoid& a : sample_poses(world, {.count = 300, .seed = 11, .radius_min = 0.005, .radius_max = 0.015}))
    for (int k = 0; k < 5; ++k) tools.push_back(ToolEllipsoid::sphere(a.center + Eigen::Vector3d(0, 0, 0.02 * k * a.semi_axes.x()), a.semi_axes.x()));
  const CandidateCacheStats big = run_both(world, tools, 0.1 * tools[0].semi_axes.x(), "karangkidul_crop");
  EXPECT_GT(big.hits, 0u);
  // A cache of 2 leaves overflows on almost every refill and falls back to the traversal.
  ContactQuery plain(world);
  QueryOptions o;
  o.cache_margin = 0.1 * tools[0].semi_axes.x();
  o.cache_leaves = 2;
  ContactQuery tiny(world, o);
  for (std::size_t i = 0; i < 200; ++i) {
    plain.run(tools[i]);
    tiny.run(tools[i]);
    expect_bit_identical(plain.result(), tiny.result(), "tiny cache tick " + std::to_string(i));
  }
  EXPECT_GT(tiny.cache_stats().overflows, 0u);
}

// The narrow phase's batches do not depend on the BVH's leaf size: a world whose leaves are
// larger than a batch (~420 records > kBatchCapacity, so each leaf is split across batches) gives the same
// contacts, each with the same K_min to the last bit, as the default world (in another order:
// the records are ordered by another BVH). And any_contact() agrees with run() on both.
TEST(ContactQuery, LeavesLargerThanABatchAndAnyContactAgree) {
  const LoadedScene s = load_scene(test::data_path("truck.splat"));
  WorldConfig config;
  config.registration = load_registration_file(test::data_path("truck.registration.json"));
  const CollisionWorld small = CollisionWorld::build(s.scene, config);
  config.leaf_size = 600;  // Truck: leaves of ~420 records, each split over two batches
  const CollisionWorld big = CollisionWorld::build(s.scene, config);
  ASSERT_GT(config.leaf_size, kBatchCapacity);
  ContactQuery qs(small), qb(big);
  std::size_t contacts = 0, free_poses = 0;
  for (const ToolEllipsoid& t :
       sample_poses(small, {.count = 150, .seed = 19, .radius_min = 0.01, .radius_max = 0.04, .anisotropic = true})) {
    qs.run(t);
    qb.run(t);
    ASSERT_EQ(qs.result().contacts().size(), qb.result().contacts().size());
    std::map<std::uint32_t, double> k_small;
    for (const Contact& c : qs.result().contacts()) k_small[c.index] = c.k_min;
    for (const Contact& c : qb.result().contacts()) {
      ASSERT_EQ(k_small.count(c.index), 1u) << "Gaussian " << c.index;
      ASSERT_EQ(std::memcmp(&k_small[c.index], &c.k_min, sizeof(double)), 0) << "Gaussian " << c.index;
    }
    // (The candidate and pre-filter counts differ: larger leaves hand over more candidates.)
    const bool any = !qs.result().contacts().empty();
    EXPECT_EQ(qs.any_contact(t), any);
    EXPECT_EQ(qb.any_contact(t), any);
    contacts += qs.result().contacts().size();
    free_poses += any ? 0 : 1;
  }
  EXPECT_GT(contacts, 10000u);  // large queries: many batches per query
  // The near-surface poses are mostly in contact; lift a few clear of everything for the
  // "free" answer.
  const Eigen::Vector3d above = small.bounds_hi() + Eigen::Vector3d::Constant(1.0);
  const ToolEllipsoid clear = ToolEllipsoid::sphere(above, 0.05);
  EXPECT_FALSE(qs.any_contact(clear));
  EXPECT_FALSE(qb.any_contact(clear));
}

// first_overlaps() lists the Gaussians run() reports, in the same (BVH) order, and stops once
// its span is full: with room for all it lists exactly run()'s slots; with room for k it lists
// the first k of them.
TEST(ContactQuery, FirstOverlapsListsRunsContactsUntilFull) {
  const LoadedScene s = load_scene(test::data_path("truck.splat"));
  WorldConfig config;
  config.registration = load_registration_file(test::data_path("truck.registration.json"));
  const CollisionWorld w = CollisionWorld::build(s.scene, config);
  ContactQuery q(w), listing(w);
  std::vector<std::uint32_t> slots(4096);
  std::size_t checked = 0;
  for (const ToolEllipsoid& t :
       sample_poses(w, {.count = 80, .seed = 23, .radius_min = 0.005, .radius_max = 0.03, .anisotropic = true})) {
    q.run(t);
    const std::span<const Contact> all = q.result().contacts();
    ASSERT_LT(all.size(), slots.size());
    const std::size_t n = listing.first_overlaps(t, slots);
    ASSERT_EQ(n, all.size());
    for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(slots[i], all[i].slot) << i;
    for (const std::size_t room : {std::size_t(1), std::size_t(3)}) {
      const std::size_t k = listing.first_overlaps(t, {slots.data(), room});
      ASSERT_EQ(k, std::min(room, all.size()));
      for (std::size_t i = 0; i < k; ++i) ASSERT_EQ(slots[i], all[i].slot) << i;
    }
    checked += all.size() > 3;
  }
  EXPECT_GT(checked, 20u);
  const ToolEllipsoid clear = ToolEllipsoid::sphere(w.bounds_hi() + Eigen::Vector3d::Constant(1.0), 0.05);
  EXPECT_EQ(listing.first_overlaps(clear, slots), 0u);
}

}  // namespace
}  // namespace gshaptics

#include "gshaptics/servo/query_pool.h"

namespace gshaptics {
namespace {

TEST(QueryPool, EveryTaskRunsOncePerRun) {
  for (int threads : {1, 2, 3}) {
    for (int spin_us : {0, 100}) {  // sleeping workers (woken every run) and spinning ones
      QueryPool pool(threads, {}, spin_us);
      for (int tasks : {1, 2, 5, 17}) {
        std::vector<std::atomic<int>> hits(static_cast<std::size_t>(tasks));
        for (int r = 0; r < 300; ++r)
          pool.run([](void* ctx, int t) { (*static_cast<std::vector<std::atomic<int>>*>(ctx))[std::size_t(t)]++; },
                   &hits, tasks);
        for (int t = 0; t < tasks; ++t)
          EXPECT_EQ(hits[std::size_t(t)].load(), 300) << threads << " threads, " << tasks << " tasks, task " << t;
      }
    }
  }
  EXPECT_EQ(default_query_threads(2), 1);
  EXPECT_EQ(default_query_threads(4), 2);
  EXPECT_EQ(default_query_threads(8), 4);
  EXPECT_EQ(default_query_threads(16), 4);
}

// A pool used and destroyed before its worker threads got to run: the workers must still see
// the jobs and the stop as new (a worker that took the stop for the state it started in would
// sleep forever and the destructor would hang; this failed 3 times in 4 before the fix).
TEST(QueryPool, DestroyedBeforeItsWorkersStart) {
  std::atomic<int> hits{0};
  for (int i = 0; i < 100; ++i) {
    QueryPool pool(3, {}, /*spin_us=*/0);
    pool.run([](void* ctx, int) { ++*static_cast<std::atomic<int>*>(ctx); }, &hits, 5);
  }
  EXPECT_EQ(hits.load(), 500);
}

TEST(ParallelNarrowPhase, ThreadedQueriesAreBitIdentical) {
  const CollisionWorld& world = test::truck_world();
  const std::vector<ToolEllipsoid> tools =  // radii up to 5 %: up to thousands of contacts
      sample_poses(world, {.count = 150, .seed = 5, .radius_min = 0.01, .radius_max = 0.05, .anisotropic = true});
  for (int parts : {2, 3}) {
    QueryPool pool(parts);
    ContactQuery plain(world), threaded(world);
    threaded.set_executor(&pool, /*min_candidates=*/0);
    for (std::size_t i = 0; i < tools.size(); ++i) {
      EXPECT_EQ(plain.run(tools[i]), threaded.run(tools[i]));
      expect_bit_identical(plain.result(), threaded.result(), std::to_string(parts) + " parts, pose " + std::to_string(i));
      if (::testing::Test::HasFailure()) return;
    }
    EXPECT_GT(threaded.parallel_queries(), tools.size() / 2);
    // With the candidate cache too, on a walk.
    QueryOptions o;
    o.cache_margin = 0.02;
    ContactQuery both(world, o);
    both.set_executor(&pool, 0);
    for (std::size_t i = 0; i < tools.size(); ++i) {
      ToolEllipsoid t = tools[i / 3];
      t.center.x() += 0.005 * double(i % 3);
      plain.run(t);
      both.run(t);
      expect_bit_identical(plain.result(), both.result(), "cache + threads " + std::to_string(i));
      if (::testing::Test::HasFailure()) return;
    }
  }
}

// A full contact set keeps the first contacts in order, plain or threaded, and says so; the
// count still says how many there were. Both append a batch's contacts at once.
TEST(ParallelNarrowPhase, OverflowKeepsTheFirstContactsInOrder) {
  const CollisionWorld& world = test::truck_world();
  const std::vector<ToolEllipsoid> tools =
      sample_poses(world, {.count = 60, .seed = 9, .radius_min = 0.02, .radius_max = 0.05});
  QueryPool pool(2);
  ContactQuery full(world);
  int overflowed = 0;
  for (std::size_t cap : {std::size_t(1), std::size_t(100), std::size_t(1000)}) {
    QueryOptions o;
    o.max_contacts = cap;
    ContactQuery plain(world, o), threaded(world, o);
    threaded.set_executor(&pool, /*min_candidates=*/0);
    for (std::size_t i = 0; i < tools.size(); ++i) {
      full.run(tools[i]);
      const std::size_t n = full.result().contacts().size();
      for (ContactQuery* q : {&plain, &threaded}) {
        const QueryStatus st = q->run(tools[i]);
        const std::span<const Contact> got = q->result().contacts();
        EXPECT_EQ(st, n > cap ? QueryStatus::kContactOverflow : QueryStatus::kOk) << "pose " << i;
        ASSERT_EQ(got.size(), std::min(n, cap)) << "pose " << i;
        EXPECT_EQ(q->result().counts.contacts, full.result().counts.contacts);
        for (std::size_t j = 0; j < got.size(); ++j) {
          ASSERT_EQ(got[j].slot, full.result().contacts()[j].slot) << "pose " << i << " contact " << j;
          ASSERT_EQ(got[j].k_min, full.result().contacts()[j].k_min) << "pose " << i << " contact " << j;
        }
        overflowed += n > cap ? 1 : 0;
      }
    }
  }
  EXPECT_GT(overflowed, 20);  // the poses really overflowed the smaller sets
}

}  // namespace
}  // namespace gshaptics
