// `gshaptics latency`: what this machine takes from a thread that never sleeps (the gaps a
// spinning thread sees between clock reads, as hwlatdetect / sysjitter measure them), on the CPU
// `run` gives the servo thread, and what that means for a 1 kHz servo loop and a query's tail.

#include <fmt/format.h>
#include <pthread.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <thread>

#include "commands.h"
#include "gshaptics/error.h"
#include "gshaptics/servo/interruptions.h"
#include "gshaptics/servo/realtime_thread.h"

namespace gshaptics::cli {

namespace {
struct LatencyOptions {
  double seconds = 2.0;
  int cpu = -1;  // -1: the last CPU (where `run` pins the servo thread)
  int priority = 0;
  double threshold_us = 5.0;
  bool json = false;
};
}  // namespace

void register_latency(CLI::App& app) {
  auto o = std::make_shared<LatencyOptions>();
  CLI::App* cmd = app.add_subcommand(
      "latency",
      "Measure what this machine takes from a real-time thread: spin on the clock for a while on "
      "one CPU and report every gap between reads longer than a threshold (interrupts, the "
      "hypervisor, other threads). Tells whether a servo loop's late ticks or a benchmark's tail "
      "are the machine's or the code's.");
  cmd->add_option("--seconds", o->seconds, "How long to spin")->capture_default_str()->check(CLI::Range(0.01, 600.0));
  cmd->add_option("--cpu", o->cpu, "CPU to spin on (default: the last one, where `run` puts the servo thread)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--priority", o->priority,
                  "SCHED_FIFO priority to spin at, as `run`'s servo thread (0: normal scheduling)")
      ->capture_default_str()->check(CLI::Range(0, 99));
  cmd->add_option("--threshold-us", o->threshold_us, "Shortest gap counted, us")->capture_default_str()->check(CLI::PositiveNumber);
  cmd->add_flag("--json", o->json, "Print the profile as one JSON object");
  cmd->callback([o] {
    const long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    const int cpu = o->cpu >= 0 ? o->cpu : int(std::max(1L, ncpu) - 1);
    if (ncpu > 0 && cpu >= ncpu)
      throw InputError(fmt::format("--cpu {}: this machine has CPUs 0-{}", cpu, ncpu - 1));
    std::string warning;
    InterruptionProfile p;
    std::thread t([&] {
      if (int e = pin_thread_to_cpu(pthread_self(), cpu); e != 0)
        warning += fmt::format("pinning to CPU {} refused: {}; ", cpu, std::strerror(e));
      if (o->priority > 0) {
        if (int e = set_fifo_priority(pthread_self(), o->priority); e != 0)
          warning += fmt::format("SCHED_FIFO {} refused: {} (grant CAP_SYS_NICE or an rtprio limit); ",
                                 o->priority, std::strerror(e));
      }
      p = measure_interruptions(MonotonicClock::instance(), o->seconds, o->threshold_us);
    });
    t.join();
    if (!warning.empty()) fmt::print(stderr, "warning: {}measured anyway\n", warning);
    const double tick_hit = p.hit_probability(1000.0);
    if (o->json) {
      fmt::print(
          "{{\"cpu\": {}, \"priority\": {}, \"seconds\": {:.6f}, \"threshold_us\": {}, \"count\": {}, "
          "\"per_second\": {:.1f}, \"median_us\": {:.2f}, \"p99_us\": {:.2f}, \"max_us\": {:.2f}, "
          "\"lost_fraction\": {:.5f}, \"hit_probability_10us\": {:.5f}, \"hit_probability_50us\": {:.5f}, "
          "\"hit_probability_1ms\": {:.5f}}}\n",
          cpu, o->priority, p.seconds, p.threshold_us, p.count, p.per_second, p.median_us, p.p99_us, p.max_us,
          p.lost_fraction, p.hit_probability(10), p.hit_probability(50), tick_hit);
      return;
    }
    fmt::print("CPU {} ({}), {:.2f} s spinning on the clock, gaps over {:g} us:\n", cpu,
               o->priority > 0 ? fmt::format("SCHED_FIFO {}", o->priority) : std::string("normal scheduling"),
               p.seconds, p.threshold_us);
    if (p.count == 0) {
      fmt::print("  none: this CPU ran the thread without a break\n");
      return;
    }
    fmt::print("  {} gaps, {:.0f} per second; median {:.1f} us, p99 {:.1f} us, max {:.1f} us; {:.2f} % of the time lost\n",
               p.count, p.per_second, p.median_us, p.p99_us, p.max_us, 100 * p.lost_fraction);
    fmt::print("  a computation of 10 us is hit with probability {:.2f} %, one of 50 us {:.2f} %: a latency\n"
               "  percentile rarer than that includes a gap (for `gshaptics_bench`, compare its \"median of passes\")\n",
               100 * p.hit_probability(10), 100 * p.hit_probability(50));
    fmt::print("  a 1 kHz servo tick is hit {:.1f} % of the time; the longest gap is {:.0f} % of its 1 ms budget\n",
               100 * tick_hit, p.max_us / 10.0);
  });
}

}  // namespace gshaptics::cli
