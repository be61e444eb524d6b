#include "gshaptics/device/peer_messages.h"

#include <nlohmann/json.hpp>

#include <cmath>

namespace gshaptics {

using json = nlohmann::json;

namespace {

// The member `key` of object `j`, or nullptr (no member, or `j` is not an object). Unlike
// operator[] on a const json (undefined for a missing key) and value() (throws on a type
// mismatch), this never fails.
const json* member(const json& j, const char* key) noexcept {
  if (!j.is_object()) return nullptr;
  const auto it = j.find(key);
  return it == j.end() ? nullptr : &*it;
}

// `n` numbers of array `j` into out[0..n); false unless `j` is an array of exactly n numbers.
bool numbers(const json* j, std::size_t n, double* out) noexcept {
  if (j == nullptr || !j->is_array() || j->size() != n) return false;
  for (std::size_t i = 0; i < n; ++i) {
    const json& v = (*j)[i];
    if (!v.is_number()) return false;
    out[i] = v.get<double>();
  }
  return true;
}

// Members x, y, z of object `j` (numbers, all finite) into `out`.
bool finite_xyz(const json* j, Eigen::Vector3d& out) noexcept {
  const char* keys[] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i) {
    const json* v = j == nullptr ? nullptr : member(*j, keys[i]);
    if (v == nullptr || !v->is_number()) return false;
    out[i] = v->get<double>();
  }
  return out.allFinite();
}

json parse_or_discard(std::string_view text) noexcept {
  try {
    // allow_exceptions = false: a syntax error gives a discarded value, not an exception; what
    // is left to throw is std::bad_alloc (the callers bound the message size).
    return json::parse(text.begin(), text.end(), nullptr, /*allow_exceptions=*/false);
  } catch (...) {
    return json(json::value_t::discarded);
  }
}

}  // namespace

std::optional<ViewerToolMessage> parse_viewer_tool_message(std::string_view text) noexcept {
  const json j = parse_or_discard(text);
  const json* type = member(j, "type");
  if (type == nullptr || !type->is_string() || type->get_ref<const std::string&>() != "tool") return std::nullopt;
  ViewerToolMessage m;
  double c[3];
  if (!numbers(member(j, "center"), 3, c)) return std::nullopt;
  m.center = Eigen::Vector3d(c[0], c[1], c[2]);
  if (const json* r = member(j, "rotation")) {  // a tracked controller's orientation, w first
    double q[4];
    if (!numbers(r, 4, q)) return std::nullopt;
    const Eigen::Quaterniond rot(q[0], q[1], q[2], q[3]);
    if (!rot.coeffs().allFinite() || !(rot.norm() >= 1e-6)) return std::nullopt;
    m.rotation = rot.normalized();
  }
  return m;
}

HaplyStateMessage parse_haply_state(std::string_view text, int index) noexcept {
  HaplyStateMessage m;
  const json j = parse_or_discard(text);
  const auto bad = [&m](const char* why) -> HaplyStateMessage& {
    m.problem = why;
    return m;
  };
  if (j.is_discarded()) return bad("not JSON");
  const json* inverse3 = member(j, "inverse3");
  if (inverse3 == nullptr || !inverse3->is_array() || index < 0) return bad("no \"inverse3\" array");
  m.has_session_id = member(j, "session_id") != nullptr;
  if (std::size_t(index) >= inverse3->size()) {  // a valid message without our device
    m.valid = true;
    m.devices_listed = long(inverse3->size());
    return m;
  }
  const json& device = (*inverse3)[std::size_t(index)];
  if (!device.is_object()) return bad("the \"inverse3\" entry is not an object");
  if (const json* id = member(device, "device_id")) {
    try {
      m.device_id = id->is_string() ? id->get<std::string>()
                                    : id->dump(-1, ' ', false, json::error_handler_t::replace);
    } catch (...) {  // std::bad_alloc only
      m.device_id.reset();
    }
  }
  if (const json* config = member(device, "config")) {
    const json* hand = member(*config, "handedness");
    if (hand != nullptr && hand->is_string()) m.handedness = hand->get_ref<const std::string&>();
  }
  if (const json* status = member(device, "status")) {
    const auto flag = [status](const char* key) {
      const json* v = member(*status, key);
      return v != nullptr && v->is_boolean() ? int(v->get<bool>()) : -1;
    };
    m.calibrated = flag("calibrated");
    m.ready = flag("ready");
  }
  const json* state = member(device, "state");
  if (!finite_xyz(state == nullptr ? nullptr : member(*state, "cursor_position"), m.sample.position))
    return bad("no state.cursor_position of three finite numbers x, y, z");
  if (const json* v = member(*state, "cursor_velocity"); v != nullptr && !finite_xyz(v, m.sample.velocity))
    return bad("state.cursor_velocity is not three finite numbers x, y, z");
  m.valid = true;
  // The first wireless VerseGrip, if any: orientation and buttons (optional; never invalidate).
  const json* grips = member(j, "wireless_verse_grip");
  if (grips == nullptr || !grips->is_array() || grips->empty()) return m;
  const json* grip_state = member((*grips)[0], "state");
  if (grip_state == nullptr) return m;
  if (const json* o = member(*grip_state, "orientation")) {
    const char* keys[] = {"w", "x", "y", "z"};
    double q[4];
    bool ok = true;
    for (int i = 0; i < 4 && ok; ++i) {
      const json* v = member(*o, keys[i]);
      ok = v != nullptr && v->is_number();
      if (ok) q[i] = v->get<double>();
    }
    if (ok) {
      const Eigen::Quaterniond rot(q[0], q[1], q[2], q[3]);
      if (rot.coeffs().allFinite() && rot.norm() > 0.5) m.sample.orientation = rot.normalized();
    }
  }
  if (const json* buttons = member(*grip_state, "buttons")) {
    const char* names[] = {"a", "b", "c"};
    for (std::uint32_t b = 0; b < 3; ++b) {
      const json* v = member(*buttons, names[b]);
      if (v != nullptr && v->is_boolean() && v->get<bool>()) m.sample.buttons |= 1u << b;
    }
  }
  return m;
}

}  // namespace gshaptics
