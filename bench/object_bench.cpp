// What one rigid object adds to the servo tick (issue 72 target: at most 20 us on the tick's
// p99, MuJoCo step included). Each benchmark iteration is one tick of a hand that sweeps into a
// 10 x 8 x 6 cm box of discs on a floor slab and back (2 s per cycle, the scene put back at rest
// between cycles, untimed): arg 0 renders the floor alone (the proxy), arg 1 the floor and the
// box through ObjectRenderer as every command makes it (a proxy per body, the whole scene's proxy,
// the MuJoCo step in the tick), arg 2 the same without the whole scene's proxy. A renderer-level
// number: no device, no safety layer, no worker (a shortcut, labelled as such in RESULTS).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "gshaptics/objects/object_renderer.h"

namespace gshaptics {
namespace {

struct Bench {
  Bench() {
    ObjectSpec spec;
    spec.mass = 0.4;
    spec.friction = 0.3;
    spec.text = "bench box";
    objects.push_back(make_rigid_object(
        box_surface_gaussians(Eigen::Vector3d(0, 0, 0.03), Eigen::Vector3d(0.05, 0.04, 0.03), 0.01), spec, WorldConfig{}));
    dynamics = std::make_shared<ObjectDynamics>(objects, support_under(objects, Eigen::Vector3d::UnitZ()));
  }
  CollisionWorld floor = CollisionWorld::build(
      box_surface_gaussians(Eigen::Vector3d(0, 0, -0.0105), Eigen::Vector3d(0.4, 0.3, 0.01), 0.01), WorldConfig{});
  std::vector<RigidObject> objects;
  std::shared_ptr<ObjectDynamics> dynamics;
};

// The hand at tick k of a 2 s cycle: from x = -0.12 m to 0.10 m and back at mid-height, 1 cm off
// the floor's centre line.
Eigen::Vector3d hand(int k, Eigen::Vector3d& velocity) {
  const double t = (k % 2000) * 1e-3, w = 2 * M_PI / 2.0;
  velocity = Eigen::Vector3d(0.11 * w * std::sin(w * t), 0, 0);
  return Eigen::Vector3d(-0.01 - 0.11 * std::cos(w * t), 0.01, 0.03);
}

void BM_ObjectTick(benchmark::State& state) {
  static Bench bench;
  WholeSceneOptions whole;
  whole.enabled = state.range(0) == 1;
  std::unique_ptr<ForceRenderer> renderer =
      state.range(0) == 0 ? make_force_renderer(RendererSpec{}, bench.floor)
                          : std::unique_ptr<ForceRenderer>(make_object_renderer(RendererSpec{}, bench.floor, bench.objects,
                                                                                bench.dynamics, {}, whole));
  std::vector<double> ticks;
  ticks.reserve(1 << 22);
  int k = 0;
  double contacts = 0;
  for (auto _ : state) {
    if (k % 2000 == 0) {
      state.PauseTiming();
      renderer->reset();
      state.ResumeTiming();
    }
    Eigen::Vector3d v;
    const ToolEllipsoid tool = ToolEllipsoid::sphere(hand(k, v), 0.01);
    const auto t0 = std::chrono::steady_clock::now();
    const RenderOutput out = renderer->render(tool, v, 1e-3);
    const auto t1 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(out.force);
    if (ticks.size() < ticks.capacity()) ticks.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    contacts += out.force.squaredNorm() > 0;
    ++k;
  }
  std::sort(ticks.begin(), ticks.end());
  if (!ticks.empty()) {
    state.counters["p50_us"] = ticks[ticks.size() / 2];
    state.counters["p99_us"] = ticks[std::min(ticks.size() - 1, ticks.size() * 99 / 100)];
  }
  state.counters["in_contact"] = contacts / double(std::max(k, 1));
}
BENCHMARK(BM_ObjectTick)->Arg(0)->Arg(1)->Arg(2)->Iterations(20000)->Unit(benchmark::kMicrosecond);

// The MuJoCo step alone, the box sliding under a steady push of twice mu m g at its centre of
// mass (arg 1), or resting untouched and awake (arg 0: the step a resting box costs before it sleeps).
void BM_DynamicsStep(benchmark::State& state) {
  static Bench bench;
  ObjectDynamics d(bench.objects, support_under(bench.objects, Eigen::Vector3d::UnitZ()));
  const Eigen::Vector3d push(2 * 0.3 * 0.4 * 9.81, 0, 0);
  std::vector<double> steps;
  steps.reserve(1 << 20);
  int k = 0;
  for (auto _ : state) {
    if (k % 1000 == 0) {
      state.PauseTiming();
      d.reset();
      state.ResumeTiming();
    }
    const auto t0 = std::chrono::steady_clock::now();
    if (state.range(0) == 1) d.apply_wrench(0, push, d.center_of_mass(0));
    d.step();
    const auto t1 = std::chrono::steady_clock::now();
    if (steps.size() < steps.capacity()) steps.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    ++k;
  }
  std::sort(steps.begin(), steps.end());
  if (!steps.empty()) {
    state.counters["p50_us"] = steps[steps.size() / 2];
    state.counters["p99_us"] = steps[std::min(steps.size() - 1, steps.size() * 99 / 100)];
  }
}
BENCHMARK(BM_DynamicsStep)->Arg(0)->Arg(1)->Iterations(20000)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace gshaptics

BENCHMARK_MAIN();
