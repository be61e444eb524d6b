#pragma once
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

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
void register_seen_felt(CLI::App& app);
void register_stability(CLI::App& app);
void register_devices(CLI::App& app);
void register_latency(CLI::App& app);
/// Middleware arguments taken off the command line before parsing (ROS 1 `from:=to`, ROS 2
/// `--ros-args ...`); only `node` accepts them.
std::vector<std::string>& ros_arguments();
/// Exit status a command set while running (0 unless it reported a failure).
int exit_code();
void set_exit_code(int code);
}  // namespace gshaptics::cli
