#pragma once
/// @file
/// The viewer's HTTP + WebSocket server (Boost.Beast): serves the page, its npm packages and the
/// ORIGINAL scene file, and streams the runtime's state to every browser at a display rate,
/// decoupled from the servo loop (a slow browser drops frames; it never slows a tick). Browsers
/// may steer a StreamDevice (the mouse/keyboard device).
///
/// Protocol (JSON text frames on ws://HOST:PORT/ws; documented in docs/viewer_protocol.md):
///   server -> client, once: {"type":"hello", scene, registration, tool, force limit, bounds...}
///   server -> client, at display rate: {"type":"state", tool pose, force, counts, stats, contacts}
///   client -> server: {"type":"tool","center":[x,y,z][,"rotation":[w,x,y,z]]} (the mouse or XR
///   controller device; also a keep-alive)
///
/// Threading contract: all network work runs on one server thread started by start(); it is
/// the single reader of HapticRuntime::latest_tick() and ContactSnapshotObserver::take(), and
/// the single producer of StreamDevice::set_target(). stop() joins it.

#include <cstdint>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "gshaptics/viewer/viewer_security.h"

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/force/material.h"
#include "gshaptics/net/contact_snapshot.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/device/stream_device.h"

namespace gshaptics {

struct ViewerConfig {
  std::string host = "127.0.0.1";
  std::uint16_t port = 8080;  ///< 0: any free port (see ViewerServer::port())
  std::string web_root;       ///< folder with index.html, app.js and node_modules/
  std::string scene_path;     ///< the original scene file, served at /scene
  /// When set, served at /scene instead of the file: the scene re-packed in a form the page's
  /// splat renderer reads (spz_as_gzip for SPZ v4).
  std::shared_ptr<const std::string> scene_bytes;
  double display_hz = 30;     ///< state frames per second
  /// Sent once in the hello message: scene format, registration, tool, limits, bounds.
  std::string hello_json = "{}";
  /// Pages at these exact Origins may open the WebSocket too ("http://lab-pc:8080"); the page
  /// this server serves always may (OriginPolicy).
  std::vector<std::string> allow_origins;
  /// When not empty, every request must carry it (request_token: query, header or cookie);
  /// compared in constant time. `gshaptics serve` makes one off loopback.
  std::string token;
  ViewerLimits limits;
  /// With a material map (--materials): each state frame names the material of the shown
  /// contacts ("material"); the hello carries the map's regions (serve_session).
  std::shared_ptr<const MaterialField> materials;
  /// While a page is connected, re-send the steered device's last target at the display rate
  /// (the mouse device: a page busy rendering still holds the tool). false for a tracked device
  /// (a VR controller): when its page stops reporting, the device times out and the force fades.
  bool repeat_targets = true;
  /// Rigid objects (--object, issue 72): each one's Gaussians as .splat bytes in the world frame
  /// at rest, served at /object/I (the hello lists them); their body-frame worlds, to draw their
  /// contacts; the channel their live poses come through (the server subscribes once). Each
  /// state frame then carries every object's pose ("objects").
  std::vector<std::shared_ptr<const std::string>> object_splats;
  std::vector<std::shared_ptr<const CollisionWorld>> object_worlds;
  std::shared_ptr<ObjectPoseChannel> object_poses;
};

/// Counters of the server (any thread may read).
struct ViewerStats {
  std::atomic<std::uint64_t> frames_built{0};
  std::atomic<std::uint64_t> frames_sent{0};
  std::atomic<std::uint64_t> frames_dropped{0};  ///< a client was still busy with the last one
  std::atomic<std::uint64_t> tool_messages{0};
  std::atomic<std::uint64_t> bad_messages{0};
  std::atomic<std::uint32_t> clients{0};
  // Refusals and limit breaches (every one counted; none reaches the runtime).
  std::atomic<std::uint64_t> refused_host{0};         ///< Host header not this server (403)
  std::atomic<std::uint64_t> refused_origin{0};       ///< WebSocket from a foreign Origin (403)
  std::atomic<std::uint64_t> refused_token{0};        ///< missing or wrong token (401)
  std::atomic<std::uint64_t> refused_connections{0};  ///< over ViewerLimits::max_connections
  std::atomic<std::uint64_t> oversize_frames{0};      ///< over max_frame_bytes: connection closed
  std::atomic<std::uint64_t> rate_limited{0};         ///< messages over max_messages_per_s, dropped
  std::atomic<std::uint64_t> flood_closed{0};         ///< connections closed for a sustained flood
  std::atomic<std::uint64_t> idle_closed{0};          ///< peers silent past idle_timeout_s
};

/// The counters as JSON (the summary's and /api/hello's "server" object).
[[nodiscard]] nlohmann::json to_json(const ViewerStats& stats);

class ViewerServer {
 public:
  /// `mouse` may be null (the runtime's device is not steered from the page).
  ViewerServer(const ViewerConfig& config, HapticRuntime& runtime, const CollisionWorld& world,
               ContactSnapshotObserver& contacts, StreamDevice* mouse, Clock& clock);
  ~ViewerServer();
  ViewerServer(const ViewerServer&) = delete;
  ViewerServer& operator=(const ViewerServer&) = delete;

  /// Binds and starts the server thread. Throws InputError when the address cannot be bound
  /// (port in use, bad host) or web_root has no index.html. Every request passes the Host check,
  /// then the token (when set); WebSocket upgrades also the Origin check (OriginPolicy).
  void start();
  /// Stops accepting, closes connections, joins the thread.
  void stop();
  /// The bound port (after start()).
  [[nodiscard]] std::uint16_t port() const noexcept;
  [[nodiscard]] const ViewerStats& stats() const noexcept;

  /// The state frame for a tick record and a contact snapshot (exposed for tests). `worlds`: the
  /// worlds the snapshot's contacts index, with the objects' poses now; with poses, the frame
  /// lists each object's pose as [px, py, pz, qw, qx, qy, qz] (world, m) under "objects".
  [[nodiscard]] static std::string state_json(const TickRecord& tick, const ContactSnapshot& contacts,
                                              const SnapshotWorlds& worlds, const RuntimeStats& stats,
                                              const LatencyHistogram& query, double rate_hz,
                                              const MaterialField* materials = nullptr);
  /// The same for a scene without objects.
  [[nodiscard]] static std::string state_json(const TickRecord& tick, const ContactSnapshot& contacts,
                                              const CollisionWorld& world, const RuntimeStats& stats,
                                              const LatencyHistogram& query, double rate_hz,
                                              const MaterialField* materials = nullptr) {
    return state_json(tick, contacts, SnapshotWorlds{&world, {}, nullptr}, stats, query, rate_hz, materials);
  }

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace gshaptics
