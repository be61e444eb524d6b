// `gshaptics serve [SCENE]`: the real-time runtime plus the browser viewer. Serves the page, the
// original scene file and a WebSocket stream of the tool, the touched Gaussians and the force;
// with --device mouse the page steers the tool.

#include <cstdint>
#include <memory>

#include "commands.h"
#include "gshaptics/session/serve_session.h"
#include "options.h"

namespace gshaptics::cli {

void register_serve(CLI::App& app) {
  auto o = std::make_shared<ServeOptions>();
  o->run.device = "mouse";
  CLI::App* cmd = app.add_subcommand(
      "serve",
      "Real-time runtime plus the browser viewer: serves http://HOST:PORT/ with the original "
      "scene (Spark on three.js), the tool ellipsoid at its live pose, the colliding Gaussians, "
      "the force arrow, live counters and a scrolling plot; --device mouse (default) lets the "
      "page steer the tool (drag the tool, arrows/WASD/QE keys). Ctrl-C stops and writes the run's "
      "log and summary like `run`.");
  add_runtime_options(*cmd, o->run,
                      "mouse: the tool follows the browser (drag, keys); xr: the VR controller of "
                      "the page's WebXR session (vibration as feedback)" + registry_device_help(false) + " (`gshaptics devices`)");
  add_object_option(*cmd, o->run.scene);
  cmd->add_option("--host", o->host, "Address to listen on (127.0.0.1: this machine only)")->capture_default_str();
  cmd->add_option("--port", o->port, "HTTP/WebSocket port (0: any free port)")->capture_default_str()
      ->check(CLI::Range(0, 65535));
  cmd->add_option("--display-rate", o->display_rate, "State frames per second to each browser")
      ->capture_default_str()->check(check::range(1.0, 120.0));
  cmd->add_option("--web-root", o->web_root,
                  "Folder of the page (default: share/gshaptics/web beside an installed binary, else the source tree's web/)");
  cmd->add_option("--allow-origin", o->allow_origins,
                  "Also let pages at this exact Origin open the WebSocket (http://HOST:PORT; repeatable)");
  cmd->add_option("--token", o->token,
                  "Access token every request must carry (?token=, header or cookie). Default: none "
                  "on loopback; a random one, printed in the URL, on any other --host");
  cmd->add_flag("--no-token", o->no_token, "Off loopback, serve without a token (anyone on the network may steer the tool)");
  cmd->add_option("--max-connections", o->limits.max_connections, "Open HTTP/WebSocket connections at most")
      ->capture_default_str()->check(CLI::Range(1, 10000));
  cmd->add_option("--max-message-rate", o->limits.max_messages_per_s, "Messages per second per WebSocket at most")
      ->capture_default_str()->check(check::range(1.0, 100000.0));
  cmd->add_option("--max-frame-bytes", o->limits.max_frame_bytes, "Largest WebSocket message a client may send")
      ->capture_default_str()->check(CLI::Range(64, 1 << 20));
  cmd->add_option("--idle-timeout", o->limits.idle_timeout_s, "Close a WebSocket peer that answers no ping this long, s")
      ->capture_default_str()->check(check::range(1.0, 3600.0));
  cmd->callback([o] {
    if (const int rc = run_serve(*o)) set_exit_code(rc);
  });
}

}  // namespace gshaptics::cli
