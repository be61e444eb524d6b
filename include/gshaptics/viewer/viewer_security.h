#pragma once
/// @file
/// Who may talk to the viewer server: the Host and Origin checks that stop DNS rebinding and
/// cross-site WebSocket hijacking, the access token required off loopback, and the limits on what
/// one client may send. Pure functions, so each rule is tested on its own.
///
/// The rules follow the usual defences for local web servers: a request is served only when its
/// Host names this server (a rebound DNS name does not), a WebSocket upgrade only when its Origin
/// is the page this server served (or an --allow-origin entry), and off loopback only with a
/// token (random by default and printed in the URL, as Jupyter does).

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace gshaptics {

/// Per-connection and per-server limits. Every breach is counted (ViewerStats) and visible in the
/// run summary and in /api/hello.
struct ViewerLimits {
  std::size_t max_frame_bytes = 4096;   ///< largest WebSocket message a client may send
  double max_messages_per_s = 200;      ///< per connection; the page sends 30
  std::uint32_t max_connections = 32;   ///< open TCP connections (HTTP and WebSocket)
  double idle_timeout_s = 30;           ///< a WebSocket peer that answers no ping this long is closed
};

/// True for an address on this machine only: 127.0.0.0/8, ::1, "localhost".
[[nodiscard]] bool is_loopback_host(std::string_view host);

/// The Host and Origin rules of a server bound to `bind_host`:`port`.
class OriginPolicy {
 public:
  /// `allow_origins`: extra exact Origins ("http://lab-pc:8080") whose pages may open the
  /// WebSocket. Their host:port is also accepted as a Host header.
  OriginPolicy(std::string bind_host, std::uint16_t port, std::vector<std::string> allow_origins = {});

  /// A Host header this server answers: 127.0.0.1 / localhost / [::1] with this port or none;
  /// bound to one other address, that address with this port too; bound to every address (0.0.0.0, ::),
  /// any host (the token is then the protection). Empty: refused.
  [[nodiscard]] bool host_ok(std::string_view host_header) const;
  /// An Origin a WebSocket upgrade may come from: absent (not a browser: a browser always sends
  /// one), "http://" + the request's own Host (the page this server served), or an allowed one.
  [[nodiscard]] bool origin_ok(std::string_view origin, std::string_view host_header) const;

 private:
  std::string bind_;
  std::uint16_t port_;
  bool any_host_;
  std::vector<std::string> hosts_;  // accepted Host values, lower case
  std::vector<std::string> origins_;
};

/// A random access token: 32 hex digits (128 bits) from std::random_device.
[[nodiscard]] std::string make_access_token();

/// Compares two byte strings in time that depends only on their lengths, never on where they
/// first differ (no early exit): every byte of `expected` is read whatever `given` holds.
template <class A, class B>
[[nodiscard]] bool constant_time_equal(const A& given, const B& expected) {
  const std::size_t n = expected.size();
  const std::size_t m = given.size();
  unsigned diff = unsigned(n ^ m) != 0 ? 1u : 0u;
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char g = i < m ? static_cast<unsigned char>(given[i]) : 0;
    diff |= unsigned(g ^ static_cast<unsigned char>(expected[i]));
  }
  return diff == 0;
}

/// The token a request carries, from (in this order) the query parameter `token`, the header
/// `Authorization: token T` or `X-Gshaptics-Token: T`, or the cookie `gshaptics_token`. Empty
/// when none. `target` is the request target with its query, `cookie` the Cookie header.
[[nodiscard]] std::string request_token(std::string_view target, std::string_view authorization,
                                        std::string_view token_header, std::string_view cookie);

/// A token bucket: at most `rate` messages per second on average, bursts of `rate` (one second).
class MessageRateLimiter {
 public:
  explicit MessageRateLimiter(double rate) : rate_(rate), tokens_(rate) {}
  /// True when a message arriving at `now_s` (seconds, monotonic) is within the limit.
  bool allow(double now_s);

 private:
  double rate_, tokens_;
  double last_s_ = -1;
};

}  // namespace gshaptics
