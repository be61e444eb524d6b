// gshaptics: touch a 3D Gaussian Splatting scene through a haptic device.
// Thin entry point: each subcommand parses its arguments and calls the library.

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "commands.h"
#include "gshaptics/error.h"

namespace gshaptics::cli {
namespace {
int g_exit_code = 0;
}
std::vector<std::string>& ros_arguments() {
  static std::vector<std::string> args;
  return args;
}
int exit_code() { return g_exit_code; }
void set_exit_code(int code) { g_exit_code = code; }
}  // namespace gshaptics::cli

int main(int argc, char** argv) {
  CLI::App app{
      "gshaptics: direct haptic rendering of 3D Gaussian Splatting scenes.\n"
      "Loads a trained 3DGS scene, filters it by opacity, registers it into the device's world "
      "frame, finds the Gaussians overlapping a tool ellipsoid (BVH broad phase + exact "
      "Gilitschenski-Hanebeck K_min narrow phase) and renders the contact force: a god-object proxy on "
      "the Gaussians with virtual coupling and optional friction (default), or the paper's penalty "
      "force (--force-model paper).",
      "gshaptics"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "gshaptics 0.1.0");
  gshaptics::cli::register_info(app);
  gshaptics::cli::register_query(app);
  gshaptics::cli::register_simulate(app);
  gshaptics::cli::register_run(app);
#ifdef GSHAPTICS_HAVE_VIEWER
  gshaptics::cli::register_serve(app);
#endif
#if defined(GSHAPTICS_HAVE_ROS2) || defined(GSHAPTICS_HAVE_ROS1)
  gshaptics::cli::register_node(app);
#endif
#ifdef GSHAPTICS_HAVE_ROS2
  gshaptics::cli::register_device_sim(app);
#endif
  gshaptics::cli::register_poses(app);
  gshaptics::cli::register_convert(app);
  gshaptics::cli::register_synth(app);
  gshaptics::cli::register_fidelity(app);
  gshaptics::cli::register_seen_felt(app);
  gshaptics::cli::register_stability(app);
  gshaptics::cli::register_devices(app);
  gshaptics::cli::register_latency(app);
  // ROS arguments go to the middleware, not to CLI11: ROS 1 remappings (`from:=to`, `__name:=`,
  // `__ns:=`) and ROS 2's `--ros-args ... [--]`.
  std::vector<char*> args{argv[0]};
  auto& ros = gshaptics::cli::ros_arguments();
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--ros-args") {
      for (ros.push_back(a); ++i < argc && std::string(argv[i]) != "--";) ros.emplace_back(argv[i]);
      continue;
    }
    if (!a.empty() && a[0] != '-' && a.find(":=") != std::string::npos) {
      ros.push_back(a);
      continue;
    }
    args.push_back(argv[i]);
  }
  if (!ros.empty() && !(args.size() > 1 && std::string(args[1]) == "node")) {
    std::fprintf(stderr, "gshaptics: error: '%s' is a ROS argument; only `gshaptics node` takes them\n", ros.front().c_str());
    return 2;
  }
  try {
    app.parse(int(args.size()), args.data());
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0 through CLI11; every input error is one line and exit 2.
    if (e.get_exit_code() == 0) return app.exit(e);
    std::fprintf(stderr, "gshaptics: error: %s (see --help)\n", e.what());
    return 2;
  } catch (const gshaptics::InputError& e) {
    std::fprintf(stderr, "gshaptics: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gshaptics: internal error: %s\n", e.what());
    return 3;
  }
  return gshaptics::cli::exit_code();
}
