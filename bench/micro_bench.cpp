// Google Benchmark microbenchmarks of the collision query's stages on real scenes:
// narrow phase per pair (scalar and 8-lane batch), broad phase per query, whole query per pose.
// Run: build/bench/gshaptics_micro_bench [--benchmark_filter=...]

#include <benchmark/benchmark.h>

#include <algorithm>
#include <limits>
#include <map>
#include <memory>
#include <random>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/collision/sweep_query.h"
#include "gshaptics/force/force_model.h"
#include "gshaptics/force/support_normal.h"
#include "gshaptics/servo/passivity.h"
#include "gshaptics/servo/query_pool.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/narrowphase/k_min_batch.h"
#include "gshaptics/sim/pose_sampler.h"

namespace gshaptics {
namespace {

struct Fixture {
  std::unique_ptr<CollisionWorld> world;
  std::vector<ToolEllipsoid> poses;
};

// Loads a scene once per process; tool radius as a fraction of the robust extent.
const Fixture& fixture(const std::string& name, double rmin, double rmax) {
  static std::map<std::string, Fixture> cache;
  auto it = cache.find(name);
  if (it != cache.end()) return it->second;
  const std::string dir = name == "truck.splat" ? GSHAPTICS_DATA_DIR : GSHAPTICS_SCENES_DIR;
  const LoadedScene s = load_scene(dir + "/" + name);
  WorldConfig cfg;
  if (name == "truck.splat") cfg.registration = load_registration_file(std::string(GSHAPTICS_DATA_DIR) + "/truck.registration.json");
  Fixture f;
  f.world = std::make_unique<CollisionWorld>(CollisionWorld::build(s.scene, cfg));
  PoseSamplerParams p;
  p.count = 2000;
  p.radius_min = rmin;
  p.radius_max = rmax;
  f.poses = sample_poses(*f.world, p);
  return cache.emplace(name, std::move(f)).first->second;
}

// Prefiltered pairs of real near-surface queries, for the narrow-phase benchmarks.
struct Pairs {
  std::vector<PairCoefficients> coeffs;
  std::vector<PairBatch> batches;
  BatchTool tool;
  double radius = 0;  ///< the spherical tool's radius
};

const Pairs& pairs() {
  static Pairs p = [] {
    Pairs out;
    const Fixture& f = fixture("karangkidul_crop.ply", 0.005, 0.015);
    const ToolEllipsoid& t0 = f.poses[0];
    out.tool = make_batch_tool(Eigen::Matrix3d::Identity(), t0.semi_axes);
    out.radius = t0.semi_axes.x();
    const ToolFrame frame = ToolFrame::from(Eigen::Matrix3d::Identity(), t0.semi_axes);
    PairBatch b{};
    for (std::size_t i = 0; i < 200 && out.coeffs.size() < 20000; ++i) {
      const ToolEllipsoid& t = f.poses[i];
      for (const auto& g : f.world->gaussians()) {
        const Eigen::Vector3d d(g.center[0] - t.center.x(), g.center[1] - t.center.y(), g.center[2] - t.center.z());
        const double reach = g.bounding_radius() + t0.semi_axes.x();
        if (d.squaredNorm() > reach * reach) continue;
        const Eigen::Vector3d s(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
        out.coeffs.push_back(pair_coefficients(frame, d, rotation_matrix(g), s));
        const int l = b.count++;
        b.dx[l] = d.x(); b.dy[l] = d.y(); b.dz[l] = d.z();
        for (int k = 0; k < 4; ++k) b.q[k][l] = g.quaternion[k];
        b.sx[l] = g.semi_axes[0]; b.sy[l] = g.semi_axes[1]; b.sz[l] = g.semi_axes[2];
        if (b.count == kBatchCapacity) { out.batches.push_back(b); b.count = 0; }
      }
    }
    return out;
  }();
  return p;
}

void BM_NarrowPhaseScalar(benchmark::State& state) {
  const Pairs& p = pairs();
  KMinOptions opt;
  opt.stop_when_separated = true;
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(k_min(p.coeffs[i], opt));
    if (++i == p.coeffs.size()) i = 0;
  }
  state.SetItemsProcessed(std::int64_t(state.iterations()));
}
BENCHMARK(BM_NarrowPhaseScalar);

void BM_NarrowPhaseBatch(benchmark::State& state) {
  Pairs p = pairs();
  std::size_t i = 0;
  for (auto _ : state) {
    k_min_batch(p.batches[i], p.tool, true);
    benchmark::DoNotOptimize(p.batches[i].k_min[0]);
    if (++i == p.batches.size()) i = 0;
  }
  state.SetItemsProcessed(std::int64_t(state.iterations()) * kBatchCapacity);
}
BENCHMARK(BM_NarrowPhaseBatch);

// The same pairs against an ellipsoidal tool (semi-axes 1, 0.7, 0.5 of the sphere's radius,
// turned): the general coefficient form, in the tool's frame (BM_NarrowPhaseBatch's spherical
// tool takes the Gaussian-frame form).
void BM_NarrowPhaseBatchEllipsoid(benchmark::State& state) {
  Pairs p = pairs();
  const Eigen::Vector3d a = p.radius * Eigen::Vector3d(1.0, 0.7, 0.5);
  const BatchTool tool =
      make_batch_tool(Eigen::AngleAxisd(0.6, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(), a);
  std::size_t i = 0;
  for (auto _ : state) {
    k_min_batch(p.batches[i], tool, true);
    benchmark::DoNotOptimize(p.batches[i].k_min[0]);
    if (++i == p.batches.size()) i = 0;
  }
  state.SetItemsProcessed(std::int64_t(state.iterations()) * kBatchCapacity);
}
BENCHMARK(BM_NarrowPhaseBatchEllipsoid);

// The proxy's exact first-contact search (sweep_time) for one tool-Gaussian pair: truck Gaussians
// near sampled tool poses, each tool moved a tool radius toward its Gaussian. Arg 0: a sphere;
// 1: an ellipsoidal tool (semi-axes 1, 0.7, 0.4 of the radius, turned). Arg 1 of the range: 0 cold
// (the full scan over lambda), 1 warm (started at the pair's last maximiser, as the sweep does
// from tick to tick).
void BM_SweepTime(benchmark::State& state) {
  const Fixture& f = fixture("truck.splat", 0.01, 0.02);
  std::mt19937_64 rng(4);
  struct Pair {
    std::uint32_t slot;
    ToolEllipsoid tool;
    Eigen::Vector3d motion;
    double s;
  };
  std::vector<Pair> pairs;
  const auto& gs = f.world->gaussians();
  for (const ToolEllipsoid& pose : f.poses) {
    if (pairs.size() == 512) break;
    ToolEllipsoid tool = pose;
    if (state.range(0) == 1) {
      tool.semi_axes = pose.semi_axes.maxCoeff() * Eigen::Vector3d(1.0, 0.7, 0.4);
      tool.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.6, Eigen::Vector3d(1, 2, 3).normalized()));
    }
    const std::uint32_t k = std::uint32_t(rng() % gs.size());
    const Eigen::Vector3d cg(gs[k].center[0], gs[k].center[1], gs[k].center[2]);
    const double r = tool.semi_axes.maxCoeff();
    tool.center = cg + (pose.center - cg).normalized() * (2.5 * r + gs[k].radius);
    pairs.push_back({k, tool, (cg - tool.center).normalized() * 2 * r, std::numeric_limits<double>::quiet_NaN()});
  }
  const bool warm = state.range(1) == 1;
  if (warm)
    for (Pair& p : pairs) (void)sweep_time(gs[p.slot], p.tool, p.motion, nullptr, 2.0, &p.s);
  std::size_t i = 0;
  for (auto _ : state) {
    Pair& p = pairs[i];
    Eigen::Vector3d n;
    double s = warm ? p.s : std::numeric_limits<double>::quiet_NaN();
    benchmark::DoNotOptimize(sweep_time(gs[p.slot], p.tool, p.motion, &n, 2.0, &s));
    if (++i == pairs.size()) i = 0;
  }
}
BENCHMARK(BM_SweepTime)->Args({0, 0})->Args({0, 1})->Args({1, 0})->Args({1, 1});

// The support normal at a convex edge (EdgeNormal's solve, support_normal.h): a sphere part of
// radius 5 mm resting on the edge of two faces of discs (semi-axes 4, 4, 0.2 mm at 4 mm spacing,
// their centres jittered), the solve started from one face's normal. Arg: the patch size (the
// discs nearest the part; EdgeNormal holds up to 256).
void BM_SupportNormal(benchmark::State& state) {
  const std::size_t n = std::size_t(state.range(0));
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> jitter(-2e-4, 2e-4);
  std::vector<PatchGaussian> all;
  const Eigen::Vector3d normals[2] = {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX()};
  for (int f = 0; f < 2; ++f) {
    const Eigen::Vector3d nf = normals[f], along = Eigen::Vector3d::UnitY();
    const Eigen::Vector3d across = f == 0 ? Eigen::Vector3d(-1, 0, 0) : Eigen::Vector3d(0, 0, -1);
    const Eigen::Matrix3d shape =
        (4e-3 * 4e-3) * (Eigen::Matrix3d::Identity() - nf * nf.transpose()) + (2e-4 * 2e-4) * nf * nf.transpose();
    for (int i = 0; i < 16; ++i)
      for (int j = -16; j < 16; ++j) {
        const Eigen::Vector3d c = across * (2e-3 + 4e-3 * i) + along * (4e-3 * j) +
                                  Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
        all.push_back({c, shape, 0.9});
      }
  }
  ToolEllipsoid part = ToolEllipsoid::sphere(Eigen::Vector3d(1.0, 0, 1.0).normalized() * 5.3e-3, 5e-3);
  std::sort(all.begin(), all.end(), [&](const PatchGaussian& a, const PatchGaussian& b) {
    return (a.center - part.center).squaredNorm() < (b.center - part.center).squaredNorm();
  });
  all.resize(std::min(n, all.size()));
  int iterations = 0;
  for (auto _ : state) {
    const SupportNormal sn = support_normal(part, all, Eigen::Vector3d::UnitZ(), 0.1 * 5e-3);
    iterations = sn.iterations;
    benchmark::DoNotOptimize(sn.normal);
  }
  state.counters["newton_steps"] = iterations;
}
BENCHMARK(BM_SupportNormal)->Arg(64)->Arg(256)->Unit(benchmark::kMicrosecond);

// The passivity observer and controller's share of one servo tick (account, correct, sent) on a
// pressed, oscillating contact, with the round trip in ticks as the argument (0: a local device;
// the in-flight prediction loops over the round trip).
void BM_PassivityTick(benchmark::State& state) {
  PassivityController pc;
  pc.reset(int(state.range(0)));
  double t = 0;
  for (auto _ : state) {
    t += 1e-3;
    const Eigen::Vector3d x(0, 0, -0.002 + 0.001 * std::sin(40 * t));
    const Eigen::Vector3d v(0, 0, 0.04 * std::cos(40 * t));
    const Eigen::Vector3d f(0, 0, 2000 * -x.z() + 0.3 * std::sin(40 * t - 0.5));
    pc.account(x);
    const PassivityStep step = pc.correct(f, v, 1e-3);
    pc.sent(step.force);
    benchmark::DoNotOptimize(step.force);
  }
}
BENCHMARK(BM_PassivityTick)->Arg(0)->Arg(5)->Arg(20);

void BM_BroadPhase(benchmark::State& state, const char* scene, double rmin, double rmax) {
  const Fixture& f = fixture(scene, rmin, rmax);
  std::size_t i = 0;
  for (auto _ : state) {
    const ToolEllipsoid& t = f.poses[i];
    const Eigen::Vector3d h = t.aabb_half_extent();
    float lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = float(t.center[k] - h[k]);
      hi[k] = float(t.center[k] + h[k]);
    }
    std::uint32_t n = 0;
    f.world->bvh().for_each_overlapping_leaf(lo, hi, [&](std::uint32_t, std::uint32_t c) { n += c; });
    benchmark::DoNotOptimize(n);
    if (++i == f.poses.size()) i = 0;
  }
  state.SetItemsProcessed(std::int64_t(state.iterations()));
}
BENCHMARK_CAPTURE(BM_BroadPhase, truck, "truck.splat", 0.01, 0.02);
BENCHMARK_CAPTURE(BM_BroadPhase, karangkidul, "karangkidul_crop.ply", 0.005, 0.015);

void BM_Query(benchmark::State& state, const char* scene, double rmin, double rmax) {
  const Fixture& f = fixture(scene, rmin, rmax);
  ContactQuery q(*f.world);
  ForceModel force;
  std::size_t i = 0, contacts = 0, candidates = 0, prefiltered = 0;
  for (auto _ : state) {
    const ToolEllipsoid& t = f.poses[i];
    q.run(t);
    candidates += q.result().counts.candidates;
    prefiltered += q.result().counts.prefiltered;
    benchmark::DoNotOptimize(force.update(q.result().contacts(), t.center, Eigen::Vector3d::Zero(), 1e-3));
    contacts += q.result().contacts().size();
    if (++i == f.poses.size()) i = 0;
  }
  state.SetItemsProcessed(std::int64_t(state.iterations()));
  state.counters["contacts/query"] = double(contacts) / double(state.iterations());
  state.counters["candidates/query"] = double(candidates) / double(state.iterations());
  state.counters["prefiltered/query"] = double(prefiltered) / double(state.iterations());
}
BENCHMARK_CAPTURE(BM_Query, truck, "truck.splat", 0.01, 0.02)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_Query, karangkidul, "karangkidul_crop.ply", 0.005, 0.015)->Unit(benchmark::kMicrosecond);

// The same pose again and again: every record in cache (the servo loop's case, where
// successive queries 1 ms apart touch nearly the same Gaussians); compare with BM_Query.
void BM_QueryHot(benchmark::State& state, const char* scene, double rmin, double rmax) {
  const Fixture& f = fixture(scene, rmin, rmax);
  ContactQuery q(*f.world);
  std::size_t i = 0;
  std::int64_t contacts = 0;
  for (auto _ : state) {
    const ToolEllipsoid& t = f.poses[i / 64];
    q.run(t);
    contacts += std::int64_t(q.result().contacts().size());
    if (++i == 64 * f.poses.size()) i = 0;
  }
  state.SetItemsProcessed(std::int64_t(state.iterations()));
  state.counters["contacts/query"] = double(contacts) / double(state.iterations());
}
BENCHMARK_CAPTURE(BM_QueryHot, truck, "truck.splat", 0.01, 0.02)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_QueryHot, karangkidul, "karangkidul_crop.ply", 0.005, 0.015)->Unit(benchmark::kMicrosecond);

// Only the poses with >= 2000 contacts (the p99 of the near-surface sets; target p99 <= 500
// us, issue 19), query alone; ns per contact in the counters.
// Argument: threads sharing each query (QueryPool; 1: none), every query split.
void BM_QueryHeavy(benchmark::State& state, const char* scene, double rmin, double rmax) {
  const Fixture& f = fixture(scene, rmin, rmax);
  ContactQuery q(*f.world);
  const int threads = int(state.range(0));
  std::unique_ptr<QueryPool> pool;
  std::vector<ToolEllipsoid> heavy;
  for (const ToolEllipsoid& t : f.poses) {
    q.run(t);
    if (q.result().contacts().size() >= 2000) heavy.push_back(t);
  }
  if (heavy.empty()) {
    state.SkipWithError("no pose with >= 2000 contacts");
    return;
  }
  if (threads > 1) {
    pool = std::make_unique<QueryPool>(threads);
    q.set_executor(pool.get(), 0);
  }
  std::size_t i = 0;
  std::int64_t contacts = 0, candidates = 0, prefiltered = 0;
  for (auto _ : state) {
    q.run(heavy[i]);
    contacts += std::int64_t(q.result().contacts().size());
    candidates += q.result().counts.candidates;
    prefiltered += q.result().counts.prefiltered;
    if (++i == heavy.size()) i = 0;
  }
  state.SetItemsProcessed(contacts);
  state.counters["contacts/query"] = double(contacts) / double(state.iterations());
  state.counters["candidates/query"] = double(candidates) / double(state.iterations());
  // The pairs the narrow-phase kernel solved (BM_NarrowPhaseBatch's ns per pair times this is the
  // kernel's share of the query).
  state.counters["prefiltered/query"] = double(prefiltered) / double(state.iterations());
  state.counters["poses"] = double(heavy.size());
}
BENCHMARK_CAPTURE(BM_QueryHeavy, truck, "truck.splat", 0.01, 0.02)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace gshaptics

BENCHMARK_MAIN();
