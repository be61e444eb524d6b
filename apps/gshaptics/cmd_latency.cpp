// `gshaptics latency`: what this machine takes from a thread that never sleeps (a thin CLI over
// session/report_session.h's run_latency_command).

#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/session/report_session.h"

namespace gshaptics::cli {

void register_latency(CLI::App& app) {
  auto o = std::make_shared<LatencyCommandOptions>();
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
  cmd->callback([o] { run_latency_command(*o); });
}

}  // namespace gshaptics::cli
