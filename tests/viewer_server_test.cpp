// The viewer server without a browser: HTTP routes, the hello and state frames over a real
// WebSocket (Boost.Beast client), the mouse device steered through the protocol into contact,
// malformed messages, and the state frame's contact encoding.

#include "gshaptics/viewer/viewer_server.h"

#include <gtest/gtest.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <thread>

#include "gshaptics/io/scene_loader.h"
#include "support/scenes.h"

namespace gshaptics {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using nlohmann::json;

struct Reply {
  int status = 0;
  std::string body, set_cookie;
};

/// One GET with chosen headers (Host defaults to 127.0.0.1:PORT, as a browser sends it).
Reply request(std::uint16_t port, const std::string& target,
              const std::vector<std::pair<std::string, std::string>>& headers = {}) {
  asio::io_context io;
  tcp::resolver resolver(io);
  beast::tcp_stream stream(io);
  stream.connect(resolver.resolve("127.0.0.1", std::to_string(port)));
  http::request<http::empty_body> req{http::verb::get, target, 11};
  req.set(http::field::host, "127.0.0.1:" + std::to_string(port));
  for (const auto& [k, v] : headers) req.set(k, v);
  http::write(stream, req);
  beast::flat_buffer buffer;
  http::response_parser<http::string_body> parser;
  parser.body_limit(64u << 20);
  http::read(stream, buffer, parser);
  beast::error_code ec;
  stream.socket().shutdown(tcp::socket::shutdown_both, ec);
  return {int(parser.get().result_int()), parser.get().body(), std::string(parser.get()[http::field::set_cookie])};
}

/// A WebSocket handshake with chosen headers: true when the server upgraded the connection.
bool ws_handshake(std::uint16_t port, const std::vector<std::pair<std::string, std::string>>& headers,
                 std::string host = "") {
  asio::io_context io;
  tcp::resolver resolver(io);
  websocket::stream<beast::tcp_stream> ws(io);
  beast::get_lowest_layer(ws).connect(resolver.resolve("127.0.0.1", std::to_string(port)));
  ws.set_option(websocket::stream_base::decorator([&headers](websocket::request_type& r) {
    for (const auto& [k, v] : headers) r.set(k, v);
  }));
  websocket::response_type res;
  beast::error_code ec;
  ws.handshake(res, host.empty() ? "127.0.0.1:" + std::to_string(port) : host, "/ws", ec);
  if (ec) return false;
  ws.close(websocket::close_code::normal, ec);
  return true;
}

class Viewer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world_ = &test::truck_world();
  }

  void SetUp() override {
    StreamDeviceParams sp;
    sp.name = "mouse";
    if (xr_) {  // as `serve --device xr` makes it
      sp.name = "xr controller";
      sp.input_timeout = 0.25;
      sp.alive_before_first_target = false;
    }
    mouse_ = std::make_unique<StreamDevice>(sp, Eigen::Vector3d(0, 0, 4));
    RuntimeConfig rc;
    rc.tool.semi_axes = Eigen::Vector3d::Constant(0.08);
    rc.safety.ramp_time = 0.05;
    rc.realtime.servo_priority = rc.realtime.worker_priority = 0;
    runtime_ = std::make_unique<HapticRuntime>(*world_, *mouse_, rc);
    snapshots_ = std::make_unique<ContactSnapshotObserver>(30, MonotonicClock::instance());
    runtime_->set_observer(snapshots_.get());
    ViewerConfig vc;
    vc.port = 0;
    vc.web_root = std::string(GSHAPTICS_SOURCE_DIR) + "/web";
    vc.scene_path = test::data_path("truck.splat");
    vc.hello_json = R"({"type":"hello","protocol":1,"scene_url":"/scene"})";
    vc.token = token_;
    vc.repeat_targets = !xr_;
    vc.object_splats = object_splats_;
    server_ = std::make_unique<ViewerServer>(vc, *runtime_, *world_, *snapshots_, mouse_.get(),
                                             MonotonicClock::instance());
    runtime_->start();
    server_->start();
  }
  void TearDown() override {
    server_->stop();
    runtime_->request_stop();
    runtime_->wait();
  }

  static const CollisionWorld* world_;
  std::string token_;
  bool xr_ = false;
  std::vector<std::shared_ptr<const std::string>> object_splats_;
  std::unique_ptr<StreamDevice> mouse_;
  std::unique_ptr<HapticRuntime> runtime_;
  std::unique_ptr<ContactSnapshotObserver> snapshots_;
  std::unique_ptr<ViewerServer> server_;
};
const CollisionWorld* Viewer::world_ = nullptr;

TEST_F(Viewer, HttpRoutes) {
  const std::uint16_t port = server_->port();
  ASSERT_NE(port, 0);
  const Reply page = request(port, "/");
  EXPECT_EQ(page.status, 200);
  EXPECT_NE(page.body.find("importmap"), std::string::npos);
  const Reply hello = request(port, "/api/hello");
  EXPECT_EQ(json::parse(hello.body)["type"], "hello");
  const Reply scene = request(port, "/scene");
  EXPECT_EQ(scene.status, 200);
  EXPECT_EQ(scene.body.size(), std::filesystem::file_size(test::data_path("truck.splat")));
  EXPECT_EQ(request(port, "/../CMakeLists.txt").status, 400);
  EXPECT_EQ(request(port, "/package.json").status, 404);  // only the page and its packages
}

TEST_F(Viewer, WebSocketHelloThenStatesAndTheMouseSteersIntoContact) {
  asio::io_context io;
  tcp::resolver resolver(io);
  websocket::stream<beast::tcp_stream> ws(io);
  beast::get_lowest_layer(ws).connect(resolver.resolve("127.0.0.1", std::to_string(server_->port())));
  ws.handshake("127.0.0.1", "/ws");
  beast::flat_buffer buf;
  ws.read(buf);
  const json hello = json::parse(beast::buffers_to_string(buf.data()));
  buf.consume(buf.size());
  EXPECT_EQ(hello["type"], "hello");

  // Steer the tool into the middle of the truck, as the page does (30 Hz, also a keep-alive).
  const auto t0 = std::chrono::steady_clock::now();
  json last;
  int states = 0;
  bool touched = false;
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(20)) {
    const double z = std::max(0.5, 1.6 - 0.05 * states);
    ws.write(asio::buffer(json{{"type", "tool"}, {"center", {0.0, 0.0, z}}}.dump()));
    ws.read(buf);
    last = json::parse(beast::buffers_to_string(buf.data()));
    buf.consume(buf.size());
    ASSERT_EQ(last["type"], "state");
    ++states;
    const double f = std::hypot(double(last["force"][0]), double(last["force"][1]), double(last["force"][2]));
    if (last["counts"]["contacts"].get<int>() > 0 && f > 0 && last["contacts"].size() > 0) {
      touched = true;
      break;
    }
  }
  ASSERT_TRUE(touched) << last.dump().substr(0, 400);
  EXPECT_GT(states, 3);
  const json& c = last["contacts"][0];
  ASSERT_EQ(c.size(), 11u);  // index, centre, semi-axes, quaternion
  EXPECT_LT(c[0].get<std::uint32_t>(), 116544u);
  EXPECT_GT(c[4].get<double>(), 0.0);
  EXPECT_LE(last["contacts"].size(), last["contacts_total"].get<std::size_t>());
  EXPECT_GT(server_->stats().tool_messages.load(), 3u);
  EXPECT_GT(last["stats"]["ticks"].get<int>(), 0);

  // A malformed message is counted and ignored; the connection stays up.
  ws.write(asio::buffer(std::string("{\"type\":\"tool\",\"center\":[1,\"x\",2]}")));
  ws.write(asio::buffer(std::string("not json")));
  // A field of the wrong type (this one used to throw out of the I/O thread and end the process).
  ws.write(asio::buffer(std::string("{\"type\":5,\"center\":[0,0,0]}")));
  ws.read(buf);
  EXPECT_EQ(json::parse(beast::buffers_to_string(buf.data()))["type"], "state");
  buf.consume(buf.size());
  const auto t1 = std::chrono::steady_clock::now();
  while (server_->stats().bad_messages.load() < 3 && std::chrono::steady_clock::now() - t1 < std::chrono::seconds(5))
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(server_->stats().bad_messages.load(), 3u);
  ws.close(websocket::close_code::normal);
}

TEST_F(Viewer, ForeignHostAndOriginAreRefused) {
  const std::uint16_t port = server_->port();
  const std::string self = "http://127.0.0.1:" + std::to_string(port);
  // DNS rebinding: the browser sends the attacker's name as Host.
  EXPECT_EQ(request(port, "/api/hello", {{"Host", "evil.example:" + std::to_string(port)}}).status, 403);
  EXPECT_EQ(request(port, "/scene", {{"Host", "evil.example"}}).status, 403);
  EXPECT_EQ(server_->stats().refused_host.load(), 2u);
  EXPECT_EQ(request(port, "/api/hello").status, 200);
  EXPECT_EQ(request(port, "/api/hello", {{"Host", "localhost:" + std::to_string(port)}}).status, 200);
  // Cross-site WebSocket hijacking: a foreign page's Origin.
  EXPECT_FALSE(ws_handshake(port, {{"Origin", "http://evil.example"}}));
  EXPECT_FALSE(ws_handshake(port, {{"Origin", "http://localhost:" + std::to_string(port)}}));  // Host is 127.0.0.1
  EXPECT_EQ(server_->stats().refused_origin.load(), 2u);
  EXPECT_TRUE(ws_handshake(port, {{"Origin", self}}));  // the page this server served
  EXPECT_TRUE(ws_handshake(port, {}));                  // not a browser
  EXPECT_FALSE(ws_handshake(port, {{"Origin", "http://evil.example"}}, "evil.example"));
  const json hello = json::parse(request(port, "/api/hello").body);
  EXPECT_EQ(hello["server"]["refused_origin"], 2);
  EXPECT_EQ(hello["server"]["refused_host"], 3);  // the last handshake fails the Host check first
}

TEST_F(Viewer, OversizeFramesFloodsAndConnectionsStayWithinTheLimits) {
  const std::uint16_t port = server_->port();
  const RuntimeStats& rs = runtime_->stats();
  const std::uint64_t ticks0 = rs.ticks.load();
  const auto t0 = std::chrono::steady_clock::now();
  asio::io_context io;
  tcp::resolver resolver(io);
  const auto open_ws = [&] {
    auto ws = std::make_unique<websocket::stream<beast::tcp_stream>>(io);
    beast::get_lowest_layer(*ws).connect(resolver.resolve("127.0.0.1", std::to_string(port)));
    ws->handshake("127.0.0.1:" + std::to_string(port), "/ws");
    return ws;
  };
  // An oversize frame closes its connection.
  {
    auto ws = open_ws();
    beast::error_code ec;
    ws->write(asio::buffer(std::string(64 * 1024, 'x')), ec);
    beast::flat_buffer buf;
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!ec && std::chrono::steady_clock::now() < until) {
      ws->read(buf, ec);
      buf.consume(buf.size());
    }
    EXPECT_TRUE(ec) << "the server kept an oversize sender";
    while (server_->stats().oversize_frames.load() == 0 && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));  // Beast closes before our handler runs
    EXPECT_EQ(server_->stats().oversize_frames.load(), 1u);
  }
  // A flood: 5000 messages as fast as possible. Over the rate they are dropped, then the
  // connection is closed; the tool never sees them.
  {
    auto ws = open_ws();
    beast::error_code ec;
    const std::string msg = json{{"type", "tool"}, {"center", {0.0, 0.0, 3.0}}}.dump();
    for (int i = 0; i < 5000 && !ec; ++i) ws->write(asio::buffer(msg), ec);
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (server_->stats().flood_closed.load() == 0 && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    EXPECT_GT(server_->stats().rate_limited.load(), 100u);
    EXPECT_EQ(server_->stats().flood_closed.load(), 1u);
    EXPECT_LE(server_->stats().tool_messages.load(), 2 * 200u + 10u);  // about one second's burst
  }
  // 100 connections: at most max_connections (32) are held, the rest refused at once.
  {
    std::vector<std::unique_ptr<beast::tcp_stream>> conns;
    for (int i = 0; i < 100; ++i) {
      auto c = std::make_unique<beast::tcp_stream>(io);
      beast::error_code ec;
      c->connect(resolver.resolve("127.0.0.1", std::to_string(port)), ec);
      conns.push_back(std::move(c));
    }
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (server_->stats().refused_connections.load() < 68 && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    EXPECT_GE(server_->stats().refused_connections.load(), 68u);
    conns.clear();
    // Capacity comes back when they close.
    const auto until2 = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    int status = 0;
    while (status != 200 && std::chrono::steady_clock::now() < until2) {
      try {
        status = request(port, "/api/hello").status;
      } catch (const std::exception&) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    }
    EXPECT_EQ(status, 200);
  }
  // The servo loop kept its rate through all of it (a window of at least 2 s around it, so the
  // figure is a rate, not the noise of a few ticks).
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(2))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double rate = double(rs.ticks.load() - ticks0) / wall;
  EXPECT_GT(rate, 0.8 * runtime_->config().rate_hz) << rate << " Hz over " << wall << " s";
}

class ViewerXr : public Viewer {
 protected:
  void SetUp() override {
    xr_ = true;
    Viewer::SetUp();
  }
};

TEST_F(ViewerXr, ControllerPoseSteersWithOrientationAndItsSilenceFadesTheForce) {
  asio::io_context io;
  tcp::resolver resolver(io);
  websocket::stream<beast::tcp_stream> ws(io);
  beast::get_lowest_layer(ws).connect(resolver.resolve("127.0.0.1", std::to_string(server_->port())));
  ws.handshake("127.0.0.1", "/ws");
  beast::flat_buffer buf;
  ws.read(buf);
  buf.consume(buf.size());
  const auto read_state = [&] {
    ws.read(buf);
    json j = json::parse(beast::buffers_to_string(buf.data()));
    buf.consume(buf.size());
    return j;
  };
  const auto force = [](const json& j) {
    return std::hypot(double(j["force"][0]), double(j["force"][1]), double(j["force"][2]));
  };
  // Before any controller pose: no data, so no force (the device is not alive).
  for (int i = 0; i < 3; ++i) EXPECT_EQ(force(read_state()), 0.0);
  // A controller pose with an orientation (w first, not normalised), at the headset's rate.
  const json rot = {2.0, 0.0, 0.0, 2.0};  // 90 degrees about z
  const auto t0 = std::chrono::steady_clock::now();
  json last;
  bool touched = false;
  for (int i = 0; std::chrono::steady_clock::now() - t0 < std::chrono::seconds(20); ++i) {
    const double z = std::max(0.5, 1.6 - 0.05 * i);
    ws.write(asio::buffer(json{{"type", "tool"}, {"center", {0.0, 0.0, z}}, {"rotation", rot}}.dump()));
    last = read_state();
    if (last["counts"]["contacts"].get<int>() > 0 && force(last) > 0) {
      touched = true;
      break;
    }
  }
  ASSERT_TRUE(touched) << last.dump().substr(0, 300);
  EXPECT_NEAR(last["tool"]["rotation"][0].get<double>(), std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(last["tool"]["rotation"][3].get<double>(), std::sqrt(0.5), 1e-6);
  // A rotation that is not a quaternion is counted and ignored.
  ws.write(asio::buffer(json{{"type", "tool"}, {"center", {0.0, 0.0, 0.5}}, {"rotation", {0, 0, 0}}}.dump()));
  // The controller stops reporting (the session ended, tracking lost) while the page stays
  // connected: the server does not repeat its pose, the device times out, the force goes to zero.
  const auto t1 = std::chrono::steady_clock::now();
  double f = force(last);
  while (f > 0 && std::chrono::steady_clock::now() - t1 < std::chrono::seconds(10)) f = force(read_state());
  EXPECT_EQ(f, 0.0);
  EXPECT_GE(std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count(), 0.2);
  EXPECT_EQ(server_->stats().bad_messages.load(), 1u);
  ws.close(websocket::close_code::normal);
}

class ViewerWithToken : public Viewer {
 protected:
  static constexpr const char* kToken = "0123456789abcdef0123456789abcdef";
  void SetUp() override {
    token_ = kToken;
    Viewer::SetUp();
  }
};

// Rigid objects' splats are served at /object/I, and nothing else under /object/.
class ViewerWithObjects : public Viewer {
 protected:
  void SetUp() override {
    object_splats_ = {std::make_shared<const std::string>(32, 'a'), std::make_shared<const std::string>(64, 'b')};
    Viewer::SetUp();
  }
};

TEST_F(ViewerWithObjects, EachObjectsSplatsAtItsOwnRoute) {
  const std::uint16_t port = server_->port();
  const Reply first = request(port, "/object/0"), second = request(port, "/object/1");
  EXPECT_EQ(first.status, 200);
  EXPECT_EQ(first.body, std::string(32, 'a'));
  EXPECT_EQ(second.body, std::string(64, 'b'));
  for (const char* bad : {"/object/2", "/object/", "/object/x", "/object/-1", "/object/00001", "/object/1a"})
    EXPECT_EQ(request(port, bad).status, 404) << bad;
}

TEST_F(ViewerWithToken, RefusedWithoutAcceptedWithAndCarriedAsCookie) {
  const std::uint16_t port = server_->port();
  EXPECT_EQ(request(port, "/").status, 401);
  EXPECT_EQ(request(port, "/api/hello?token=wrong").status, 401);
  EXPECT_EQ(request(port, "/api/hello?token=0123456789abcdef0123456789abcdeX").status, 401);
  EXPECT_EQ(server_->stats().refused_token.load(), 3u);
  const Reply page = request(port, std::string("/?token=") + kToken);
  EXPECT_EQ(page.status, 200);
  EXPECT_NE(page.set_cookie.find(std::string("gshaptics_token=") + kToken), std::string::npos);
  EXPECT_NE(page.set_cookie.find("HttpOnly"), std::string::npos);
  EXPECT_EQ(request(port, "/scene", {{"Cookie", std::string("a=b; gshaptics_token=") + kToken}}).status, 200);
  EXPECT_EQ(request(port, "/api/hello", {{"Authorization", std::string("token ") + kToken}}).status, 200);
  EXPECT_EQ(request(port, "/api/hello", {{"X-Gshaptics-Token", kToken}}).status, 200);
  EXPECT_FALSE(ws_handshake(port, {}));
  EXPECT_TRUE(ws_handshake(port, {{"Cookie", std::string("gshaptics_token=") + kToken}}));
}

// A page at 7 frames/s (software GL, a stalled browser): with the timeout scaled to its frame
// interval, one late frame does not cut the force; the fixed 0.25 s timeout would. Silence
// longer than three intervals still ends the data.
TEST(StreamDeviceTimeout, ScalesToTheInputPeriodWithinItsBounds) {
  const auto alive_after = [](double timeout_periods, double gap_s) {
    StreamDeviceParams sp;
    sp.input_timeout = 0.25;
    sp.timeout_periods = timeout_periods;
    sp.alive_before_first_target = false;
    StreamDevice dev(sp, Eigen::Vector3d::Zero());
    dev.start(0);
    const Nanos period = to_nanos(1.0 / 7.0);
    Nanos t = 0;
    for (int k = 0; k < 20; ++k) {  // 20 frames at 7 Hz
      t += period;
      dev.set_target(Eigen::Vector3d(0.001 * k, 0, 0), Eigen::Quaterniond::Identity(), t);
      (void)dev.read(t);
    }
    const std::uint64_t seq = dev.read(t).sequence;
    return std::pair(dev.read(t + to_nanos(gap_s)).sequence > seq, dev.input_timeout());
  };
  const auto [fixed_alive, fixed_timeout] = alive_after(0, 0.35);
  EXPECT_FALSE(fixed_alive);
  EXPECT_DOUBLE_EQ(fixed_timeout, 0.25);
  const auto [scaled_alive, scaled_timeout] = alive_after(3, 0.35);
  EXPECT_TRUE(scaled_alive) << "a frame 0.35 s late at 7 frames/s cut the input";
  EXPECT_NEAR(scaled_timeout, 3.0 / 7.0, 1e-6);
  EXPECT_FALSE(alive_after(3, 0.5).first);  // > 3 intervals: the controller is gone
}

TEST(ViewerSecurity, OriginPolicy) {
  const OriginPolicy lo("127.0.0.1", 8080);
  EXPECT_TRUE(lo.host_ok("127.0.0.1:8080"));
  EXPECT_TRUE(lo.host_ok("LOCALHOST:8080"));
  EXPECT_TRUE(lo.host_ok("[::1]:8080"));
  EXPECT_TRUE(lo.host_ok("localhost"));
  EXPECT_FALSE(lo.host_ok("localhost:8081"));
  EXPECT_FALSE(lo.host_ok("evil.example:8080"));
  EXPECT_FALSE(lo.host_ok("127.0.0.1.evil.example:8080"));
  EXPECT_FALSE(lo.host_ok(""));
  EXPECT_TRUE(lo.origin_ok("", "127.0.0.1:8080"));
  EXPECT_TRUE(lo.origin_ok("http://127.0.0.1:8080", "127.0.0.1:8080"));
  EXPECT_FALSE(lo.origin_ok("http://127.0.0.1:8080", "evil.example:8080"));
  EXPECT_FALSE(lo.origin_ok("https://127.0.0.1:8080", "127.0.0.1:8080"));
  EXPECT_FALSE(lo.origin_ok("null", "127.0.0.1:8080"));
  const OriginPolicy lab("192.168.1.5", 8080, {"http://lab-pc:9000"});
  EXPECT_TRUE(lab.host_ok("192.168.1.5:8080"));
  EXPECT_TRUE(lab.host_ok("lab-pc:9000"));
  EXPECT_FALSE(lab.host_ok("evil.example:8080"));
  EXPECT_TRUE(lab.origin_ok("http://lab-pc:9000", "192.168.1.5:8080"));
  const OriginPolicy any("0.0.0.0", 8080);
  EXPECT_TRUE(any.host_ok("my-machine:8080"));  // every name: the token protects it
  EXPECT_TRUE(is_loopback_host("127.0.0.1") && is_loopback_host("::1") && is_loopback_host("localhost"));
  EXPECT_FALSE(is_loopback_host("0.0.0.0") || is_loopback_host("192.168.1.5"));
}

// A string whose every byte read is counted.
struct CountingBytes {
  std::string s;
  mutable int reads = 0;
  [[nodiscard]] std::size_t size() const { return s.size(); }
  char operator[](std::size_t i) const {
    ++reads;
    return s[i];
  }
};

TEST(ViewerSecurity, TokenComparisonReadsEveryByte) {
  CountingBytes expected{"0123456789abcdef0123456789abcdef"};
  EXPECT_TRUE(constant_time_equal(std::string("0123456789abcdef0123456789abcdef"), expected));
  EXPECT_EQ(expected.reads, 32);
  expected.reads = 0;
  EXPECT_FALSE(constant_time_equal(std::string("X123456789abcdef0123456789abcdef"), expected));
  EXPECT_EQ(expected.reads, 32);  // differs at byte 0 and still reads all 32
  expected.reads = 0;
  EXPECT_FALSE(constant_time_equal(std::string(""), expected));
  EXPECT_EQ(expected.reads, 32);
  EXPECT_FALSE(constant_time_equal(std::string("0123456789abcdef0123456789abcdef0"), expected.s));
  EXPECT_FALSE(constant_time_equal(std::string("0123456789abcdef"), expected.s));
  EXPECT_EQ(make_access_token().size(), 32u);
  EXPECT_NE(make_access_token(), make_access_token());
}

TEST(ViewerSecurity, TokenSourcesAndRateLimiter) {
  EXPECT_EQ(request_token("/?a=1&token=abc", "", "", ""), "abc");
  EXPECT_EQ(request_token("/x", "token  def ", "", ""), "def");
  EXPECT_EQ(request_token("/x", "", "ghi", ""), "ghi");
  EXPECT_EQ(request_token("/x", "", "", "a=b; gshaptics_token=jkl; c=d"), "jkl");
  EXPECT_EQ(request_token("/x", "Bearer zzz", "", "other=1"), "");
  MessageRateLimiter lim(10);
  int allowed = 0;
  for (int i = 0; i < 100; ++i) allowed += lim.allow(0.0) ? 1 : 0;  // a burst at one instant
  EXPECT_EQ(allowed, 10);
  EXPECT_FALSE(lim.allow(0.05));  // half a token back
  EXPECT_TRUE(lim.allow(0.2));
}

TEST(ViewerState, ContactsEncodeTheWorldGeometry) {
  GaussianScene s;
  s.push_back({1.f, 2.f, 3.f}, {0.1f, 0.2f, 0.3f}, {0.7071068f, 0.7071068f, 0.f, 0.f}, 0.9f, 41);
  s.push_back({0.f, 0.f, 0.f}, {0.1f, 0.1f, 0.1f}, {1.f, 0.f, 0.f, 0.f}, 0.9f, 7);
  const CollisionWorld world = CollisionWorld::build(s, WorldConfig{});
  ContactSnapshot snap;
  snap.counts.contacts = 2;
  snap.shown = 2;
  for (std::uint32_t r = 0; r < 2; ++r) snap.record[r] = r;
  TickRecord tick;
  tick.position = {1, 2, 3.2};
  tick.force = {0, 0, 2};
  tick.torque = {0.125, -0.25, 0};
  RuntimeStats stats;
  LatencyHistogram query;
  const json j = json::parse(ViewerServer::state_json(tick, snap, world, stats, query, 1000));
  ASSERT_EQ(j["contacts"].size(), 2u);
  bool found = false;
  for (const auto& c : j["contacts"]) {
    if (c[0] != 41) continue;
    found = true;
    EXPECT_NEAR(c[1].get<double>(), 1.0, 1e-6);
    EXPECT_NEAR(c[3].get<double>(), 3.0, 1e-6);
    EXPECT_NEAR(c[6].get<double>(), 0.3, 1e-4);
    EXPECT_NEAR(std::abs(c[7].get<double>()), 0.7071, 1e-3);  // w of the 90 degree turn about x
  }
  EXPECT_TRUE(found);
  EXPECT_EQ(j["force"][2], 2.0);
  EXPECT_EQ(j["torque"][0], 0.125);  // the torque sent, about the tool centre point
  EXPECT_EQ(j["torque"][1], -0.25);
  EXPECT_FALSE(j.contains("material"));  // no map, no material
}

// A contact on a moved object is drawn where the object is now: its body-frame Gaussian moved by
// the object's pose; a contact whose world or pose is unknown, or whose slot is out of range, is
// left out rather than read out of bounds. The frame lists every object's pose.
TEST(ViewerState, ObjectContactsAreDrawnAtTheObjectsPose) {
  GaussianScene floor, box;
  floor.push_back({0.f, 0.f, 0.f}, {0.1f, 0.1f, 0.01f}, {1.f, 0.f, 0.f, 0.f}, 0.9f, 3);
  box.push_back({0.1f, 0.f, 0.f}, {0.1f, 0.2f, 0.3f}, {1.f, 0.f, 0.f, 0.f}, 0.9f, 11);
  const CollisionWorld world = CollisionWorld::build(floor, WorldConfig{});
  const std::vector<std::shared_ptr<const CollisionWorld>> bodies{
      std::make_shared<const CollisionWorld>(CollisionWorld::build(box, WorldConfig{}))};
  ObjectPoses poses;
  poses.count = 1;
  poses.poses[0].position = {1, 2, 3};
  poses.poses[0].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  ContactSnapshot snap;
  snap.counts.contacts = 4;
  snap.shown = 4;
  snap.record = {0, 0, 5, 0};
  snap.body = {0, 1, 1, 2};  // the floor's, the box's, a slot past the box's, an object not given
  RuntimeStats stats;
  LatencyHistogram query;
  const json j = json::parse(ViewerServer::state_json(TickRecord{}, snap, SnapshotWorlds{&world, bodies, &poses},
                                                      stats, query, 1000));
  ASSERT_EQ(j["contacts"].size(), 2u);
  EXPECT_EQ(j["contacts"][0][0], 3);
  const json& c = j["contacts"][1];
  EXPECT_EQ(c[0], 11);
  EXPECT_NEAR(c[1].get<double>(), 1.0, 1e-6);  // (0.1, 0, 0) turned 90 degrees about z is (0, 0.1, 0)
  EXPECT_NEAR(c[2].get<double>(), 2.1, 1e-6);
  EXPECT_NEAR(c[3].get<double>(), 3.0, 1e-6);
  EXPECT_NEAR(std::abs(c[7].get<double>()), std::sqrt(0.5), 1e-3);  // the Gaussian turned with the box
  EXPECT_NEAR(std::abs(c[10].get<double>()), std::sqrt(0.5), 1e-3);
  ASSERT_EQ(j["objects"].size(), 1u);
  EXPECT_EQ(j["objects"][0][0], 1.0);
  EXPECT_EQ(j["objects"][0][2], 3.0);
  EXPECT_NEAR(j["objects"][0][6].get<double>(), std::sqrt(0.5), 1e-6);
  // Without the poses, an object's contact cannot be placed: only the floor's is drawn.
  const json still = json::parse(ViewerServer::state_json(TickRecord{}, snap, SnapshotWorlds{&world, bodies, nullptr},
                                                          stats, query, 1000));
  EXPECT_EQ(still["contacts"].size(), 1u);
  EXPECT_FALSE(still.contains("objects"));
}

TEST(ViewerState, TheFrameNamesTheMaterialOfTheContactsAndTheHelloItsRegions) {
  GaussianScene s;
  s.push_back({-1.f, 0.f, 0.f}, {0.1f, 0.1f, 0.1f}, {1.f, 0.f, 0.f, 0.f}, 0.3f, 0);
  s.push_back({1.f, 0.f, 0.f}, {0.1f, 0.1f, 0.1f}, {1.f, 0.f, 0.f, 0.f}, 0.9f, 1);
  const CollisionWorld world = CollisionWorld::build(s, WorldConfig{});
  const MaterialMap map = MaterialMap::parse(json::parse(R"({"materials": [{"name": "felt"}, {"name": "steel"}],
      "regions": [{"material": "felt", "box": {"min": [-2, -1, -1], "max": [0, 1, 1]}},
                  {"material": "steel", "sphere": {"center": [1, 0, 0], "radius": 0.5}}]})"), "map");
  const auto field = MaterialField::resolve(map, world, ProxyParams{});
  ContactSnapshot snap;
  snap.counts.contacts = 2;
  snap.shown = 2;
  snap.record[0] = 0;
  snap.record[1] = 1;
  RuntimeStats stats;
  LatencyHistogram query;
  const json both = json::parse(ViewerServer::state_json(TickRecord{}, snap, world, stats, query, 1000, field.get()));
  EXPECT_EQ(both["material"], "steel");  // the more opaque contact's
  // What the VR controller plays: the tick's texture RMS and material level.
  TickRecord textured;
  textured.texture_rms = 0.125f;
  textured.vibration = 0.5f;
  const json buzz = json::parse(ViewerServer::state_json(textured, snap, world, stats, query, 1000, field.get()));
  EXPECT_DOUBLE_EQ(buzz["vibration"]["texture_rms"].get<double>(), 0.125);
  EXPECT_DOUBLE_EQ(buzz["vibration"]["level"].get<double>(), 0.5);
  EXPECT_FALSE(json::parse(ViewerServer::state_json(textured, snap, world, stats, query, 1000, nullptr)).contains("vibration"));
  snap.shown = 0;
  const json none = json::parse(ViewerServer::state_json(TickRecord{}, snap, world, stats, query, 1000, field.get()));
  EXPECT_EQ(none["material"], "default");
  const json regions = regions_in_world(map, world);
  ASSERT_EQ(regions.size(), 2u);
  EXPECT_EQ(regions[0]["material"], "felt");
  EXPECT_EQ(regions[0]["box"]["corners"].size(), 8u);
  EXPECT_EQ(regions[1]["sphere"]["radius"], 0.5);
}

}  // namespace
}  // namespace gshaptics
