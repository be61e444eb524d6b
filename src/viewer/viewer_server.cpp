#include "gshaptics/viewer/viewer_server.h"

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <algorithm>
#include <cmath>
#include <deque>
#include <filesystem>
#include <fmt/format.h>
#include <list>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "gshaptics/error.h"
#include "gshaptics/device/peer_messages.h"

namespace gshaptics {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;

namespace {

std::string mime_type(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json" || ext == ".map") return "application/json";
  if (ext == ".wasm") return "application/wasm";
  if (ext == ".png") return "image/png";
  return "application/octet-stream";
}

void append_vec(std::string& s, const Eigen::Vector3d& v, int digits = 5) {
  s += fmt::format("[{:.{}g},{:.{}g},{:.{}g}]", v.x(), digits, v.y(), digits, v.z(), digits);
}

}  // namespace

namespace {

// Contacts: [source index, cx, cy, cz, ax, ay, az, qw, qx, qy, qz] in the world frame (an
// object's at its pose now); contacts whose world is not known are left out.
void append_contacts(std::string& s, const ContactSnapshot& contacts, const SnapshotWorlds& worlds) {
  s += fmt::format(",\"contacts_total\":{},\"contacts\":[", contacts.counts.contacts);
  bool first = true;
  for (std::uint32_t i = 0; i < contacts.shown; ++i) {
    const std::optional<ShownGaussian> g = shown_gaussian(contacts, i, worlds);
    if (!g) continue;
    const Eigen::Quaterniond& q = g->rotation;
    s += fmt::format("{}[{},{:.6g},{:.6g},{:.6g},{:.4g},{:.4g},{:.4g},{:.4f},{:.4f},{:.4f},{:.4f}]",
                     first ? "" : ",", g->source_index, g->center[0], g->center[1], g->center[2],
                     double(g->semi_axes[0]), double(g->semi_axes[1]), double(g->semi_axes[2]), q.w(), q.x(),
                     q.y(), q.z());
    first = false;
  }
  s += "]";
}

// The objects' poses: [[px, py, pz, qw, qx, qy, qz], ...] (world, m).
void append_objects(std::string& s, const ObjectPoses& poses) {
  s += ",\"objects\":[";
  for (std::uint32_t i = 0; i < poses.count; ++i) {
    const BodyPose& p = poses.poses[i];
    const Eigen::Quaterniond& q = p.rotation;
    s += fmt::format("{}[{:.7g},{:.7g},{:.7g},{:.7g},{:.7g},{:.7g},{:.7g}]", i ? "," : "", p.position.x(),
                     p.position.y(), p.position.z(), q.w(), q.x(), q.y(), q.z());
  }
  s += "]";
}

}  // namespace

std::string ViewerServer::state_json(const TickRecord& tick, const ContactSnapshot& contacts,
                                     const SnapshotWorlds& worlds, const RuntimeStats& stats,
                                     const LatencyHistogram& query, double rate_hz, const MaterialField* materials) {
  // Built by hand: this runs 30-60 times a second with up to 2048 contacts.
  std::string s;
  s.reserve(200 + std::size_t(contacts.shown) * 110);
  s += "{\"type\":\"state\",\"t\":";
  s += fmt::format("{:.4f}", tick.time);
  s += ",\"tool\":{\"center\":";
  append_vec(s, tick.position, 7);
  const Eigen::Quaterniond& q = contacts.pose.orientation;
  s += fmt::format(",\"rotation\":[{:.6g},{:.6g},{:.6g},{:.6g}]}}", q.w(), q.x(), q.y(), q.z());
  // The proxy (god-object): where the renderer holds the tool; the tool's own centre without one.
  s += fmt::format(",\"proxy\":{{\"constraints\":{},\"center\":", unsigned(tick.constraints));
  append_vec(s, tick.proxy, 7);
  s += "}";
  s += ",\"force\":";
  append_vec(s, tick.force);
  s += ",\"torque\":";
  append_vec(s, tick.torque);
  s += ",\"desired\":";
  append_vec(s, tick.desired);
  s += ",\"user_force\":";
  append_vec(s, tick.user_force);
  const std::uint64_t ticks = stats.ticks.load(std::memory_order_relaxed);
  const double wall = to_seconds(stats.last_tick_ns.load() - stats.start_ns.load());
  s += fmt::format(
      ",\"counts\":{{\"candidates\":{},\"prefiltered\":{},\"contacts\":{}}},\"query_us\":{:.2f},"
      "\"flags\":{},\"stats\":{{\"ticks\":{},\"rate_hz\":{:.1f},\"set_rate_hz\":{:.0f},"
      "\"jitter_p99_us\":{:.1f},\"deadline_misses\":{},\"stale_ticks\":{},\"fades\":{},"
      "\"query_p99_us\":{:.1f}}}",
      tick.counts.candidates, tick.counts.prefiltered, tick.counts.contacts, double(tick.query_us),
      tick.flags, ticks, wall > 0 && ticks > 1 ? double(ticks - 1) / wall : 0.0, rate_hz,
      stats.jitter.percentile(99) * 1e-3, stats.deadline_misses.load(), stats.stale_ticks.load(),
      stats.fades.load(), query.percentile(99) * 1e-3);
  append_contacts(s, contacts, worlds);
  if (worlds.poses != nullptr) append_objects(s, *worlds.poses);
  // The material the shown contacts of the static scene are mostly made of (by opacity).
  // With it, what a vibrotactile device (the VR controller) plays: the texture's RMS force and
  // the material's vibration level (RenderOutput).
  if (materials != nullptr && worlds.scene != nullptr) {
    std::vector<std::uint32_t> scene_records;
    scene_records.reserve(contacts.shown);
    for (std::uint32_t i = 0; i < contacts.shown; ++i)
      if (contacts.body[i] == 0 && contacts.record[i] < worlds.scene->size()) scene_records.push_back(contacts.record[i]);
    s += fmt::format(",\"material\":\"{}\",\"vibration\":{{\"texture_rms\":{:.4g},\"level\":{:.3g}}}",
                     materials->name(materials->dominant(scene_records, *worlds.scene)), double(tick.texture_rms),
                     double(tick.vibration));
  }
  s += "}";
  return s;
}

nlohmann::json to_json(const ViewerStats& s) {
  return {{"frames_sent", s.frames_sent.load()},
          {"frames_dropped", s.frames_dropped.load()},
          {"tool_messages", s.tool_messages.load()},
          {"bad_messages", s.bad_messages.load()},
          {"clients", s.clients.load()},
          {"refused_host", s.refused_host.load()},
          {"refused_origin", s.refused_origin.load()},
          {"refused_token", s.refused_token.load()},
          {"refused_connections", s.refused_connections.load()},
          {"oversize_frames", s.oversize_frames.load()},
          {"rate_limited", s.rate_limited.load()},
          {"flood_closed", s.flood_closed.load()},
          {"idle_closed", s.idle_closed.load()}};
}

// ---------------------------------------------------------------------------------------------

struct WsSession;

struct ViewerServer::Impl {
  Impl(const ViewerConfig& c, HapticRuntime& rt, const CollisionWorld& w, ContactSnapshotObserver& o,
       StreamDevice* m, Clock& cl)
      : config(c), runtime(rt), world(w), contacts(o), mouse(m), clock(cl), acceptor(io), timer(io) {}

  void accept();
  void tick_display();
  void on_tool_message(const std::string& text);

  ViewerConfig config;
  HapticRuntime& runtime;
  const CollisionWorld& world;
  ContactSnapshotObserver& contacts;
  StreamDevice* mouse;
  Clock& clock;
  asio::io_context io;
  tcp::acceptor acceptor;
  asio::steady_timer timer;
  std::thread thread;
  std::list<std::weak_ptr<WsSession>> sessions;
  ViewerStats stats;
  TickRecord tick;
  ContactSnapshot snapshot;
  Eigen::Vector3d mouse_target = Eigen::Vector3d::Zero();
  Eigen::Quaterniond mouse_rotation = Eigen::Quaterniond::Identity();
  bool have_mouse_target = false;
  std::uint16_t bound_port = 0;
  bool stopping = false;
  std::optional<OriginPolicy> policy;
  nlohmann::json hello;  // config.hello_json parsed once (an object; empty when it is not one)
  std::uint32_t open_connections = 0;  // HTTP and WebSocket sessions alive (server thread only)
  int pose_reader = -1;       // this server's slot in config.object_poses
  ObjectPoses object_state;   // the objects' newest poses (server thread only)
  double now_s() const { return to_seconds(clock.now()); }
};

/// One WebSocket client. Keeps at most one frame queued: a newer state replaces an unsent one.
struct WsSession : std::enable_shared_from_this<WsSession> {
  WsSession(tcp::socket socket, ViewerServer::Impl& server)
      : ws(std::move(socket)), srv(server), limiter(server.config.limits.max_messages_per_s) {
    ++srv.open_connections;
  }
  ~WsSession() { --srv.open_connections; }

  void run(http::request<http::string_body> req) {
    websocket::stream_base::timeout t{};
    t.handshake_timeout = std::chrono::seconds(30);
    t.idle_timeout = std::chrono::milliseconds(std::int64_t(1000 * srv.config.limits.idle_timeout_s));
    t.keep_alive_pings = true;  // idle means a peer that answers no ping, not a quiet page
    ws.set_option(t);
    ws.read_message_max(srv.config.limits.max_frame_bytes);
    ws.async_accept(req, [self = shared_from_this()](beast::error_code ec) {
      if (ec) return;
      self->srv.stats.clients.fetch_add(1);
      self->open = true;
      self->send(std::make_shared<std::string>(self->srv.config.hello_json));
      self->read();
    });
  }
  void read() {
    ws.async_read(buffer, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        if (ec == websocket::error::message_too_big) self->srv.stats.oversize_frames.fetch_add(1);
        if (ec == beast::error::timeout) self->srv.stats.idle_closed.fetch_add(1);
        self->close();
        self->shutdown();
        return;
      }
      if (self->limiter.allow(self->srv.now_s())) {
        self->dropped_in_a_row = 0;
        self->srv.on_tool_message(beast::buffers_to_string(self->buffer.data()));
      } else {
        self->srv.stats.rate_limited.fetch_add(1);
        // A second's worth of messages over the limit in a row: a flood, not a fast page.
        if (++self->dropped_in_a_row > self->srv.config.limits.max_messages_per_s) {
          self->srv.stats.flood_closed.fetch_add(1);
          self->close();
          self->shutdown();
          return;
        }
      }
      self->buffer.consume(self->buffer.size());
      self->read();
    });
  }
  void send(std::shared_ptr<const std::string> frame) {
    if (!open) return;
    if (writing) {
      if (pending) srv.stats.frames_dropped.fetch_add(1);
      pending = std::move(frame);
      return;
    }
    write(std::move(frame));
  }
  void write(std::shared_ptr<const std::string> frame) {
    writing = true;
    ws.text(true);
    ws.async_write(asio::buffer(*frame), [self = shared_from_this(), frame](beast::error_code ec, std::size_t) {
      self->writing = false;
      if (ec) {
        self->close();
        return;
      }
      self->srv.stats.frames_sent.fetch_add(1);
      if (self->pending) self->write(std::exchange(self->pending, nullptr));
    });
  }
  void close() {
    if (!open) return;
    open = false;
    srv.stats.clients.fetch_sub(1);
  }
  void shutdown() {
    if (!ws.is_open()) return;
    beast::error_code ec;
    beast::get_lowest_layer(ws).socket().close(ec);
  }

  websocket::stream<beast::tcp_stream> ws;
  ViewerServer::Impl& srv;
  beast::flat_buffer buffer;
  std::shared_ptr<const std::string> pending;
  bool writing = false, open = false;
  MessageRateLimiter limiter;
  double dropped_in_a_row = 0;
};

/// One HTTP connection: files, the scene, the hello JSON, or an upgrade to a WebSocket.
struct HttpSession : std::enable_shared_from_this<HttpSession> {
  HttpSession(tcp::socket socket, ViewerServer::Impl& server) : stream(std::move(socket)), srv(server) {
    ++srv.open_connections;
  }
  ~HttpSession() { --srv.open_connections; }

  void read() {
    req = {};
    stream.expires_after(std::chrono::seconds(30));
    http::async_read(stream, buffer, req, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return;
      self->handle();
    });
  }

  template <class Response>
  void send(Response&& res) {
    auto sp = std::make_shared<std::decay_t<Response>>(std::forward<Response>(res));
    http::async_write(stream, *sp, [self = shared_from_this(), sp](beast::error_code ec, std::size_t) {
      if (ec || sp->need_eof()) {
        beast::error_code ignored;
        self->stream.socket().shutdown(tcp::socket::shutdown_send, ignored);
        return;
      }
      self->read();
    });
  }

  void text(http::status status, const std::string& body, const std::string& type = "text/plain") {
    http::response<http::string_body> res{status, req.version()};
    res.set(http::field::content_type, type);
    res.set(http::field::cache_control, "no-store");
    if (!set_cookie.empty()) res.set(http::field::set_cookie, set_cookie);
    res.keep_alive(req.keep_alive());
    res.body() = body;
    res.prepare_payload();
    send(std::move(res));
  }

  void file(const std::string& path) {
    beast::error_code ec;
    http::file_body::value_type body;
    body.open(path.c_str(), beast::file_mode::scan, ec);
    if (ec) {
      text(http::status::not_found, "not found\n");
      return;
    }
    const auto size = body.size();
    http::response<http::file_body> res{std::piecewise_construct, std::make_tuple(std::move(body)),
                                        std::make_tuple(http::status::ok, req.version())};
    res.set(http::field::content_type, mime_type(path));
    if (!set_cookie.empty()) res.set(http::field::set_cookie, set_cookie);
    res.content_length(size);
    res.keep_alive(req.keep_alive());
    send(std::move(res));
  }

  /// The Host check, then the token; false (with the refusal sent) when the request may not pass.
  bool admitted() {
    const std::string_view host(req[http::field::host].data(), req[http::field::host].size());
    if (!srv.policy->host_ok(host)) {
      srv.stats.refused_host.fetch_add(1);
      text(http::status::forbidden, "gshaptics: this server answers only to its own host name\n");
      return false;
    }
    if (!srv.config.token.empty()) {
      const auto sv = [this](http::field f) {
        const auto v = req[f];
        return std::string_view(v.data(), v.size());
      };
      const auto custom = req["X-Gshaptics-Token"];
      const std::string given = request_token(std::string_view(req.target().data(), req.target().size()),
                                              sv(http::field::authorization),
                                              std::string_view(custom.data(), custom.size()),
                                              sv(http::field::cookie));
      if (!constant_time_equal(given, srv.config.token)) {
        srv.stats.refused_token.fetch_add(1);
        text(http::status::unauthorized,
             "gshaptics: this server needs its access token: open the URL it printed "
             "(http://HOST:PORT/?token=...)\n");
        return false;
      }
      // The page's own requests (modules, the scene, the WebSocket) then carry it as a cookie.
      set_cookie = "gshaptics_token=" + srv.config.token + "; Path=/; HttpOnly; SameSite=Strict";
    }
    return true;
  }

  void handle() {
    set_cookie.clear();
    if (!admitted()) return;
    if (websocket::is_upgrade(req)) {
      const auto origin = req[http::field::origin];
      const auto host = req[http::field::host];
      if (!srv.policy->origin_ok(std::string_view(origin.data(), origin.size()),
                                 std::string_view(host.data(), host.size()))) {
        srv.stats.refused_origin.fetch_add(1);
        text(http::status::forbidden, "gshaptics: WebSocket from a foreign page (Origin) refused\n");
        return;
      }
      if (req.target() != "/ws") {
        text(http::status::not_found, "WebSocket endpoint is /ws\n");
        return;
      }
      auto ws = std::make_shared<WsSession>(stream.release_socket(), srv);
      srv.sessions.push_back(ws);
      ws->run(std::move(req));
      return;
    }
    if (req.method() != http::verb::get && req.method() != http::verb::head) {
      text(http::status::method_not_allowed, "GET only\n");
      return;
    }
    std::string target(req.target());
    if (const auto q = target.find('?'); q != std::string::npos) target.resize(q);
    if (target.find("..") != std::string::npos) {
      text(http::status::bad_request, "bad path\n");
      return;
    }
    if (target == "/" || target == "/index.html") return file(srv.config.web_root + "/index.html");
    if (target == "/api/hello") {
      nlohmann::json j = srv.hello;
      j["server"] = to_json(srv.stats);
      return text(http::status::ok, j.dump(), "application/json");
    }
    if (target == "/favicon.ico") return text(http::status::no_content, "");
    if (target.rfind("/object/", 0) == 0) {  // an object's splats (ViewerConfig::object_splats)
      const std::string n = target.substr(8);
      const bool digits = !n.empty() && n.size() < 4 && std::all_of(n.begin(), n.end(), [](char c) { return c >= '0' && c <= '9'; });
      if (digits && std::size_t(std::stoi(n)) < srv.config.object_splats.size())
        return text(http::status::ok, *srv.config.object_splats[std::size_t(std::stoi(n))], "application/octet-stream");
      return text(http::status::not_found, "not found\n");
    }
    if (target == "/scene") {
      if (srv.config.scene_bytes) return text(http::status::ok, *srv.config.scene_bytes, "application/octet-stream");
      return file(srv.config.scene_path);
    }
    const bool allowed = target.rfind("/node_modules/three/", 0) == 0 ||
                         target.rfind("/node_modules/@sparkjsdev/spark/", 0) == 0 ||
                         // WebXR emulation (?xr-emulate=...): IWER's self-contained build
                         target.rfind("/node_modules/iwer/build/", 0) == 0 ||
                         target == "/app.js" || target == "/xr.js" || target == "/style.css";
    if (!allowed) return text(http::status::not_found, "not found\n");
    file(srv.config.web_root + target);
  }

  beast::tcp_stream stream;
  ViewerServer::Impl& srv;
  beast::flat_buffer buffer;
  http::request<http::string_body> req;
  std::string set_cookie;
};

void ViewerServer::Impl::accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (stopping) return;
    if (!ec) {
      if (open_connections >= config.limits.max_connections) {
        stats.refused_connections.fetch_add(1);
        beast::error_code ignored;
        socket.close(ignored);
      } else {
        std::make_shared<HttpSession>(std::move(socket), *this)->read();
      }
    }
    accept();
  });
}

void ViewerServer::Impl::on_tool_message(const std::string& text) {
  // {"type":"tool","center":[x,y,z][,"rotation":[w,x,y,z]]}; anything else is counted and ignored.
  const std::optional<ViewerToolMessage> m = parse_viewer_tool_message(text);
  if (!m) {
    stats.bad_messages.fetch_add(1);
    return;
  }
  const Eigen::Vector3d c = m->center;
  const Eigen::Quaterniond q = m->rotation;
  stats.tool_messages.fetch_add(1);
  // A NaN pose is passed on: the runtime's safety layer drops and counts it.
  mouse_target = c;
  mouse_rotation = q;
  have_mouse_target = true;
  if (mouse != nullptr) mouse->set_target(c, q, clock.now());
}

void ViewerServer::Impl::tick_display() {
  if (stopping) return;
  // While a browser is connected, the mouse device is alive even when the page is too busy
  // rendering (software GL: ~1 frame/s) to send: repeat its last target. When every page is
  // gone, the targets stop and the runtime's watchdog zeroes the force.
  if (config.repeat_targets && mouse != nullptr && have_mouse_target && stats.clients.load() > 0)
    mouse->set_target(mouse_target, mouse_rotation, clock.now());
  if (runtime.latest_tick(tick)) {
    contacts.take(snapshot);
    if (config.object_poses) config.object_poses->read_if_new(pose_reader, object_state);
    const SnapshotWorlds worlds{&world, config.object_worlds, config.object_poses ? &object_state : nullptr};
    auto frame = std::make_shared<const std::string>(ViewerServer::state_json(
        tick, snapshot, worlds, runtime.stats(), runtime.worker().latency(), runtime.config().rate_hz,
        config.materials.get()));
    stats.frames_built.fetch_add(1);
    for (auto it = sessions.begin(); it != sessions.end();) {
      if (auto s = it->lock()) {
        s->send(frame);
        ++it;
      } else {
        it = sessions.erase(it);
      }
    }
  }
  timer.expires_after(std::chrono::microseconds(std::int64_t(1e6 / std::max(1.0, config.display_hz))));
  timer.async_wait([this](beast::error_code ec) {
    if (!ec) tick_display();
  });
}

ViewerServer::ViewerServer(const ViewerConfig& config, HapticRuntime& runtime, const CollisionWorld& world,
                           ContactSnapshotObserver& contacts, StreamDevice* mouse, Clock& clock)
    : impl_(std::make_unique<Impl>(config, runtime, world, contacts, mouse, clock)) {}

ViewerServer::~ViewerServer() { stop(); }

void ViewerServer::start() {
  Impl& m = *impl_;
  if (!std::filesystem::exists(m.config.web_root + "/index.html"))
    throw InputError("viewer: " + m.config.web_root + "/index.html not found (ViewerConfig::web_root)");
  beast::error_code ec;
  const auto address = asio::ip::make_address(m.config.host, ec);
  if (ec) throw InputError("viewer: bad host address '" + m.config.host + "'");
  const tcp::endpoint ep{address, m.config.port};
  m.acceptor.open(ep.protocol(), ec);
  if (!ec) m.acceptor.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) m.acceptor.bind(ep, ec);
  if (!ec) m.acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec)
    throw InputError(fmt::format("viewer: cannot listen on {}:{}: {}", m.config.host, m.config.port, ec.message()));
  m.bound_port = m.acceptor.local_endpoint().port();
  m.policy.emplace(m.config.host, m.bound_port, m.config.allow_origins);
  if (m.config.object_poses) {
    m.pose_reader = m.config.object_poses->subscribe();
    if (m.pose_reader < 0) throw InputError("viewer: the objects' pose channel has no reader slot left");
  }
  m.hello = nlohmann::json::parse(m.config.hello_json, nullptr, false);
  if (m.hello.is_discarded() || !m.hello.is_object()) m.hello = nlohmann::json::object();
  m.accept();
  m.tick_display();
  m.thread = std::thread([&m] { m.io.run(); });
}

void ViewerServer::stop() {
  Impl& m = *impl_;
  if (!m.thread.joinable()) return;
  asio::post(m.io, [&m] {
    m.stopping = true;
    beast::error_code ec;
    m.acceptor.close(ec);
    m.timer.cancel();
    for (auto& w : m.sessions)
      if (auto s = w.lock()) s->shutdown();
    m.io.stop();  // idle keep-alive HTTP connections would otherwise hold run() for their timeout
  });
  m.thread.join();
}

std::uint16_t ViewerServer::port() const noexcept { return impl_->bound_port; }
const ViewerStats& ViewerServer::stats() const noexcept { return impl_->stats; }

}  // namespace gshaptics
