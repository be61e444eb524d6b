#pragma once
// A fake Haply Inverse Service for the tests: a WebSocket server that speaks the documented
// Inverse Service JSON (see gshaptics/device/haply_device.h) of version 3.1 (force key "values",
// no session) or 3.5 (a "session_id" in the first message, force key "vector", a session
// profile handshake with the first command; docs.haply.co/inverseSDK/service, 3.5.x), with each
// device's "status" {calibrated, ready, ...}, in lock-step - a state message,
// then one command, then the next state - records the forces it is sent, and can be told to
// drop the connection and refuse new ones for a while (a service restart), to slip malformed
// messages in, or to list no device.

#include <sys/socket.h>

#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Core>

namespace gshaptics::test {

class FakeInverseService {
 public:
  FakeInverseService() : acceptor_(ioc_, {boost::asio::ip::make_address("127.0.0.1"), 0}) {
    acceptor_.non_blocking(true);
    port_ = acceptor_.local_endpoint().port();
    thread_ = std::thread([this] { serve(); });
  }
  ~FakeInverseService() {
    stop_ = true;
    drop();
    thread_.join();
  }
  int port() const { return port_; }

  void set_position(const Eigen::Vector3d& p) { std::lock_guard<std::mutex> l(mu_); position_ = p; }
  void set_velocity(const Eigen::Vector3d& v) { std::lock_guard<std::mutex> l(mu_); velocity_ = v; }
  void set_buttons(bool a, bool b, bool c) { std::lock_guard<std::mutex> l(mu_); buttons_ = {a, b, c}; }
  void set_devices(int n) { devices_ = n; }
  /// The documented form served and expected: 31 (3.1-3.4) or 35 (3.5). A command in the other
  /// form counts as a bad command and is not applied.
  void set_version(int v) { version_ = v; }
  /// What the device's status says (both true unless told).
  void set_status(bool calibrated, bool ready) { calibrated_ = calibrated; ready_ = ready; }
  /// 3.5: connections whose first command carried session.configure.profile.name (the name kept).
  std::vector<std::string> session_profiles() const { std::lock_guard<std::mutex> l(mu_); return profiles_; }
  /// Every n-th message is malformed JSON (0: never).
  void set_malformed_every(int n) { malformed_every_ = n; }
  /// Each connection opens with this text instead of the documented first state (empty: the
  /// documented one), and sends nothing more until a command comes.
  void set_first_message(std::string text) { std::lock_guard<std::mutex> l(mu_); first_override_ = std::move(text); }
  /// Commands that answered a malformed message with a force other than zero.
  long nonzero_after_malformed() const { return nonzero_after_malformed_; }
  /// Drops the current connection and refuses new ones for `seconds`.
  void restart(double seconds) {
    refuse_until_ = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                         std::chrono::duration<double>(seconds));
    drop();
  }

  Eigen::Vector3d last_force() const { std::lock_guard<std::mutex> l(mu_); return last_force_; }
  /// Per connection: the force of its first command.
  std::vector<Eigen::Vector3d> first_forces() const { std::lock_guard<std::mutex> l(mu_); return first_forces_; }
  int connections() const { return connections_; }
  long commands() const { return commands_; }
  long bad_commands() const { return bad_commands_; }

 private:
  void drop() {
    const int fd = socket_fd_.load();
    if (fd >= 0) ::shutdown(fd, SHUT_RDWR);
  }

  std::string state(bool first) {
    std::lock_guard<std::mutex> l(mu_);
    nlohmann::json inv = nlohmann::json::array();
    for (int i = 0; i < devices_; ++i) {
      nlohmann::json d = {{"device_id", "INV3-" + std::to_string(i)},
                          {"state",
                           {{"cursor_position", {{"x", position_.x()}, {"y", position_.y()}, {"z", position_.z()}}},
                            {"cursor_velocity", {{"x", velocity_.x()}, {"y", velocity_.y()}, {"z", velocity_.z()}}}}}};
      if (first) d["config"] = {{"handedness", "right"}};
      d["status"] = {{"calibrated", calibrated_.load()}, {"in_use", true}, {"power_supply", true},
                     {"ready", ready_.load()}, {"started", true}};
      inv.push_back(d);
    }
    nlohmann::json grip = nlohmann::json::array(
        {{{"device_id", "GRIP-0"},
          {"state",
           {{"orientation", {{"w", 1.0}, {"x", 0.0}, {"y", 0.0}, {"z", 0.0}}},
            {"buttons", {{"a", buttons_[0]}, {"b", buttons_[1]}, {"c", buttons_[2]}}}}}}});
    nlohmann::json msg{{"inverse3", inv}, {"wireless_verse_grip", grip}};
    if (first && version_ == 35) msg["session_id"] = 7;
    return msg.dump();
  }

  void serve() {
    namespace beast = boost::beast;
    using tcp = boost::asio::ip::tcp;
    while (!stop_) {
      tcp::socket socket(ioc_);
      boost::system::error_code ec;
      acceptor_.accept(socket, ec);
      if (ec) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        continue;
      }
      if (std::chrono::steady_clock::now() < refuse_until_.load()) continue;  // closed at once
      socket.non_blocking(false);
      socket_fd_ = socket.native_handle();
      ++connections_;
      bool first_command = true;
      try {
        beast::websocket::stream<tcp::socket> ws(std::move(socket));
        ws.accept();
        ws.text(true);
        long sent = 0;
        bool malformed_sent = false;
        std::string first;
        {
          std::lock_guard<std::mutex> l(mu_);
          first = first_override_;
        }
        ws.write(boost::asio::buffer(first.empty() ? state(true) : first));
        while (!stop_) {
          beast::flat_buffer buf;
          ws.read(buf);
          ++commands_;
          const auto j = nlohmann::json::parse(beast::buffers_to_string(buf.data()), nullptr, false);
          try {
            if (first_command && version_ == 35 && j.contains("session")) {
              std::lock_guard<std::mutex> l(mu_);
              profiles_.push_back(j.at("session").at("configure").at("profile").at("name").get<std::string>());
            }
            const char* key = version_ == 35 ? "vector" : "values";
            const auto& v = j.at("inverse3").at(0).at("commands").at("set_cursor_force").at(key);
            const Eigen::Vector3d f(v.at("x").get<double>(), v.at("y").get<double>(), v.at("z").get<double>());
            std::lock_guard<std::mutex> l(mu_);
            if (malformed_sent && f != Eigen::Vector3d::Zero()) ++nonzero_after_malformed_;
            last_force_ = f;
            if (first_command) first_forces_.push_back(f);
            first_command = false;
          } catch (const std::exception&) {
            ++bad_commands_;
          }
          ++sent;
          malformed_sent = malformed_every_ > 0 && sent % malformed_every_ == 0;
          if (malformed_sent)
            ws.write(boost::asio::buffer(std::string("{\"inverse3\": [ {\"device_id\": ")));
          else
            ws.write(boost::asio::buffer(state(false)));
        }
      } catch (const std::exception&) {
        // connection dropped (restart() or the client left)
      }
      socket_fd_ = -1;
    }
  }

  boost::asio::io_context ioc_;
  boost::asio::ip::tcp::acceptor acceptor_;
  int port_ = 0;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<int> socket_fd_{-1};
  std::atomic<std::chrono::steady_clock::time_point> refuse_until_{};
  std::atomic<int> devices_{1}, malformed_every_{0}, connections_{0}, version_{31};
  std::atomic<bool> calibrated_{true}, ready_{true};
  std::vector<std::string> profiles_;
  std::atomic<long> commands_{0}, bad_commands_{0}, nonzero_after_malformed_{0};
  mutable std::mutex mu_;
  std::string first_override_;
  Eigen::Vector3d position_ = Eigen::Vector3d::Zero(), velocity_ = Eigen::Vector3d::Zero(), last_force_ = Eigen::Vector3d::Zero();
  std::array<bool, 3> buttons_{false, false, false};
  std::vector<Eigen::Vector3d> first_forces_;
};

}  // namespace gshaptics::test
