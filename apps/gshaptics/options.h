#pragma once
// The CLI's options: CLI11 bindings of the session layer's option structs (gshaptics::session),
// and validators that reject NaN and infinities.

#include <CLI/CLI.hpp>

#include "gshaptics/session/run_session.h"

namespace gshaptics::cli {

using namespace gshaptics::session;

/// Option validators that also reject NaN and infinities (CLI11's numeric ones let NaN through),
/// with one short message: "--rate: must be a finite number in [10, 20000], got 'nan'".
namespace check {
CLI::Validator positive();                   ///< finite and > 0
CLI::Validator non_negative();               ///< finite and >= 0
CLI::Validator range(double lo, double hi);  ///< finite and in [lo, hi]
}  // namespace check

/// Adds --min-opacity, --sigma, --registration and the --reg-* overrides.
void add_world_options(CLI::App& app, SceneOptions& o);
/// Adds --world-cache (the commands that build a world for a run: run, serve, node, simulate).
void add_world_cache_option(CLI::App& app, SceneOptions& o);
/// --object SPEC (repeatable): a rigid object cut from the scene (parse_object_spec), simulated by
/// MuJoCo (run and simulate).
void add_object_option(CLI::App& app, SceneOptions& o);

/// Adds --inline, --decoupled and (when `simulated`) --latency. The default is the runtime's.
void add_execution_options(CLI::App& cmd, ExecutionOptions& o, bool simulated);

/// Adds --force-model, the paper model's --k-base, --damping, --tau-normal, --tau-opacity, the
/// proxy's --stiffness, --coupling-damping, --mu-s, --mu-k, --opacity-stiffness, --substeps,
/// --energy-bound, --device-shading, --corner-normal, --crest-hold, --overhang-falloff, --near-lists,
/// --face-average, --isolation-gap, --floater-cluster, and --f-max.
/// And --device-profile, whose values fill --f-max and --stiffness unless they are given.
/// Options given that do not apply are refused (refuse_options_not_applying): the other model's,
/// and, with `tool` (the command's --tool), the proxy's options for the other kind of tool.
void add_force_options(CLI::App& cmd, ForceModelOptions& o, const ToolOption* tool = nullptr);
/// Adds --tool, parsed once into `tool` (parse_tool_option) as the command line is read.
void add_tool_option(CLI::App& cmd, ToolOption& tool, const std::string& help);

/// Adds --passivity on|off and --passivity-max-damping (the servo step's passivity controller).
void add_passivity_option(CLI::App& cmd, PassivityParams& p);
/// --control impedance|admittance, --virtual-mass, --virtual-damping (servo/admittance.h).
void add_control_options(CLI::App& cmd, ControlParams& c);
/// Adds the device, rate, duration, tool, force, safety, real-time, output and world options.
/// `devices` is the --device help text.
void add_runtime_options(CLI::App& cmd, RuntimeOptions& o, const std::string& devices);

}  // namespace gshaptics::cli
