#include "gshaptics/device/hand_trajectory.h"

#include <algorithm>

namespace gshaptics {

ProbeTrajectory::ProbeTrajectory(std::vector<Waypoint> waypoints, std::vector<ProbeSite> sites,
                                 double tool_radius)
    : waypoints_(std::move(waypoints)), sites_(std::move(sites)), tool_radius_(tool_radius) {}

void ProbeTrajectory::sample(double t, Eigen::Vector3d& position,
                             Eigen::Vector3d& velocity) const noexcept {
  velocity.setZero();
  if (waypoints_.empty()) {
    position.setZero();
    return;
  }
  if (t <= waypoints_.front().time) {
    position = waypoints_.front().position;
    return;
  }
  if (t >= waypoints_.back().time) {
    position = waypoints_.back().position;
    return;
  }
  const auto it = std::upper_bound(waypoints_.begin(), waypoints_.end(), t,
                                   [](double x, const Waypoint& w) { return x < w.time; });
  const Waypoint& b = *it;
  const Waypoint& a = *(it - 1);
  const double T = b.time - a.time;
  if (!(T > 0)) {
    position = b.position;
    return;
  }
  // Minimum-jerk blend: s = 10 u^3 - 15 u^4 + 6 u^5, zero velocity and acceleration at waypoints.
  const double u = (t - a.time) / T;
  const double s = u * u * u * (10 - 15 * u + 6 * u * u);
  const double ds = 30 * u * u * (1 - 2 * u + u * u) / T;
  position = a.position + s * (b.position - a.position);
  velocity = ds * (b.position - a.position);
}

}  // namespace gshaptics
