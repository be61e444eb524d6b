#include "gshaptics/device/haply_device.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>

#include "gshaptics/error.h"
#include "gshaptics/device/peer_messages.h"

namespace gshaptics {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using tcp = net::ip::tcp;
using json = nlohmann::json;

namespace {

/// Runs `ioc` until `done` or `seconds` pass or `stop`; true when done.
bool run_until(net::io_context& ioc, const bool& done, double seconds, const std::atomic<bool>& stop) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!done && !stop.load(std::memory_order_relaxed) && std::chrono::steady_clock::now() < end) {
    ioc.run_for(std::chrono::milliseconds(5));
    if (ioc.stopped()) ioc.restart();
  }
  return done;
}

/// One set_cursor_force command for `id` in the service's form: "vector" for 3.5 (`format` 35),
/// "values" for 3.1-3.4; with the 3.5 session handshake naming profile `*handshake` when given.
std::string force_command(const std::string& id, const Eigen::Vector3d& f, int format, const std::string* handshake) {
  const auto quote = [](const std::string& t) { return json(t).dump(-1, ' ', false, json::error_handler_t::replace); };
  const std::string quoted = quote(id);
  const char* key = format == 35 ? "vector" : "values";
  const std::string session =
      handshake != nullptr ? fmt::format(R"("session":{{"configure":{{"profile":{{"name":{}}}}}}},)", quote(*handshake))
                           : std::string();
  return fmt::format(R"({{{}"inverse3":[{{"device_id":{},"commands":{{"set_cursor_force":{{"{}":{{"x":{},"y":{},"z":{}}}}}}}}}]}})",
                     session, quoted, key, f.x(), f.y(), f.z());
}

}  // namespace

HaplyDevice::HaplyDevice(const HaplyParams& params) : params_(params), link_(params.command_timeout) {
  if (params.port <= 0 || params.port > 65535) throw InputError(fmt::format("haply: port {} is not a TCP port", params.port));
  if (params.index < 0) throw InputError(fmt::format("--device haply:{}: the index must be >= 0", params.index));
  for (double t : {params.connect_timeout, params.read_timeout, params.reconnect_interval, params.command_timeout})
    if (!(t > 0) || !std::isfinite(t)) throw InputError("haply: timeouts must be finite and > 0");
  info_.name = fmt::format("haply:{} ({})", params.index, url());
  info_.max_rate_hz = 10000;
}

HaplyDevice::~HaplyDevice() { stop(0); }

std::string HaplyDevice::url() const { return fmt::format("ws://{}:{}{}", params_.host, params_.port, params_.path); }

std::string HaplyDevice::device_id() const {
  std::lock_guard<std::mutex> lock(text_mutex_);
  return device_id_;
}
std::string HaplyDevice::handedness() const {
  std::lock_guard<std::mutex> lock(text_mutex_);
  return handedness_;
}

HaplyStats HaplyDevice::stats() const noexcept {
  HaplyStats s;
  s.messages = messages_.load(std::memory_order_relaxed);
  s.malformed = malformed_.load(std::memory_order_relaxed);
  s.commands = commands_sent_.load(std::memory_order_relaxed);
  s.connects = connects_.load(std::memory_order_relaxed);
  s.zero_after_connect = link_.zeroed_before();
  s.stale_commands = link_.stale_commands();
  s.rate_hz = rate_hz_.load(std::memory_order_relaxed);
  if (s.rate_hz == 0 && s.messages > 1) {  // before the first 0.25 s window: the rate so far
    const std::int64_t since = steady_ns() - first_message_ns_.load(std::memory_order_relaxed);
    if (since > 0) s.rate_hz = double(s.messages - 1) * 1e9 / double(since);
  }
  s.not_ready = not_ready_.load(std::memory_order_relaxed);
  s.format = format_.load(std::memory_order_relaxed);
  s.connected = connected_.load(std::memory_order_relaxed);
  return s;
}

void HaplyDevice::start(Nanos) {
  if (io_.joinable()) throw InputError("haply: already started");
  stop_.store(false);
  link_.begin_session();
  have_state_.store(false);
  messages_.store(0);
  rate_hz_.store(0);
  format_.store(0);
  not_ready_.store(0);
  {
    std::lock_guard<std::mutex> lock(text_mutex_);
    problem_.clear();
  }
  io_ = std::thread([this] { io_main(); });
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(params_.connect_timeout);
  while (!have_state_.load(std::memory_order_acquire) && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  if (have_state_.load(std::memory_order_acquire)) {
    // A few more messages (at most 0.1 s) so that status() can show the service's rate at once.
    const auto rate_end = std::chrono::steady_clock::now() + std::chrono::milliseconds(100);
    while (messages_.load(std::memory_order_relaxed) < 8 && std::chrono::steady_clock::now() < rate_end)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return;
  }
  std::string problem;
  {
    std::lock_guard<std::mutex> lock(text_mutex_);
    problem = problem_;
  }
  stop(0);
  throw InputError(fmt::format("--device haply:{}: no cursor state from the Inverse Service at {} within {:g} s: {}. "
                               "Start Haply Hub / the Inverse Service (it listens on port 10001), connect and "
                               "power the Inverse3, or give --haply-url.",
                               params_.index, url(), params_.connect_timeout,
                               problem.empty() ? "no answer" : problem));
}

// One connection to the Inverse Service: the Beast objects and what this connection learnt.
struct HaplyDevice::Link {
  net::io_context ioc;
  websocket::stream<beast::tcp_stream> ws{ioc};
  beast::error_code ec;
  bool done = false;       // the pending asynchronous operation completed
  std::string id;          // the Inverse3's device_id (empty: nothing to address yet)
  int format = 0;          // detected from this connection's first message
  bool handshake = false;  // the 3.5 session handshake goes with the first command
  std::int64_t connected_at = 0;
  beast::flat_buffer buffer;
  std::string out;
};

void HaplyDevice::set_problem(const std::string& p) {
  std::lock_guard<std::mutex> lock(text_mutex_);
  // A device missing from the service's list says more than the link loss that follows it
  // (without a device there is nothing to command, so the lock-step stops).
  // Likewise what was wrong with the messages says more than the timeout or loss it leads to.
  const auto protocol = [](const std::string& x) {
    return x.rfind("the service lists", 0) == 0 || x.rfind("malformed", 0) == 0 || x.rfind("the state of", 0) == 0;
  };
  if (!protocol(problem_) || protocol(p)) problem_ = p;
}

// The I/O thread: connect, run the lock-step until the link is lost or stop, and reconnect
// after reconnect_interval.
void HaplyDevice::io_main() noexcept {
  window_start_ = steady_ns();
  window_count_ = 0;
  while (!stop_.load(std::memory_order_relaxed)) {
    Link c;
    c.ws.read_message_max(1 << 20);  // a state message is ~1 KB; bounds what one message may allocate
    if (connect(c)) {
      connects_.fetch_add(1, std::memory_order_relaxed);
      connected_.store(true, std::memory_order_relaxed);
      c.connected_at = steady_ns();
      lock_step(c);
      if (stop_.load(std::memory_order_relaxed)) say_goodbye(c);
      connected_.store(false, std::memory_order_relaxed);
    }
    beast::get_lowest_layer(c.ws).close();
    c.ioc.run_for(std::chrono::milliseconds(1));  // let aborted handlers run
    if (stop_.load(std::memory_order_relaxed)) break;
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(params_.reconnect_interval);
    while (!stop_.load(std::memory_order_relaxed) && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

// TCP connect and the WebSocket handshake, each within connect_timeout; false (and the
// problem set) when either fails.
bool HaplyDevice::connect(Link& c) noexcept {
  bool ok = false;
  try {
    tcp::resolver resolver(c.ioc);
    const auto endpoints = resolver.resolve(params_.host, std::to_string(params_.port));
    c.done = false;
    beast::get_lowest_layer(c.ws).async_connect(endpoints, [&c](beast::error_code e, const tcp::endpoint&) {
      c.ec = e;
      c.done = true;
    });
    if (run_until(c.ioc, c.done, params_.connect_timeout, stop_) && !c.ec) {
      beast::get_lowest_layer(c.ws).socket().set_option(tcp::no_delay(true));
      c.done = false;
      c.ws.async_handshake(fmt::format("{}:{}", params_.host, params_.port), params_.path, [&c](beast::error_code e) {
        c.ec = e;
        c.done = true;
      });
      ok = run_until(c.ioc, c.done, params_.connect_timeout, stop_) && !c.ec;
    }
    if (!ok) set_problem(c.ec ? "connecting: " + c.ec.message() : std::string("connecting: timed out"));
  } catch (const std::exception& e) {
    set_problem(std::string("connecting: ") + e.what());
    ok = false;
  }
  return ok;
}

// The lock-step: each state message is read and answered with one command, until stop or the
// link is lost. Reads and writes are never abandoned half-way on stop (Beast allows one of each
// in flight): stop is seen between cycles, within one service period.
void HaplyDevice::lock_step(Link& c) noexcept {
  const std::atomic<bool> never{false};
  while (!stop_.load(std::memory_order_relaxed)) {
    c.done = false;
    c.buffer.consume(c.buffer.size());
    c.ws.async_read(c.buffer, [&c](beast::error_code e, std::size_t) {
      c.ec = e;
      c.done = true;
    });
    if (!run_until(c.ioc, c.done, params_.read_timeout, never) || c.ec) {
      set_problem(c.done ? "link lost: " + c.ec.message() : std::string("link lost: no message within the read timeout"));
      return;
    }
    count_message();
    Eigen::Vector3d f;
    if (!take_state(c, f)) continue;  // nothing to address yet (the service sends state regardless)
    c.out = force_command(c.id, f, c.format, c.handshake ? &params_.profile_name : nullptr);
    c.handshake = false;
    c.done = false;
    c.ws.text(true);
    c.ws.async_write(net::buffer(c.out), [&c](beast::error_code e, std::size_t) {
      c.ec = e;
      c.done = true;
    });
    if (!run_until(c.ioc, c.done, params_.read_timeout, never) || c.ec) {
      set_problem("link lost while sending: " + (c.done ? c.ec.message() : std::string("timed out")));
      return;
    }
    commands_sent_.fetch_add(1, std::memory_order_relaxed);
  }
}

// Counts a message and measures the service's rate over windows of 250 ms.
void HaplyDevice::count_message() noexcept {
  const std::int64_t t = steady_ns();
  if (messages_.fetch_add(1, std::memory_order_relaxed) == 0) first_message_ns_.store(t, std::memory_order_relaxed);
  ++window_count_;
  if (t - window_start_ >= 250'000'000) {
    rate_hz_.store(double(window_count_) * 1e9 / double(t - window_start_), std::memory_order_relaxed);
    window_start_ = t;
    window_count_ = 0;
  }
}

// Reads the state message in c.buffer (peer_messages.h: never throws): publishes the sample to
// the servo thread and gives the force to answer with, zero unless fresh and written after this
// connection, zero to a malformed message and to a device that says it is not ready (or not
// calibrated). False when there is no device_id to address the answer to.
bool HaplyDevice::take_state(Link& c, Eigen::Vector3d& f) noexcept {
  const HaplyStateMessage state = parse_haply_state(
      std::string_view(static_cast<const char*>(c.buffer.data().data()), c.buffer.data().size()), params_.index);
  bool good = state.valid;
  HaplySample s = state.sample;
  if (c.format == 0 && good) {
    c.format = state.has_session_id ? 35 : 31;
    c.handshake = c.format == 35;
    format_.store(c.format, std::memory_order_relaxed);
  }
  if (!good) set_problem(fmt::format("malformed state message: {}", state.problem));
  if (good && state.devices_listed < 0 && !state.device_id && c.id.empty()) {
    // Nothing to address commands to: refuse the device rather than run it without force.
    set_problem(fmt::format("the state of Inverse3 {} has no \"device_id\", so it cannot be commanded", params_.index));
    good = false;
  }
  if (state.devices_listed >= 0) {
    set_problem(fmt::format("the service lists {} Inverse3 device(s), none with index {}", state.devices_listed,
                            params_.index));
    s.position.setConstant(std::nan(""));  // a valid message; just no device for us: keep the link, no sample
  } else if (c.id.empty() && state.device_id) {
    c.id = *state.device_id;
    std::lock_guard<std::mutex> lock(text_mutex_);
    device_id_ = c.id;
    handedness_ = state.handedness;
  }
  // What the device says about itself (status, documented from 3.4): refused before the first
  // sample, zero force during a run.
  const bool not_ready = state.ready == 0, uncalibrated = params_.require_calibrated && state.calibrated == 0;
  const bool blocked = good && state.devices_listed < 0 && (not_ready || uncalibrated);
  const bool had_state = have_state_.load(std::memory_order_relaxed);
  if (blocked && !had_state)
    set_problem(fmt::format("the state of Inverse3 {} says it is {} (status.{} false){}", c.id.empty() ? "?" : c.id,
                            not_ready ? "not ready" : "not calibrated", not_ready ? "ready" : "calibrated",
                            not_ready ? ": check its power supply and Haply Hub"
                                      : ": calibrate it in Haply Hub (or give --haply-allow-uncalibrated)"));
  if (!good) {
    malformed_.fetch_add(1, std::memory_order_relaxed);
  } else if (s.position.allFinite() && (!blocked || had_state)) {
    link_.publish(LinkSample{s.position, s.velocity, s.orientation, s.buttons});
    have_state_.store(true, std::memory_order_release);
  }
  f = good ? link_.force_to_send(c.connected_at) : Eigen::Vector3d::Zero();
  if (blocked) {
    if (have_state_.load(std::memory_order_relaxed)) not_ready_.fetch_add(1, std::memory_order_relaxed);
    f.setZero();
  }
  return !c.id.empty();
}

// Leaving on a live link: a last zero-force command, then the WebSocket close (each within 0.2 s).
void HaplyDevice::say_goodbye(Link& c) noexcept {
  if (c.id.empty() || !c.done || c.ec) return;
  const std::atomic<bool> never{false};
  c.out = force_command(c.id, Eigen::Vector3d::Zero(), c.format, nullptr);
  bool sent = false;
  c.ws.async_write(net::buffer(c.out), [&sent](beast::error_code, std::size_t) { sent = true; });
  if (run_until(c.ioc, sent, 0.2, never)) commands_sent_.fetch_add(1, std::memory_order_relaxed);
  bool closed = false;
  c.ws.async_close(websocket::close_code::normal, [&closed](beast::error_code) { closed = true; });
  run_until(c.ioc, closed, 0.2, never);
}

DeviceSample HaplyDevice::read(Nanos now) noexcept { return link_.read(now); }

void HaplyDevice::write(const Wrench& wrench, Nanos) noexcept { link_.command(wrench.force); }

void HaplyDevice::stop(Nanos) noexcept {
  link_.command(Eigen::Vector3d::Zero());
  stop_.store(true, std::memory_order_relaxed);
  if (io_.joinable()) io_.join();
}

std::string HaplyDevice::status() const {
  const std::string id = device_id();
  if (id.empty()) return {};
  const std::string hand = handedness();
  const HaplyStats st = stats();
  return fmt::format("Inverse3 {} ({}-handed) at {}, service {} format{}", id, hand.empty() ? "?" : hand, url(),
                     st.format == 35 ? "3.5" : "3.1-3.4",
                     st.rate_hz > 0 ? fmt::format(", {:.0f} Hz", st.rate_hz) : "");
}

std::vector<DeviceCounter> HaplyDevice::counters() const {
  const HaplyStats st = stats();
  return {{"reconnects", st.connects > 0 ? st.connects - 1 : 0},
          {"malformed messages", st.malformed},
          {"stale commands sent as zero", st.stale_commands},
          {"messages answered with zero force (device not ready)", st.not_ready}};
}

void parse_haply_url(const std::string& u, HaplyParams& p) {
  const std::string scheme = "ws://";
  if (u.rfind(scheme, 0) != 0) throw InputError("--haply-url: expected ws://HOST:PORT/PATH, got '" + u + "'");
  const std::string rest = u.substr(scheme.size());
  const std::size_t slash = rest.find('/');
  const std::string hostport = rest.substr(0, slash);
  p.path = slash == std::string::npos ? "/" : rest.substr(slash);
  const std::size_t colon = hostport.rfind(':');
  p.host = hostport.substr(0, colon);
  if (colon != std::string::npos) {
    std::size_t used = 0;
    try {
      p.port = std::stoi(hostport.substr(colon + 1), &used);
    } catch (...) {
      used = 0;
    }
    if (used == 0 || used != hostport.size() - colon - 1 || p.port <= 0 || p.port > 65535)
      throw InputError("--haply-url: bad port in '" + u + "'");
  }
  if (p.host.empty()) throw InputError("--haply-url: no host in '" + u + "'");
}

void register_haply_device(DeviceRegistry& registry) {
  if (registry.find("haply") != nullptr) return;
  DeviceKind k;
  k.name = "haply";
  k.grammar = "haply[:N]";
  k.summary = "a Haply Inverse3 through the Haply Inverse Service (JSON over its local WebSocket)";
  k.hardware = true;
  k.check = [](const std::string& arg) { (void)device_index_arg("haply:" + arg, arg); };
  k.open = [](const std::string& arg, const DeviceOptions& o) -> std::unique_ptr<HapticDevice> {
    HaplyParams p;
    p.index = device_index_arg("haply:" + arg, arg);
    parse_haply_url(o.haply_url, p);
    p.require_calibrated = !o.haply_allow_uncalibrated;
    return std::make_unique<HaplyDevice>(p);
  };
  k.probe = [](const DeviceOptions& o) {
    try {
      HaplyParams p;
      parse_haply_url(o.haply_url, p);
      p.connect_timeout = 1.0;
      p.require_calibrated = !o.haply_allow_uncalibrated;
      HaplyDevice d(p);
      d.start(0);
      std::this_thread::sleep_for(std::chrono::milliseconds(300));  // one rate window
      const std::string note = describe_device(d) + ", " + d.status();
      d.stop(0);
      return std::vector<DeviceStatus>{{"haply:0", true, note}};
    } catch (const InputError& e) {
      return std::vector<DeviceStatus>{{"haply[:N]", false, e.what()}};
    }
  };
  registry.add(std::move(k));
}

}  // namespace gshaptics
