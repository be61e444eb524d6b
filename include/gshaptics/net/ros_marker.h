#pragma once
/// @file
/// A visualization_msgs/Marker in plain types, the common form both ROS bridges translate into
/// their message types. C++17-clean on purpose: the ROS 1 transport (built as C++17 because
/// Debian's ROS 1 message headers predate C++20) uses it too.

#include <array>
#include <cstdint>
#include <string>

namespace gshaptics {

struct RosMarker {
  static constexpr std::int32_t kCube = 1;       ///< visualization_msgs/Marker CUBE
  static constexpr std::int32_t kSphere = 2;     ///< visualization_msgs/Marker SPHERE
  static constexpr std::int32_t kAdd = 0;        ///< ADD
  static constexpr std::int32_t kDeleteAll = 3;  ///< DELETEALL
  std::string ns;
  std::int32_t id = 0, type = kSphere, action = kAdd;
  std::array<double, 3> position{};                       ///< world frame, m
  std::array<double, 4> orientation_xyzw{0, 0, 0, 1};     ///< ROS order x, y, z, w
  std::array<double, 3> scale{};                          ///< full extents (diameters), m
  std::array<float, 4> rgba{};
  double lifetime = 0;  ///< s after which RViz drops the marker unless it is republished; 0: never
};

}  // namespace gshaptics
