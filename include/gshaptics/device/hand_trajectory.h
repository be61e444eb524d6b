#pragma once
/// @file
/// The path a simulated hand follows: timed waypoints joined by minimum-jerk blends, and the
/// contact sites it presses (paper Sec. V-A, Fig. 4). SimulatedDevice plays it; the probe
/// generator (sim/probe_trajectory.h) makes one from a scene.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace gshaptics {

/// One contact site found on the surface.
struct ProbeSite {
  Eigen::Vector3d surface_point;  ///< centre of the Gaussian chosen on the surface (world)
  Eigen::Vector3d normal;         ///< outward unit normal (world)
  Eigen::Vector3d touch_point;    ///< tool centre at first contact along the approach
  std::uint32_t gaussian_index;   ///< source index of the chosen Gaussian
  double t_touch = 0;             ///< time (s) the target reaches touch_point
};

/// A piecewise minimum-jerk path through waypoints, sampled by time (s); positions in the world
/// frame, world units.
class ProbeTrajectory {
 public:
  struct Waypoint {
    double time;
    Eigen::Vector3d position;
  };
  ProbeTrajectory() = default;
  ProbeTrajectory(std::vector<Waypoint> waypoints, std::vector<ProbeSite> sites, double tool_radius);

  /// Target position and velocity at time t (clamped to the ends).
  void sample(double t, Eigen::Vector3d& position, Eigen::Vector3d& velocity) const noexcept;
  [[nodiscard]] double duration() const { return waypoints_.empty() ? 0 : waypoints_.back().time; }
  [[nodiscard]] const std::vector<ProbeSite>& sites() const { return sites_; }
  [[nodiscard]] const std::vector<Waypoint>& waypoints() const { return waypoints_; }
  [[nodiscard]] double tool_radius() const { return tool_radius_; }

 private:
  std::vector<Waypoint> waypoints_;
  std::vector<ProbeSite> sites_;
  double tool_radius_ = 0;
};

}  // namespace gshaptics
