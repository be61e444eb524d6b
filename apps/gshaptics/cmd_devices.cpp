// `gshaptics devices`: every device kind, whether it can be used here, and why not; for the
// desktop devices found, their workspace and rate.

#include <fmt/format.h>

#include <chrono>
#include <thread>

#include "commands.h"
#include "gshaptics/error.h"
#include "gshaptics/device/device_registry.h"
#ifdef GSHAPTICS_HAVE_VIEWER
#include "gshaptics/device/haply_device.h"
#endif

namespace gshaptics::cli {

namespace {
void row(const std::string& kind, bool ok, const std::string& note) {
  fmt::print("{:<22} {:<4} {}\n", kind, ok ? "yes" : "no", note);
}

}  // namespace

void register_devices(CLI::App& app) {
  auto haply_url = std::make_shared<std::string>("ws://127.0.0.1:10001/");
  CLI::App* cmd = app.add_subcommand(
      "devices",
      "List every device kind, whether it is available on this machine and, when not, why and what "
      "to install; desktop devices found are opened briefly (zero force) for their workspace and "
      "rate. Vendor libraries are looked up at run time (dlopen): nothing proprietary is needed to "
      "build gshaptics.");
  cmd->add_option("--haply-url", *haply_url, "Where the Haply Inverse Service listens")->capture_default_str();
  cmd->callback([haply_url] {
    fmt::print("{:<22} {:<4} {}\n", "device", "here", "notes");
#ifdef GSHAPTICS_HAVE_VIEWER
    row("mouse", true, "the browser page steers the tool (serve)");
    row("xr", true, "a VR controller in the page's WebXR session steers the tool, vibration as feedback (serve)");
#else
    row("mouse", false, "built without the viewer (Boost.Beast); reconfigure with it");
#endif
#ifdef GSHAPTICS_HAVE_ROS2
    row("ros (node --ros2)", true, "any device a ROS 2 driver publishes (Cyclone DDS)");
#else
    row("ros (node --ros2)", false, "built without Cyclone DDS (GSHAPTICS_WITH_ROS2=OFF)");
#endif
#ifdef GSHAPTICS_HAVE_ROS1
    row("ros (node --ros1)", true, "any device a ROS 1 driver publishes (roscpp)");
#else
    row("ros (node --ros1)", false, "built without roscpp (GSHAPTICS_WITH_ROS1=OFF)");
#endif
    // Everything the device registry knows (sim, replay, the vendor devices, Haply when built in).
    DeviceOptions opts;
    opts.haply_url = *haply_url;
    for (const DeviceStatus& d : list_devices(opts)) row(d.spec, d.available, d.note);
#ifndef GSHAPTICS_HAVE_VIEWER
    row("haply[:N]", false, "built without the WebSocket client (Boost.Beast)");
#endif
  });
}

}  // namespace gshaptics::cli
