#pragma once
/// @file
/// The JSON messages that peers send the process over a WebSocket: a viewer page's tool pose, and
/// the Haply Inverse Service's state. Pure functions, so the rules are tested (and fuzzed, fuzz/)
/// on their own, away from the sockets.
///
/// Every function here reads text that another program wrote and never throws, whatever the text
/// is: a message that is not the documented JSON is reported as malformed and the caller counts
/// and skips it. (They run on I/O threads, where an escaped exception ends the whole process,
/// haptic loop included: nlohmann's value() and get() throw on a field of the wrong type, so
/// every field is type-checked before it is read.)

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace gshaptics {

/// A viewer page's tool pose: {"type":"tool","center":[x,y,z][,"rotation":[w,x,y,z]]}
/// (world frame, world units; the rotation unit, w first). The centre may hold NaN or Inf
/// (JSON has no such numbers, but a huge one overflows to Inf): the runtime's safety layer
/// drops and counts such a pose.
struct ViewerToolMessage {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  ///< normalised; identity when absent
};

/// Parses a viewer page's message; nullopt when it is not a tool message of the form above
/// (not JSON, another type, a centre that is not three numbers, a rotation that is not four
/// finite numbers of norm >= 1e-6). Never throws.
[[nodiscard]] std::optional<ViewerToolMessage> parse_viewer_tool_message(std::string_view text) noexcept;

/// One Inverse3 cursor sample (the service's device frame, m, m/s).
struct HaplySample {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< zero when the message has no cursor_velocity
  /// The first wireless VerseGrip's orientation (w, x, y, z; normalised) when it sends four
  /// finite numbers of norm > 0.5; otherwise identity.
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  std::uint32_t buttons = 0;  ///< VerseGrip buttons a, b, c as bits 0, 1, 2 (a button that is not `true` is up)
};

/// What one Haply Inverse Service state message says about Inverse3 number `index`
/// (haply_device.h has the protocol).
struct HaplyStateMessage {
  /// The documented form: an object whose "inverse3" array holds an object at `index` with
  /// state.cursor_position {x,y,z} (and, if present, cursor_velocity {x,y,z}) finite numbers;
  /// or an "inverse3" array too short for `index` (see devices_listed). False: malformed.
  bool valid = false;
  /// The "inverse3" array's length when it is shorter than index + 1 (the service lists no such
  /// device: a valid message with no sample); otherwise -1.
  long devices_listed = -1;
  HaplySample sample;  ///< read when `valid` and our device is listed
  /// The device's "device_id" (a string as is; another JSON value as its text) when present.
  std::optional<std::string> device_id;
  std::string handedness;  ///< config.handedness when it is a string, else empty
  /// The message has a top-level "session_id" (Inverse Service 3.5 and later put one in every
  /// connection's first message; 3.1-3.4 have none). Its value is not interpreted.
  bool has_session_id = false;
  /// The device's status.calibrated / status.ready: 1 true, 0 false, -1 absent or not a boolean
  /// (services before 3.4 may send no status).
  int calibrated = -1;
  int ready = -1;
  /// Why the message is malformed, for people ("not JSON", "no \"inverse3\" array", ...);
  /// empty when valid. A static string.
  const char* problem = "";
};

/// Parses one state message for Inverse3 number `index` (>= 0). Never throws.
[[nodiscard]] HaplyStateMessage parse_haply_state(std::string_view text, int index) noexcept;

}  // namespace gshaptics
