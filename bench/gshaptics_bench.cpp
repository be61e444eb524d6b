// gshaptics_bench: loads scenes, draws seeded near-surface pose sets (and the probe trajectory),
// times gshaptics' whole query (broad + narrow phase + force model) per pose, times the peers
// (the paper's method and FCL) on the same poses in the same run, checks all three against the
// extended-precision brute-force reference, and prints one table.

#include <fmt/format.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>

#include <CLI/CLI.hpp>
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/force_model.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/scene/registration.h"
#include "gshaptics/error.h"
#include "gshaptics/percentile.h"
#include "gshaptics/sim/pose_sampler.h"
#include "gshaptics/collision/world_cache.h"
#include "gshaptics/servo/interruptions.h"
#include "gshaptics/servo/query_pool.h"
#include "gshaptics/sim/probe_trajectory.h"
#include "gshaptics/sim/probe_run.h"
#ifdef GSHAPTICS_HAVE_PEERS
#include "peers.h"
#endif
#ifdef GSHAPTICS_HAVE_REFERENCE
#include "support/reference.h"
#endif

namespace gshaptics::bench {

namespace {

using Clock = std::chrono::steady_clock;
double us_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
}

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;
}

// A "VmXXX:  N kB" line of /proc/self/status in MB (0 when unreadable).
double status_mb(const char* field) {
  std::ifstream f("/proc/self/status");
  std::string line;
  const std::string key = std::string(field) + ":";
  while (std::getline(f, line))
    if (line.rfind(key, 0) == 0) return std::stod(line.substr(key.size())) / 1024.0;
  return 0;
}

// Resets the peak RSS (VmHWM) to the current RSS (Linux: /proc/self/clear_refs, "5"), so the
// next status_mb("VmHWM") is the peak of what runs in between. False when not permitted.
bool reset_peak_rss() {
  std::ofstream f("/proc/self/clear_refs");
  f << "5";
  f.flush();
  return bool(f);
}

struct BenchOptions {
  std::string scenes = "truck,truck-probe,truck-probe-cached,truck-hard,firepit-hard,karangkidul,karangkidul-4M,karangkidul-10M";
  std::size_t poses = 2000;
  int passes = 3;
  int query_threads = 1;
  std::size_t parallel_min_candidates = 2048;
  std::size_t peer_poses = 300;
  std::size_t reference_poses = 20;
  std::uint64_t seed = 1;
  bool no_peers = false;
  std::string out;
};

struct Timing {
  double p50 = 0, p99 = 0, p999 = 0, max = 0;
};

Timing timing_of(std::vector<double> us) {
  Timing t;
  if (us.empty()) return t;
  t.p50 = percentile(us, 50);
  t.p99 = percentile(us, 99);
  t.p999 = percentile(us, 99.9);
  t.max = *std::max_element(us.begin(), us.end());
  return t;
}

// A scene as the bench sees it: the loaded Gaussians (tiled if asked) and their world config.
struct BenchScene {
  std::string name, file;
  GaussianScene scene;
  WorldConfig config;
  double radius_min = 0, radius_max = 0;  // tool radius, fraction of the base scene's extent
  int tiles = 1;
  bool probe = false;
  double cache_margin = 0;  // candidate cache margin, fraction of the tool radius (0: none)
  bool anisotropic = false; // random tool orientation and axis ratios down to 1/3 (the hard sets)
};

// Copies of `base` side by side on a grid in the x-z plane (y is up/down in 3DGS scenes), each
// shifted by `spacing`, with distinct source indices. In memory only.
GaussianScene tile_scene(const GaussianScene& base, int copies, double spacing) {
  GaussianScene out;
  out.reserve(base.size() * std::size_t(copies));
  const int side = int(std::ceil(std::sqrt(double(copies))));
  for (int k = 0; k < copies; ++k) {
    const Eigen::Vector3f shift(float(spacing * (k % side)), 0.f, float(spacing * (k / side)));
    for (std::size_t i = 0; i < base.size(); ++i)
      out.push_back(base.means[i] + shift, base.scales[i], base.rotations[i], base.opacities[i],
                    std::uint32_t(std::size_t(k) * base.size() + i));
  }
  return out;
}

std::string scene_file(const std::string& name) {
  if (name == "truck.splat") return std::string(GSHAPTICS_DATA_DIR) + "/truck.splat";
  return std::string(GSHAPTICS_SCENES_DIR) + "/" + name;
}

std::string bundled_registration() { return std::string(GSHAPTICS_DATA_DIR) + "/truck.registration.json"; }

// Loads a scene, saying so on stderr (the large ones take seconds).
LoadedScene load_with_progress(const std::string& path) {
  fmt::print(stderr, "bench: loading {}\n", path);
  return load_scene(path);
}

// Missed = reference K_min > 1e-5 but not reported; extra = reported but reference K_min < -1e-5.
struct Exactness {
  std::size_t poses = 0, reference_contacts = 0, missed = 0, extra = 0;
  double max_k_error = 0;  // ours only
  [[nodiscard]] std::string str() const {
    if (poses == 0) return "-";
    return fmt::format("{} missed, {} extra", missed, extra);
  }
};

}  // namespace

void register_bench(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  CLI::App* cmd = &app;
  app.description(
      "Benchmark the whole collision query (broad + narrow phase + force model) on seeded "
      "near-surface pose sets of real scenes, side by side with the paper's method and FCL on "
      "the same poses, checked against the float64 brute-force reference. Scenes: truck (bundled, "
      "registered; tool radius 1-2% of extent), truck-probe (every 1 kHz tick of the probe "
      "trajectory), truck-probe-cached (the same with the servo loop's candidate cache, margin a "
      "quarter of the tool radius), karangkidul (0.5-1.5%), karangkidul-4M, -10M and -15M (tiled in memory; -15M is not in the default list, it is the build-memory case).");
  cmd->add_option("--scenes", o->scenes, "Comma-separated scene sets")->capture_default_str();
  cmd->add_option("--poses", o->poses, "Poses per scene for gshaptics")->capture_default_str();
  cmd->add_option("--passes", o->passes,
                  "Times each pose set is run, in the same order; the 'median of passes' columns take each "
                  "pose's median over them (an interruption of the machine rarely hits one pose twice)")
      ->capture_default_str()->check(CLI::Range(1, 99));
  cmd->add_option("--query-threads", o->query_threads,
                  "Threads sharing a large query's narrow phase (the caller included; 1: none)")->capture_default_str();
  cmd->add_option("--parallel-min-candidates", o->parallel_min_candidates,
                  "Queries with fewer candidates stay on one thread")->capture_default_str();
  cmd->add_option("--peer-poses", o->peer_poses, "Of those, poses run by the peers too")->capture_default_str();
  cmd->add_option("--reference-poses", o->reference_poses,
                  "Of those, poses checked against the brute-force reference (fewer on tiled scenes)")
      ->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of the pose sets")->capture_default_str();
  cmd->add_flag("--no-peers", o->no_peers, "Skip the paper's method and FCL");
  cmd->add_option("--out", o->out, "Also write the table (Markdown) to this file");
  cmd->callback([o] {
    std::vector<BenchScene> sets;
    std::stringstream ss(o->scenes);
    std::string name;
    std::map<std::string, LoadedScene> loaded;
    const auto load = [&](const std::string& file) -> const GaussianScene& {
      auto it = loaded.find(file);
      if (it == loaded.end()) it = loaded.emplace(file, load_with_progress(scene_file(file))).first;
      return it->second.scene;
    };
    while (std::getline(ss, name, ',')) {
      BenchScene b;
      b.name = name;
      if (name == "truck" || name == "truck-probe" || name == "truck-probe-cached") {
        b.file = "truck.splat";
        b.config.registration = load_registration_file(bundled_registration());
        b.radius_min = 0.01;
        b.radius_max = 0.02;
        b.probe = name != "truck";
        if (name == "truck-probe-cached") b.cache_margin = 0.25;
      } else if (name == "truck-hard" || name == "firepit-hard") {
        // Hard poses: large, elongated or flat tools (stylus- and disc-like, axis ratios down to
        // 1/3, any orientation), 2-5 % of the extent: thousands of contacts per query.
        b.file = name == "truck-hard" ? "truck.splat" : "firepit.ply";
        if (name == "truck-hard") b.config.registration = load_registration_file(bundled_registration());
        b.radius_min = 0.02;
        b.radius_max = 0.05;
        b.anisotropic = true;
      } else if (name.rfind("karangkidul", 0) == 0) {
        b.file = "karangkidul_crop.ply";
        b.radius_min = 0.005;
        b.radius_max = 0.015;
        if (name == "karangkidul-4M") b.tiles = 5;   // 5 x 885k kept = 4.4M
        if (name == "karangkidul-10M") b.tiles = 12; // 12 x 885k kept = 10.6M
        if (name == "karangkidul-15M") b.tiles = 17; // 17 x 885k kept = 15.0M (build memory)
        if (name != "karangkidul" && b.tiles == 1) throw InputError("bench: unknown scene set '" + name + "'");
      } else {
        throw InputError("bench: unknown scene set '" + name +
                         "' (truck, truck-probe, truck-probe-cached, truck-hard, firepit-hard, karangkidul, karangkidul-4M, karangkidul-10M, karangkidul-15M)");
      }
      sets.push_back(std::move(b));
    }

    std::vector<std::string> rows;
    const std::string passes_col = fmt::format("p50 / p99 us, median of {} passes", o->passes);
    // The machine's own interruptions, measured on this thread before any scene: they set the
    // tail of any percentile rarer than they are frequent (see the note under the table).
    const InterruptionProfile machine = measure_interruptions(MonotonicClock::instance(), 0.5);
    const std::string machine_note = fmt::format(
        "Machine: a thread spinning on the clock for {:.1f} s lost the CPU {:.0f} times per second (gaps over "
        "{:.0f} us: median {:.1f} us, p99 {:.1f} us, max {:.1f} us; {:.1f} % of the time). A query of 10 us is hit "
        "with probability {:.1f} %, one of 50 us {:.1f} %: a single pass's p99 includes them once that passes 1 %; "
        "each pose's median over {} passes does not.",
        machine.seconds, machine.per_second, machine.threshold_us, machine.median_us, machine.p99_us,
        machine.max_us, 100 * machine.lost_fraction, 100 * machine.hit_probability(10),
        100 * machine.hit_probability(50), o->passes);
    fmt::print(stderr, "bench: {}\n", machine_note);
    const std::string header =
        "| scene | Gaussians kept | build s | from cache s | world B/G | build peak MB | peak RSS MB | poses | p50 us | p99 us | "
        "p99.9 us | max us | " + passes_col + " | p99 us of >= 2000 contacts | candidates | contacts mean / max | paper p50 / p99 us | FCL p50 / p99 "
        "us | p99 ratio paper / FCL | exactness ours / paper / FCL |";
    const std::string rule = "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|";
    for (BenchScene& b : sets) {
      fmt::print(stderr, "bench: {}\n", b.name);
      const GaussianScene& base = load(b.file);
      const double base_extent = b.tiles > 1 ? robust_extent(CollisionWorld::build(base, b.config)) : 0.0;
      // Start-up as a user sees it: load (timed separately above for the first use), filter,
      // registration and BVH.
      const auto t_load = Clock::now();
      LoadedScene fresh = b.tiles == 1 ? load_scene(scene_file(b.file)) : LoadedScene{};
      const double load_s = b.tiles == 1 ? us_since(t_load) * 1e-6 : 0.0;
      GaussianScene tiled = b.tiles > 1 ? tile_scene(base, b.tiles, 400.0) : GaussianScene{};
      GaussianScene& scene = b.tiles > 1 ? tiled : fresh.scene;
      WorldBuildReport report;
      // Peak RSS of the build: reset the high-water mark, build, read it (the scene and what the
      // process held before are in it; "build peak MB").
      const bool hwm_reset = reset_peak_rss();
      const double rss_before = status_mb("VmRSS");
      // consumed, as the CLI does
      const CollisionWorld world = CollisionWorld::build(std::move(scene), b.config, &report);
      const double build_peak_mb = hwm_reset ? status_mb("VmHWM") : -1.0;
      fmt::print(stderr, "bench: {}: build peak RSS {:.0f} MB ({:.0f} MB held before the build)\n", b.name,
                 build_peak_mb, rss_before);
      const double startup_s = load_s + report.build_seconds;
      // Start-up from the world cache: key (hashing the scene file; for a tiled scene, the key
      // of its source plus the tiling), open with mmap, check the payload hash. Written to a
      // temporary folder first, so its pages are in the page cache (a warm start).
      double cache_s = -1;
      {
        const std::string cache_dir = (std::filesystem::temp_directory_path() / "gshaptics-bench-cache").string();
        std::filesystem::create_directories(cache_dir);
        const std::string src = scene_file(b.file);
        const auto key_of = [&] {
          WorldCacheKey k = world_cache_key(src, b.config);
          k.scene_hash ^= std::uint64_t(b.tiles) * 0x9E3779B97F4A7C15ull;  // the tiling is part of the scene
          return k;
        };
        const std::string cache_path = world_cache_file(cache_dir, b.name, key_of());
        write_world_cache(world, key_of(), cache_path);
        const auto t_cache = Clock::now();
        const auto cached = open_world_cache(cache_path, key_of());
        cache_s = us_since(t_cache) * 1e-6;
        if (!cached || cached->world.size() != world.size()) throw InputError("bench: the world cache did not round-trip");
        std::filesystem::remove(cache_path);
      }

      // Pose set: near-surface poses, or every tick of the probe trajectory on the truck.
      std::vector<ToolEllipsoid> poses;
      if (b.probe) {
        const ProbeParams pp = default_probe_params(world, default_tool_radius(world));
        const ProbeTrajectory traj = generate_probe_trajectory(world, pp);
        const ProbeRunResult run = run_probe(world, traj, {});
        for (const TickRecord& r : run.ticks) poses.push_back(ToolEllipsoid::sphere(r.position, pp.tool_radius));
      } else {
        PoseSamplerParams p;
        p.count = o->poses;
        p.seed = o->seed;
        // Tool sizes relative to the untiled scene's extent, so tiling only adds Gaussians.
        const double to_world = b.tiles > 1 ? base_extent / robust_extent(world) : 1.0;
        p.radius_min = b.radius_min * to_world;
        p.radius_max = b.radius_max * to_world;
        p.anisotropic = b.anisotropic;
        poses = sample_poses(world, p);
      }

      // gshaptics: query + force model per pose, as in a servo tick (the servo loop's candidate
      // cache on truck-probe-cached: margin a quarter of the tool radius).
      QueryOptions qo;
      if (b.cache_margin > 0 && !poses.empty()) qo.cache_margin = b.cache_margin * poses.front().semi_axes.maxCoeff();
      ContactQuery query(world, qo);
      std::unique_ptr<QueryPool> pool;
      if (o->query_threads > 1) {
        pool = std::make_unique<QueryPool>(o->query_threads);
        query.set_executor(pool.get(), o->parallel_min_candidates);
      }
      ForceModel force;
      std::vector<double> ours_us;
      ours_us.reserve(poses.size());
      double candidates = 0, contacts = 0;
      std::size_t max_contacts = 0, over_2000 = 0;
      std::vector<double> heavy_us;  // poses with >= 2000 contacts
      // Pass 0 gives the single-pass columns and the counts; every pass, in the same order, gives
      // each pose's median (the caches hold the same things at each pose in every pass).
      std::vector<std::vector<double>> pass_us(std::size_t(o->passes), std::vector<double>(poses.size()));
      for (int pass = 0; pass < o->passes; ++pass) {
        for (std::size_t i = 0; i < poses.size(); ++i) {
          const auto t0 = Clock::now();
          query.run(poses[i]);
          const ForceOutput f = force.update(query.result().contacts(), poses[i].center, Eigen::Vector3d::Zero(), 1e-3);
          pass_us[std::size_t(pass)][i] = us_since(t0);
          (void)f;
          if (pass > 0) continue;
          ours_us.push_back(pass_us[0][i]);
          candidates += query.result().counts.candidates;
          const std::size_t n = query.result().counts.contacts;
          contacts += double(n);
          max_contacts = std::max(max_contacts, n);
          over_2000 += n > 2000 ? 1 : 0;
          if (n >= 2000) heavy_us.push_back(ours_us.back());
        }
      }
      const Timing ours = timing_of(ours_us);
      std::vector<double> median_us(poses.size());
      for (std::size_t i = 0; i < poses.size(); ++i) {
        std::vector<double> runs;
        for (const auto& pass : pass_us) runs.push_back(pass[i]);
        median_us[i] = percentile(runs, 50);
      }
      const Timing ours_median = timing_of(median_us);
      const std::size_t n_peer = std::min(o->peer_poses, poses.size());
      // The peers run on an evenly spread subset so that long pose sets (the probe) stay fair.
      std::vector<std::size_t> subset;
      for (std::size_t k = 0; k < n_peer; ++k) subset.push_back(k * poses.size() / std::max<std::size_t>(n_peer, 1));

      std::string paper_cell = "-", fcl_cell = "-", ratio_cell = "-";
      Exactness ex_ours, ex_paper, ex_fcl;
      std::vector<std::vector<std::uint32_t>> paper_sets, fcl_sets;
#ifdef GSHAPTICS_HAVE_PEERS
      if (!o->no_peers && b.tiles == 1) {
        std::vector<double> ours_sub, paper_us, fcl_us;
        for (std::size_t k : subset) ours_sub.push_back(ours_us[k]);
        // Times one peer on the subset and keeps its contact sets for the exactness check.
        const auto run_peer = [&](auto& peer, std::vector<double>& us,
                                  std::vector<std::vector<std::uint32_t>>& contact_sets) {
          peers::PeerResult r;
          for (std::size_t k : subset) {
            const auto t0 = Clock::now();
            peer.query(poses[k], r);
            us.push_back(us_since(t0));
            contact_sets.push_back(r.contacts);
          }
        };
        {
          peers::PaperMethodPeer paper(world);
          run_peer(paper, paper_us, paper_sets);
        }
        {
          fmt::print(stderr, "bench: {}: building FCL's tree\n", b.name);
          peers::FclPeer fcl(world);
          run_peer(fcl, fcl_us, fcl_sets);
        }
        const Timing tp = timing_of(paper_us), tf = timing_of(fcl_us), to = timing_of(ours_sub);
        paper_cell = fmt::format("{:.0f} / {:.0f}", tp.p50, tp.p99);
        fcl_cell = fmt::format("{:.0f} / {:.0f}", tf.p50, tf.p99);
        ratio_cell = fmt::format("{:.0f}x / {:.0f}x", tp.p99 / to.p99, tf.p99 / to.p99);
      }
#endif
#ifdef GSHAPTICS_HAVE_REFERENCE
      {
        const std::size_t n_ref = std::min(b.tiles > 1 ? std::size_t(2) : o->reference_poses, subset.size() ? subset.size() : poses.size());
        fmt::print(stderr, "bench: {}: reference on {} poses\n", b.name, n_ref);
        // The build consumed its scene: the reference starts again from the loaded file (tiled
        // again for the tiled sets).
        const GaussianScene ref_tiled = b.tiles > 1 ? tile_scene(base, b.tiles, 400.0) : GaussianScene{};
        const auto ref_world = test::reference_world(b.tiles > 1 ? ref_tiled : base, b.config.min_opacity,
                                                     b.config.sigma, b.config.registration);
        const auto check = [&](Exactness& ex, const std::vector<std::uint32_t>& got,
                               const std::vector<test::RefContact>& ref, const ToolEllipsoid& tool) {
          std::vector<std::uint32_t> ref_ids;
          for (const auto& c : ref) ref_ids.push_back(c.index);
          for (const auto& c : ref)
            if (c.k_min > 1e-5 && !std::binary_search(got.begin(), got.end(), c.index)) ++ex.missed;
          for (std::uint32_t id : got)
            if (!std::binary_search(ref_ids.begin(), ref_ids.end(), id) &&
                test::reference_k_min_of(ref_world, tool, id) < -1e-5)
              ++ex.extra;
          ++ex.poses;
          ex.reference_contacts += ref.size();
        };
        for (std::size_t j = 0; j < n_ref; ++j) {
          const std::size_t k = subset.empty() ? j : subset[j];
          const auto ref = test::reference_contacts(ref_world, poses[k]);
          query.run(poses[k]);
          std::vector<std::uint32_t> ours_ids;
          for (const auto& c : query.result().contacts()) ours_ids.push_back(c.index);
          std::sort(ours_ids.begin(), ours_ids.end());
          check(ex_ours, ours_ids, ref, poses[k]);
          for (const auto& c : query.result().contacts()) {
            const auto it = std::lower_bound(ref.begin(), ref.end(), c.index,
                                             [](const test::RefContact& r, std::uint32_t i) { return r.index < i; });
            if (it != ref.end() && it->index == c.index)
              ex_ours.max_k_error = std::max(ex_ours.max_k_error, std::fabs(it->k_min - c.k_min));
          }
          if (j < paper_sets.size()) check(ex_paper, paper_sets[j], ref, poses[k]);
          if (j < fcl_sets.size()) check(ex_fcl, fcl_sets[j], ref, poses[k]);
        }
      }
#endif
      rows.push_back(fmt::format(
          "| {} | {} | {:.2f} | {:.3f} | {:.0f} | {:.0f} | {:.0f} | {} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {:.1f} / {:.1f} | {} | {:.0f} | "
          "{:.0f} / {} ({} over 2000) | {} | {} | {} | {} (max dK {:.1e}) / {} / {} |",
          b.name, world.size(), startup_s, cache_s, double(world.memory_bytes()) / double(world.size()),
          build_peak_mb, peak_rss_mb(), poses.size(), ours.p50, ours.p99, ours.p999, ours.max, ours_median.p50, ours_median.p99,
          heavy_us.empty() ? std::string("-") : fmt::format("{:.0f} ({} poses)", percentile(heavy_us, 99), heavy_us.size()),
          candidates / double(poses.size()), contacts / double(poses.size()), max_contacts,
          over_2000, paper_cell, fcl_cell, ratio_cell, ex_ours.str(), ex_ours.max_k_error,
          ex_paper.str(), ex_fcl.str()));
      fmt::print(stderr, "{}\n", rows.back());
    }
    std::string table = header + "\n" + rule + "\n";
    for (const auto& r : rows) table += r + "\n";
    table += "\n" + machine_note + "\n";
    fmt::print("{}", table);
    if (!o->out.empty()) write_file_atomically(o->out, table);
  });
}

}  // namespace gshaptics::bench

int main(int argc, char** argv) {
  CLI::App app{"", "gshaptics_bench"};
  gshaptics::bench::register_bench(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const gshaptics::InputError& e) {
    std::fprintf(stderr, "gshaptics_bench: error: %s\n", e.what());
    return 2;
  }
  return 0;
}
