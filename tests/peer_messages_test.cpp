// The peers' WebSocket messages (peer_messages.h): the documented forms are read exactly, and no
// text, however malformed, makes a parser throw (they are noexcept, so a throw would end this
// test binary as it ended the viewer server: one {"type":5} message used to terminate the process).
// The type-confusion sweep replaces every value of the documented messages, one at a time, by a
// value of every other JSON type; the truncation sweep cuts them at every byte.

#include "gshaptics/device/peer_messages.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace gshaptics {
namespace {

using json = nlohmann::json;

const char* kToolWithRotation = R"({"type":"tool","center":[0.1,-0.2,0.3],"rotation":[0,0,0,2]})";

json haply_state() {
  return json::parse(R"({
    "inverse3": [
      {"device_id": "INV3-A", "config": {"handedness": "left"},
       "state": {"cursor_position": {"x": 0.01, "y": -0.02, "z": 0.15},
                 "cursor_velocity": {"x": 0.1, "y": 0.0, "z": -0.3}}},
      {"device_id": "INV3-B",
       "state": {"cursor_position": {"x": 1, "y": 2, "z": 3}}}],
    "wireless_verse_grip": [
      {"device_id": "VG-1", "state": {"orientation": {"w": 0, "x": 0, "y": 3, "z": 4},
                                      "buttons": {"a": true, "b": false, "c": true}}}]})");
}

TEST(PeerMessages, ViewerToolMessageReadsCentreAndNormalisedRotation) {
  const auto plain = parse_viewer_tool_message(R"({"type":"tool","center":[1,2.5,-3]})");
  ASSERT_TRUE(plain.has_value());
  EXPECT_EQ(plain->center, Eigen::Vector3d(1, 2.5, -3));
  EXPECT_TRUE(plain->rotation.isApprox(Eigen::Quaterniond::Identity()));

  const auto rotated = parse_viewer_tool_message(kToolWithRotation);
  ASSERT_TRUE(rotated.has_value());
  EXPECT_EQ(rotated->center, Eigen::Vector3d(0.1, -0.2, 0.3));
  EXPECT_DOUBLE_EQ(rotated->rotation.z(), 1.0);  // [0,0,0,2] normalised, w first
  EXPECT_DOUBLE_EQ(rotated->rotation.w(), 0.0);
}

TEST(PeerMessages, ViewerMalformedMessagesAreRefused) {
  const char* bad[] = {
      "",
      "not json",
      "[1,2,3]",
      R"({"center":[0,0,0]})",
      R"({"type":5,"center":[0,0,0]})",  // terminated the server before peer_messages.h
      R"({"type":null,"center":[0,0,0]})",
      R"({"type":["tool"],"center":[0,0,0]})",
      R"({"type":"camera","center":[0,0,0]})",
      R"({"type":"tool"})",
      R"({"type":"tool","center":[0,0]})",
      R"({"type":"tool","center":[0,0,0,0]})",
      R"({"type":"tool","center":[0,"x",0]})",
      R"({"type":"tool","center":{"x":0,"y":0,"z":0}})",
      R"({"type":"tool","center":[0,0,0],"rotation":[0,0,0,0]})",
      R"({"type":"tool","center":[0,0,0],"rotation":[1,0,0]})",
      R"({"type":"tool","center":[0,0,0],"rotation":"identity"})",
      R"({"type":"tool","center":[0,0,0],"rotation":[1,0,null,0]})",
      R"({"type":"tool","center":[0,0,0]} trailing)",
  };
  for (const char* text : bad) EXPECT_FALSE(parse_viewer_tool_message(text).has_value()) << text;
}

TEST(PeerMessages, HaplyStateReadsTheDocumentedFields) {
  const std::string text = haply_state().dump();
  const HaplyStateMessage first = parse_haply_state(text, 0);
  ASSERT_TRUE(first.valid);
  EXPECT_EQ(first.devices_listed, -1);
  EXPECT_EQ(first.sample.position, Eigen::Vector3d(0.01, -0.02, 0.15));
  EXPECT_EQ(first.sample.velocity, Eigen::Vector3d(0.1, 0.0, -0.3));
  EXPECT_NEAR(first.sample.orientation.y(), 0.6, 1e-15);
  EXPECT_NEAR(first.sample.orientation.z(), 0.8, 1e-15);
  EXPECT_EQ(first.sample.buttons, 0b101u);
  ASSERT_TRUE(first.device_id.has_value());
  EXPECT_EQ(*first.device_id, "INV3-A");
  EXPECT_EQ(first.handedness, "left");

  const HaplyStateMessage second = parse_haply_state(text, 1);
  ASSERT_TRUE(second.valid);
  EXPECT_EQ(second.sample.position, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(second.sample.velocity, Eigen::Vector3d::Zero());  // no cursor_velocity: zero
  EXPECT_EQ(second.handedness, "");

  const HaplyStateMessage missing = parse_haply_state(text, 5);  // the service lists two
  EXPECT_TRUE(missing.valid);
  EXPECT_EQ(missing.devices_listed, 2);
  EXPECT_FALSE(parse_haply_state(text, -1).valid);
}

TEST(PeerMessages, HaplyFieldsOfTheWrongTypeAreSkippedOrRefused) {
  json j = haply_state();
  j["inverse3"][0]["device_id"] = 17;  // not a string: kept as its JSON text
  j["wireless_verse_grip"][0]["state"]["buttons"] = {{"a", "yes"}, {"b", 1}, {"c", true}};
  j["wireless_verse_grip"][0]["state"]["orientation"]["w"] = "one";
  HaplyStateMessage m = parse_haply_state(j.dump(), 0);
  ASSERT_TRUE(m.valid);  // the grip is optional: its bad fields are skipped
  EXPECT_EQ(*m.device_id, "17");
  EXPECT_EQ(m.sample.buttons, 0b100u);  // only a real `true` presses a button
  EXPECT_TRUE(m.sample.orientation.isApprox(Eigen::Quaterniond::Identity()));

  j = haply_state();
  j["inverse3"][0]["state"]["cursor_velocity"]["y"] = "fast";
  EXPECT_FALSE(parse_haply_state(j.dump(), 0).valid);  // a velocity given must be read whole
  j = haply_state();
  j["inverse3"][0]["state"]["cursor_position"] = json::array({0, 0, 0});
  EXPECT_FALSE(parse_haply_state(j.dump(), 0).valid);
  j = haply_state();
  j["inverse3"][0]["state"]["cursor_position"]["x"] = 1e308 * 10.0;  // not finite (written as null)
  EXPECT_FALSE(parse_haply_state(j.dump(), 0).valid);
  EXPECT_FALSE(parse_haply_state(R"({"inverse3":{"0":{}}})", 0).valid);
  EXPECT_FALSE(parse_haply_state("", 0).valid);
}

// Every value of `doc` (objects' members and arrays' elements, recursively), replaced in turn by
// each value of another JSON type, as text.
std::vector<std::string> type_confusions(const json& doc) {
  const std::vector<json> others = {nullptr, true, 7, -2.5, "s", json::array(), json::object(),
                                    json::array({1, 2, 3}), json{{"x", 1}}};
  std::vector<std::string> out;
  std::vector<json::json_pointer> paths;
  std::function<void(const json&, const json::json_pointer&)> walk = [&](const json& v, const json::json_pointer& p) {
    if (!p.empty()) paths.push_back(p);
    if (v.is_object())
      for (const auto& [k, child] : v.items()) walk(child, p / k);
    if (v.is_array())
      for (std::size_t i = 0; i < v.size(); ++i) walk(v[i], p / i);
  };
  walk(doc, json::json_pointer());
  for (const auto& p : paths)
    for (const json& o : others) {
      json mutated = doc;
      mutated[p] = o;
      out.push_back(mutated.dump());
    }
  return out;
}

TEST(PeerMessages, NoTypeConfusionOrTruncationThrows) {
  // parse_* are noexcept: a throw inside ends the process, so reaching the counts is the check;
  // the counts show that the sweeps ran and that some mutations still parse.
  const json tool = json::parse(kToolWithRotation);
  std::size_t tools = 0, states = 0, runs = 0;
  for (const std::string& text : type_confusions(tool)) {
    tools += parse_viewer_tool_message(text).has_value() ? 1 : 0;
    ++runs;
  }
  for (const std::string& text : type_confusions(haply_state()))
    for (int index : {0, 1, 2}) {
      states += parse_haply_state(text, index).valid ? 1 : 0;
      ++runs;
    }
  const std::string full[] = {tool.dump(), haply_state().dump()};
  for (const std::string& text : full)
    for (std::size_t n = 0; n < text.size(); ++n) {
      EXPECT_FALSE(parse_viewer_tool_message(text.substr(0, n)).has_value());
      EXPECT_FALSE(parse_haply_state(text.substr(0, n), 0).valid);
      runs += 2;
    }
  EXPECT_GT(runs, 1500u);
  // Some mutations stay valid (a number put for a number; any change inside the optional grip).
  EXPECT_GT(tools, 0u);
  EXPECT_GT(states, 100u);
}

}  // namespace
}  // namespace gshaptics
