#pragma once
// A caller's own renderer for the servo-step tests: a spring floor at z = 0 whose force is the
// tool centre's depth times `stiffness` (N/m), the force of exactly the pose it was given, so a
// result's age is visible tick by tick.

#include <algorithm>

#include "gshaptics/force/force_renderer.h"

namespace gshaptics::test {

class FloorRenderer final : public ForceRenderer {
 public:
  explicit FloorRenderer(double stiffness) : k_(stiffness) {}
  std::string_view name() const noexcept override { return "spring floor"; }
  RenderOutput render(const ToolEllipsoid& tool, const Eigen::Vector3d&, double) noexcept override {
    RenderOutput o;
    o.force = Eigen::Vector3d(0, 0, std::max(0.0, -tool.center.z()) * k_);
    o.counts.contacts = o.force.z() > 0 ? 1 : 0;
    o.proxy = tool.center;
    ++calls;
    return o;
  }
  std::span<const Contact> contacts() const noexcept override { return {}; }
  void reset() noexcept override {}
  int calls = 0;

 private:
  double k_;
};

}  // namespace gshaptics::test
