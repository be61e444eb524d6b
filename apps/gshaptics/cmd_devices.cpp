// `gshaptics devices`: every device kind, whether it can be used here, and why not; for the
// desktop devices found, their workspace and rate.

#include <fmt/format.h>

#include <chrono>
#include <thread>

#include "commands.h"
#include "gshaptics/error.h"
#include "gshaptics/servo/vendor_devices.h"
#include "gshaptics/servo/vendor_library.h"
#ifdef GSHAPTICS_HAVE_VIEWER
#include "gshaptics/net/haply_device.h"
#endif

namespace gshaptics::cli {

namespace {
void row(const std::string& kind, bool ok, const std::string& note) {
  fmt::print("{:<22} {:<4} {}\n", kind, ok ? "yes" : "no", note);
}

std::string describe(const HapticDevice& d) {
  const Eigen::AlignedBox3d& ws = d.info().workspace;
  const std::string box = ws.sizes().allFinite() && ws.sizes().maxCoeff() < 1e3
                              ? fmt::format("workspace {:.0f} x {:.0f} x {:.0f} mm, ", ws.sizes().x() * 1e3,
                                            ws.sizes().y() * 1e3, ws.sizes().z() * 1e3)
                              : std::string("workspace not reported, ");
  return fmt::format("{}: {}up to {:.0f} Hz", d.info().name, box, d.info().max_rate_hz);
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
    row("sim", true, "simulated admittance device and hand (run, serve, device-sim)");
    row("replay:FILE", true, "a pose log (CSV time_s,x,y,z[,...]) played back (run, serve)");
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
    // Force Dimension (DHD).
    const VendorLibraryProbe dhd = probe_dhd_library();
    if (!dhd.available) {
      row("dhd[:N]", false, dhd.why);
    } else if (dhd.devices <= 0) {
      row("dhd[:N]", false, fmt::format("{} loads ({}) but reports no device: check the USB cable, the power "
                                        "and the udev rules of the Force Dimension SDK", dhd.library, dhd.path));
    } else {
      for (int i = 0; i < dhd.devices; ++i) {
        try {
          DhdDevice d(i);
          d.start(0);
          const std::string s = describe(d) + ", " + d.status();
          d.stop(0);
          row(fmt::format("dhd:{}", i), true, s);
        } catch (const InputError& e) {
          row(fmt::format("dhd:{}", i), false, e.what());
        }
      }
    }
    // 3D Systems (OpenHaptics HD).
    const VendorLibraryProbe hd = probe_openhaptics_library();
    if (!hd.available) {
      row("openhaptics[:NAME]", false, hd.why);
    } else {
      try {
        OpenHapticsDevice d;
        d.start(0);
        const std::string s = describe(d) + ", " + d.status();
        d.stop(0);
        row("openhaptics", true, s);
      } catch (const InputError& e) {
        row("openhaptics", false, e.what());
      }
    }
    // Haply Inverse3 (Inverse Service).
#ifdef GSHAPTICS_HAVE_VIEWER
    {
      HaplyParams p;
      const std::string u = *haply_url;
      const std::size_t a = u.find("://"), colon = u.rfind(':'), slash = u.find('/', a == std::string::npos ? 0 : a + 3);
      if (a != std::string::npos && colon != std::string::npos && colon > a) {
        p.host = u.substr(a + 3, colon - a - 3);
        try {
          p.port = std::stoi(u.substr(colon + 1, slash == std::string::npos ? std::string::npos : slash - colon - 1));
        } catch (...) {
          p.port = 0;
        }
        if (slash != std::string::npos) p.path = u.substr(slash);
      }
      p.connect_timeout = 1.0;
      try {
        HaplyDevice d(p);
        d.start(0);
        std::this_thread::sleep_for(std::chrono::milliseconds(300));  // one rate window
        const HaplyStats st = d.stats();
        const std::string s = fmt::format("Inverse3 {} ({}-handed) at {}, service {:.0f} Hz", d.device_id(),
                                          d.handedness().empty() ? "?" : d.handedness(), d.url(), st.rate_hz);
        d.stop(0);
        row("haply:0", true, s);
      } catch (const InputError& e) {
        row("haply[:N]", false, e.what());
      }
    }
#else
    row("haply[:N]", false, "built without the WebSocket client (Boost.Beast)");
#endif
  });
}

}  // namespace gshaptics::cli
