#pragma once
/// @file
/// Tools with a shape: a rigid set of ellipsoids in the tool frame (issue 36, item 1). The paper
/// models the tool as one ellipsoid and names that as a limitation (Sec. VI: it "restricts the
/// accurate modelling of complex tool geometries and multi-point contacts"); a compound tool
/// is tested part by part with the same exact algebraic overlap test (eq. 4-6), so it stays
/// exact, and each contact carries the part that made it.
///
/// Frames: the tool frame's origin is the device's tool centre point (TCP); a part's `offset`
/// and `rotation` place its ellipsoid in that frame; the device's pose (position, orientation:
/// tool frame -> world) places the tool in the world. Metres.
///
/// Presets (parse_tool_spec):
///   sphere:R            one sphere of radius R at the TCP
///   ellipsoid:A,B,C     one ellipsoid with semi-axes A, B, C along the tool frame's x, y, z
///   stylus:L,R          a rod of length L and radius R from the TCP (its tip) along +z, as four
///                       overlapping prolate ellipsoids (semi-axes R, R, L/6 centred at
///                       z = L/6 + i 2L/9: the tip is the TCP, the end at z = L, and neighbours
///                       overlap by a third of their length)
///   disc:R,T            an oblate ellipsoid of radius R and thickness T, its axis along z
///   FILE.json           {"parts": [{"center": [x, y, z], "semi_axes": [a, b, c],
///                                   "rotation": [w, x, y, z]}, ...]} (rotation optional)
///
/// Threading: values; posed() never allocates, locks, logs or throws.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <span>
#include <string>
#include <string_view>

#include "gshaptics/collision/tool_ellipsoid.h"

namespace gshaptics {

/// Most parts a compound tool may have (fixed, so posing and rendering never allocate).
inline constexpr int kMaxToolParts = 8;

/// One ellipsoid of a compound tool, in the tool frame.
struct ToolPart {
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();              ///< centre in the tool frame, m
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  ///< ellipsoid axes in the tool frame
  Eigen::Vector3d semi_axes = Eigen::Vector3d::Constant(0.01);   ///< m, all > 0
};

/// A rigid set of 1..kMaxToolParts ellipsoids in the tool frame.
struct CompoundTool {
  std::array<ToolPart, kMaxToolParts> parts{};
  int count = 0;  ///< parts in use

  /// One part at the TCP.
  [[nodiscard]] static CompoundTool single(const Eigen::Vector3d& semi_axes,
                                           const Eigen::Quaterniond& rotation = Eigen::Quaterniond::Identity());
  [[nodiscard]] std::span<const ToolPart> view() const noexcept { return {parts.data(), std::size_t(count)}; }
  /// The parts in the world for a TCP at `position` with `orientation` (tool frame -> world).
  /// Writes min(count, out.size()) ellipsoids and returns how many.
  int posed(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
            std::span<ToolEllipsoid> out) const noexcept;
  /// One part centred on the TCP: the plain tool ellipsoid, which every renderer takes.
  [[nodiscard]] bool is_single_at_tcp() const noexcept { return count == 1 && parts[0].offset.isZero(0); }
  /// Radius of the sphere about the TCP that holds every part, m.
  [[nodiscard]] double reach() const noexcept;
  /// The largest semi-axis of any part, m (the scale a proxy or a kernel works at).
  [[nodiscard]] double largest_semi_axis() const noexcept;
  /// Throws InputError naming `what` when there are no parts, too many, or a part is not
  /// finite or has a semi-axis <= 0.
  void validate(const std::string& what) const;
};

/// Parses a preset ("sphere:R", "ellipsoid:A,B,C", "stylus:L,R", "disc:R,T"; metres) or a JSON
/// file (a spec ending in ".json"). Throws InputError naming the spec or file and what is wrong.
[[nodiscard]] CompoundTool parse_tool_spec(std::string_view spec);

/// One line for logs and summaries: "stylus, 4 parts, reach 0.1 m".
[[nodiscard]] std::string describe(const CompoundTool& tool);

}  // namespace gshaptics
