// `gshaptics devices`: every device kind, whether it can be used here, and why not.

#include <fmt/format.h>

#include "commands.h"
#include "gshaptics/servo/vendor_library.h"

namespace gshaptics::cli {

namespace {
void row(const std::string& kind, bool ok, const std::string& note) {
  fmt::print("{:<22} {:<4} {}\n", kind, ok ? "yes" : "no", note);
}
}  // namespace

void register_devices(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "devices",
      "List every device kind, whether it is available on this machine and, when not, why and what "
      "to install. Vendor libraries are looked up at run time (dlopen): nothing proprietary is "
      "needed to build gshaptics.");
  cmd->callback([] {
    fmt::print("{:<22} {:<4} {}\n", "device", "here", "notes");
    row("sim", true, "simulated admittance device and hand (run, serve, device-sim)");
    row("replay:FILE", true, "a pose log (CSV time_s,x,y,z[,...]) played back (run, serve)");
#ifdef GSHAPTICS_HAVE_VIEWER
    row("mouse", true, "the browser page steers the tool (serve)");
#else
    row("mouse", false, "built without the viewer (Boost.Beast); reconfigure with it");
#endif
#ifdef GSHAPTICS_HAVE_ROS2
    row("ros2", true, "any device a ROS 2 driver publishes (node --ros2; Cyclone DDS)");
#else
    row("ros2", false, "built without Cyclone DDS (GSHAPTICS_WITH_ROS2=OFF)");
#endif
#ifdef GSHAPTICS_HAVE_ROS1
    row("ros1", true, "any device a ROS 1 driver publishes (node --ros1; roscpp)");
#else
    row("ros1", false, "built without roscpp (GSHAPTICS_WITH_ROS1=OFF)");
#endif
    for (const VendorLibraryProbe& p : {probe_dhd_library(), probe_openhaptics_library()}) {
      if (p.available)
        row(p.kind, false,
            fmt::format("{} loads ({}){}; the device driver itself is not in this build yet, so it "
                        "cannot be selected with --device",
                        p.library, p.path, p.devices >= 0 ? fmt::format(", {} device(s) reported", p.devices) : ""));
      else
        row(p.kind, false, p.why);
    }
    row("haply", false, "Haply Inverse3 (JSON over its local WebSocket service): client not written yet");
  });
}

}  // namespace gshaptics::cli
