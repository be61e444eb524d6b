#pragma once
/// @file
/// The session layer (see world_session.h), the viewer: `gshaptics serve`, the real-time runtime
/// plus the browser viewer (docs/viewer.md). Built when the viewer is (Boost.Beast).

#include <string>
#include <vector>

#include "gshaptics/viewer/viewer_server.h"
#include "gshaptics/session/run_session.h"

namespace gshaptics::session {

/// The viewer's options beside the runtime's.
struct ServeOptions {
  RuntimeOptions run;
  std::string host = "127.0.0.1";
  int port = 8080;
  double display_rate = 30;
  std::string web_root;
  std::vector<std::string> allow_origins;
  std::string token;
  bool no_token = false;
  ViewerLimits limits;
};

/// Serves the page, the scene and the live state; runs until the run ends (--duration, a signal)
/// and writes the run's outputs. Returns the exit status (0; 1: the figure failed;
/// kExitOutputsLost). Throws InputError for bad options, a missing page or its npm packages.
int run_serve(ServeOptions o);

/// The page's folder: beside an installed binary (PREFIX/bin/gshaptics ->
/// PREFIX/share/gshaptics/web), then the configured install prefix, then the source tree; "" when
/// none has web/index.html.
[[nodiscard]] std::string find_web_root();

}  // namespace gshaptics::session
