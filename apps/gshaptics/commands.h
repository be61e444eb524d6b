#pragma once
#include <CLI/CLI.hpp>

namespace gshaptics::cli {
void register_info(CLI::App& app);
void register_query(CLI::App& app);
void register_simulate(CLI::App& app);
void register_run(CLI::App& app);
void register_serve(CLI::App& app);
void register_node(CLI::App& app);
void register_device_sim(CLI::App& app);
void register_poses(CLI::App& app);
void register_convert(CLI::App& app);
void register_synth(CLI::App& app);
void register_fidelity(CLI::App& app);
void register_stability(CLI::App& app);
void register_devices(CLI::App& app);
void register_latency(CLI::App& app);
/// Exit status a command set while running (0 unless it reported a failure).
int exit_code();
void set_exit_code(int code);
}  // namespace gshaptics::cli
