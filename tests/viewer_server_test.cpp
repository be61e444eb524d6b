// The viewer server without a browser: HTTP routes, the hello and state frames over a real
// WebSocket (Boost.Beast client), the mouse device steered through the protocol into contact,
// malformed messages, and the state frame's contact encoding.

#include "gshaptics/net/viewer_server.h"

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

struct HttpReply {
  int status = 0;
  std::string body;
};

HttpReply http_get(std::uint16_t port, const std::string& target) {
  asio::io_context io;
  tcp::resolver resolver(io);
  beast::tcp_stream stream(io);
  stream.connect(resolver.resolve("127.0.0.1", std::to_string(port)));
  http::request<http::empty_body> req{http::verb::get, target, 11};
  req.set(http::field::host, "127.0.0.1");
  http::write(stream, req);
  beast::flat_buffer buffer;
  http::response_parser<http::string_body> parser;
  parser.body_limit(64u << 20);
  http::read(stream, buffer, parser);
  beast::error_code ec;
  stream.socket().shutdown(tcp::socket::shutdown_both, ec);
  return {int(parser.get().result_int()), parser.get().body()};
}

class Viewer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world_ = &test::truck_world();
  }

  void SetUp() override {
    StreamDeviceParams sp;
    sp.name = "mouse";
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
  std::unique_ptr<StreamDevice> mouse_;
  std::unique_ptr<HapticRuntime> runtime_;
  std::unique_ptr<ContactSnapshotObserver> snapshots_;
  std::unique_ptr<ViewerServer> server_;
};
const CollisionWorld* Viewer::world_ = nullptr;

TEST_F(Viewer, HttpRoutes) {
  const std::uint16_t port = server_->port();
  ASSERT_NE(port, 0);
  const HttpReply page = http_get(port, "/");
  EXPECT_EQ(page.status, 200);
  EXPECT_NE(page.body.find("importmap"), std::string::npos);
  const HttpReply hello = http_get(port, "/api/hello");
  EXPECT_EQ(json::parse(hello.body)["type"], "hello");
  const HttpReply scene = http_get(port, "/scene");
  EXPECT_EQ(scene.status, 200);
  EXPECT_EQ(scene.body.size(), std::filesystem::file_size(test::data_path("truck.splat")));
  EXPECT_EQ(http_get(port, "/../CMakeLists.txt").status, 400);
  EXPECT_EQ(http_get(port, "/package.json").status, 404);  // only the page and its packages
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
  ws.read(buf);
  EXPECT_EQ(json::parse(beast::buffers_to_string(buf.data()))["type"], "state");
  buf.consume(buf.size());
  const auto t1 = std::chrono::steady_clock::now();
  while (server_->stats().bad_messages.load() < 2 && std::chrono::steady_clock::now() - t1 < std::chrono::seconds(5))
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(server_->stats().bad_messages.load(), 2u);
  ws.close(websocket::close_code::normal);
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
}

}  // namespace
}  // namespace gshaptics
