#include "gshaptics/viewer/viewer_security.h"

#include <algorithm>
#include <cctype>
#include <fmt/format.h>
#include <random>

namespace gshaptics {

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return out;
}

std::string trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string_view::npos) return "";
  const auto e = s.find_last_not_of(" \t");
  return std::string(s.substr(b, e - b + 1));
}

// "host:port" for a host that may be an IPv6 address.
std::string host_port(const std::string& host, std::uint16_t port) {
  const bool v6 = host.find(':') != std::string::npos && host.front() != '[';
  return fmt::format("{}{}{}:{}", v6 ? "[" : "", host, v6 ? "]" : "", port);
}

}  // namespace

bool is_loopback_host(std::string_view host) {
  const std::string h = lower(host);
  return h == "localhost" || h == "::1" || h == "[::1]" || h.rfind("127.", 0) == 0;
}

OriginPolicy::OriginPolicy(std::string bind_host, std::uint16_t port, std::vector<std::string> allow_origins)
    : bind_(lower(bind_host)), port_(port) {
  any_host_ = bind_ == "0.0.0.0" || bind_ == "::" || bind_ == "[::]";
  for (const char* h : {"127.0.0.1", "localhost", "::1"}) hosts_.push_back(host_port(h, port));
  if (!is_loopback_host(bind_) && !any_host_) hosts_.push_back(host_port(bind_, port));
  for (const std::string& o : allow_origins) {
    origins_.push_back(lower(o));
    const auto scheme = o.find("://");
    if (scheme != std::string::npos) hosts_.push_back(lower(o.substr(scheme + 3)));
  }
}

bool OriginPolicy::host_ok(std::string_view host_header) const {
  const std::string h = lower(trim(host_header));
  if (h.empty()) return false;
  if (any_host_) return true;
  // A loopback name without a port (non-browser clients send that) cannot be a rebound name.
  if (h == "127.0.0.1" || h == "localhost" || h == "[::1]") return true;
  // "host" without a port means port 80.
  for (const std::string& ok : hosts_)
    if (h == ok || (port_ == 80 && h + ":80" == ok)) return true;
  return false;
}

bool OriginPolicy::origin_ok(std::string_view origin, std::string_view host_header) const {
  const std::string o = lower(trim(origin));
  if (o.empty()) return true;
  if (o == "http://" + lower(trim(host_header)) && host_ok(host_header)) return true;
  return std::find(origins_.begin(), origins_.end(), o) != origins_.end();
}

std::string make_access_token() {
  std::random_device rd;
  std::string t;
  for (int i = 0; i < 4; ++i) t += fmt::format("{:08x}", std::uint32_t(rd()));
  return t;
}

std::string request_token(std::string_view target, std::string_view authorization,
                          std::string_view token_header, std::string_view cookie) {
  if (const auto q = target.find('?'); q != std::string_view::npos) {
    std::string_view query = target.substr(q + 1);
    while (!query.empty()) {
      const auto amp = query.find('&');
      const std::string_view item = query.substr(0, amp);
      if (item.rfind("token=", 0) == 0) return std::string(item.substr(6));
      if (amp == std::string_view::npos) break;
      query.remove_prefix(amp + 1);
    }
  }
  const std::string auth = trim(authorization);
  if (lower(auth.substr(0, 6)) == "token ") return trim(std::string_view(auth).substr(6));
  if (!trim(token_header).empty()) return trim(token_header);
  std::string_view c = cookie;
  while (!c.empty()) {
    const auto semi = c.find(';');
    const std::string item = trim(c.substr(0, semi));
    if (item.rfind("gshaptics_token=", 0) == 0) return item.substr(16);
    if (semi == std::string_view::npos) break;
    c.remove_prefix(semi + 1);
  }
  return "";
}

bool MessageRateLimiter::allow(double now_s) {
  if (last_s_ >= 0) tokens_ = std::min(rate_, tokens_ + (now_s - last_s_) * rate_);
  last_s_ = now_s;
  if (tokens_ < 1.0) return false;
  tokens_ -= 1.0;
  return true;
}

}  // namespace gshaptics
