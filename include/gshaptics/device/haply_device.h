#pragma once
/// @file
/// Haply Inverse3 through its Inverse Service: JSON over a local WebSocket, no SDK to link.
///
/// Protocol followed: the Inverse Service's simulation channel, "ws://localhost:10001", in the two
/// JSON forms its documentation gives. The form is detected from the service's first message on
/// each connection:
///   - 3.5 and later (docs.haply.co/inverseSDK/service, version 3.5.x: "WebSocket Protocol" and
///     "Control Commands"): the first message carries a top-level "session_id"; a force is
///     {"set_cursor_force": {"vector": {"x","y","z"}}}; the first command of a connection also
///     carries {"session": {"configure": {"profile": {"name": "gshaptics"}}}} (the documented
///     one-shot handshake that names the simulation in Haply Hub);
///   - 3.1-3.4 (no "session_id"; Haply's 3.1 Python tutorials and Isaac Lab's
///     isaaclab/devices/haply/se3_haply.py, v2.3.2): the force key is "values", no handshake.
/// In both, the service sends state messages
///   {"inverse3": [{"device_id": "...", "config": {"handedness": "left|right"},   (first message)
///                  "state": {"cursor_position": {"x","y","z"}, "cursor_velocity": {...}}}],
///    "wireless_verse_grip": [{"device_id": "...", "state": {"orientation": {"w","x","y","z"},
///                             "buttons": {"a": bool, "b": bool, "c": bool}}}]}
/// and expects one command per state message (lock-step: a state follows each command):
///   {"inverse3": [{"device_id": "...", "commands": {"set_cursor_force": {KEY: {"x","y","z"}}}}]}
/// with KEY "vector" (3.5) or "values" (3.1-3.4). Each device entry may carry
/// "status": {"calibrated", "ready", ...} (booleans; documented from 3.4 on).
/// Units: metres, metres per second, newtons. Frame: the service's device frame, taken as the
/// gshaptics device frame (x right, y away from the user, z up; vendor_devices.h) - this matches
/// the service's default basis as documented for desk use; a unit set to another basis in Haply
/// Hub is corrected with the workspace mapping's rotation.
///
/// Behaviour:
///   - the client runs its own I/O thread; the servo thread exchanges samples and forces with it
///     through the drivers' shared DeviceLink (wait-free; read()/write() never block);
///   - the service's rate is measured (messages per second);
///   - the link lost (service restart, no message for `read_timeout`): no new samples, so the
///     runtime's watchdog zeroes the force; the client reconnects every `reconnect_interval`,
///     and after a reconnect it sends zero force until the servo thread writes a new command;
///   - a force not refreshed by the servo thread for `command_timeout` is sent as zero;
///   - a malformed message is counted and skipped, the connection kept (a zero-force command
///     keeps the lock-step going); what was wrong with it is kept, and a start() that gets no
///     usable state names it (not JSON, no "inverse3" array, a cursor_position that is not three
///     finite numbers, ...);
///   - a state for our device without "device_id" is refused: it could never be commanded;
///   - a device whose status says it is not ready, or not calibrated (unless
///     HaplyParams::require_calibrated is false), is refused by start() with that reason; if its
///     status turns so during a run, its messages are answered with zero force (counted);
///   - stop() sends zero force, closes and joins.

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "gshaptics/device/peer_messages.h"
#include "gshaptics/device/device_registry.h"
#include "gshaptics/device/haptic_device.h"
#include "gshaptics/device/device_link.h"

namespace gshaptics {

struct HaplyParams {
  std::string host = "127.0.0.1";
  int port = 10001;         ///< the Inverse Service's WebSocket port (service 3.1)
  std::string path = "/";
  int index = 0;            ///< which Inverse3 of the service's list
  double connect_timeout = 3.0;     ///< start() waits this long for the first state, s
  double read_timeout = 0.5;        ///< no message for this long: the link is dead, s
  double reconnect_interval = 0.25; ///< s
  double command_timeout = 0.05;    ///< a force older than this is sent as zero, s
  /// Refuse force to an Inverse3 whose status says "calibrated": false (Haply Hub calibrates it).
  bool require_calibrated = true;
  std::string profile_name = "gshaptics";  ///< the session profile name sent to a 3.5 service
};

/// Counters of the link (any thread; relaxed).
struct HaplyStats {
  std::uint64_t messages = 0;    ///< state messages received
  std::uint64_t malformed = 0;   ///< messages that were not the documented JSON
  std::uint64_t commands = 0;    ///< force commands sent
  std::uint64_t connects = 0;    ///< successful (re)connections
  std::uint64_t zero_after_connect = 0;  ///< commands sent as zero because of a fresh (re)connection
  std::uint64_t stale_commands = 0;      ///< commands sent as zero: not refreshed within command_timeout
  std::uint64_t not_ready = 0;   ///< messages answered with zero force: the status said not ready / not calibrated
  /// The service's JSON form detected on the current (or last) connection: 35 (3.5+, "vector"),
  /// 31 (3.1-3.4, "values"), 0 before the first message.
  int format = 0;
  double rate_hz = 0;            ///< state messages per second, over windows of 0.25 s
  bool connected = false;
};

class HaplyDevice final : public HapticDevice {
 public:
  /// Throws InputError for an invalid port, index or timeouts.
  explicit HaplyDevice(const HaplyParams& params = {});
  ~HaplyDevice() override;
  HaplyDevice(const HaplyDevice&) = delete;
  HaplyDevice& operator=(const HaplyDevice&) = delete;

  [[nodiscard]] const DeviceInfo& info() const noexcept override { return info_; }
  /// Starts the I/O thread and waits up to connect_timeout for the first state of Inverse3
  /// number `index`. Throws InputError naming the URL and what was missing (no service, no
  /// device in its list).
  void start(Nanos now) override;
  [[nodiscard]] DeviceSample read(Nanos now) noexcept override;
  void write(const Wrench& wrench, Nanos now) noexcept override;
  void stop(Nanos now) noexcept override;

  [[nodiscard]] HaplyStats stats() const noexcept;
  /// "Inverse3 ID (HAND-handed) at URL, service 3.5 format, N Hz".
  [[nodiscard]] std::string status() const override;
  /// Reconnects and malformed messages of the session.
  [[nodiscard]] std::vector<DeviceCounter> counters() const override;
  /// The URL connected to, "ws://host:port/path".
  [[nodiscard]] std::string url() const;
  /// The Inverse3's device_id and handedness from the service's first message ("" before).
  [[nodiscard]] std::string device_id() const;
  [[nodiscard]] std::string handedness() const;

 private:
  struct Link;  // one connection's Boost.Beast state, I/O thread only
  // The I/O thread and its steps (haply_device.cpp).
  void io_main() noexcept;
  bool connect(Link& c) noexcept;
  void lock_step(Link& c) noexcept;
  void count_message() noexcept;
  bool take_state(Link& c, Eigen::Vector3d& force) noexcept;
  void say_goodbye(Link& c) noexcept;
  void set_problem(const std::string& problem);
  std::int64_t window_start_ = 0;  // the service rate's measuring window (I/O thread)
  std::uint64_t window_count_ = 0;

  HaplyParams params_;
  DeviceInfo info_;
  DeviceLink link_;  // I/O thread <-> servo thread
  std::thread io_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> have_state_{false};
  std::atomic<std::uint64_t> messages_{0}, malformed_{0}, commands_sent_{0}, connects_{0}, not_ready_{0};
  std::atomic<int> format_{0};
  std::atomic<std::int64_t> first_message_ns_{0};  // steady_ns() of the session's first message
  std::atomic<double> rate_hz_{0};
  std::atomic<bool> connected_{false};
  mutable std::mutex text_mutex_;  // the I/O thread's rare text (ids, last problem); never the servo thread
  std::string device_id_, handedness_, problem_;
};

/// Parses "ws://HOST:PORT/PATH" into `p` (host, port, path). Throws InputError naming `url`.
void parse_haply_url(const std::string& url, HaplyParams& p);

/// Adds the "haply[:N]" kind (an Inverse3 through the Haply Inverse Service) to `registry`, once.
void register_haply_device(DeviceRegistry& registry = device_registry());

}  // namespace gshaptics
