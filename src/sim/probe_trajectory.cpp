#include "gshaptics/sim/probe_trajectory.h"

#include "gshaptics/sim/pose_sampler.h"

#include <algorithm>
#include <optional>
#include <cmath>
#include <numeric>
#include <random>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/error.h"
#include "gshaptics/percentile.h"

namespace gshaptics {

namespace {

struct SiteFinder {
  const CollisionWorld& world;
  const ProbeParams& p;
  ContactQuery query;
  Eigen::Vector3d up;
  double z_safe = 0;

  SiteFinder(const CollisionWorld& w, const ProbeParams& params)
      : world(w), p(params), query(w), up(params.up.normalized()) {}

  std::uint32_t contacts_at(const Eigen::Vector3d& x) {
    query.run(ToolEllipsoid::sphere(x, p.tool_radius));
    return query.result().counts.contacts;
  }

  // True when a tool swept from a to b (inclusive) touches nothing.
  bool segment_clear(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const double len = (b - a).norm();
    const int steps = std::max(1, int(std::ceil(len / (0.5 * p.tool_radius))));
    for (int k = 0; k <= steps; ++k)
      if (contacts_at(a + (b - a) * (double(k) / steps)) > 0) return false;
    return true;
  }

  Eigen::Vector3d lift(const Eigen::Vector3d& x) const { return x + (z_safe - x.dot(up)) * up; }
};

Eigen::Vector3d center_of(const CollisionGaussian& g) { return Eigen::Vector3d(g.center[0], g.center[1], g.center[2]); }

// The object: the dense middle of the scene (horizontal distance to the median centre within
// the 35th percentile), above the lowest 5% of it (the ground, if any).
struct ObjectRegion {
  std::vector<double> rho;  // each Gaussian's horizontal distance to the median centre
  double r_obj = 0, h_ground = 0, z_safe = 0;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
};

ObjectRegion object_region(const CollisionWorld& world, const Eigen::Vector3d& up, double r) {
  const auto& gs = world.gaussians();
  std::vector<double> cx, cy, cz;
  for (const auto& g : gs) {
    cx.push_back(g.center[0]);
    cy.push_back(g.center[1]);
    cz.push_back(g.center[2]);
  }
  const Eigen::Vector3d median(percentile(cx, 50), percentile(cy, 50), percentile(cz, 50));
  const auto horizontal = [&](const Eigen::Vector3d& v) { return v - v.dot(up) * up; };
  ObjectRegion o;
  o.rho.resize(gs.size());
  for (std::size_t i = 0; i < gs.size(); ++i) o.rho[i] = horizontal(center_of(gs[i]) - median).norm();
  o.r_obj = std::max(percentile(o.rho, 35), 4 * r);
  std::vector<double> heights, heights_wide;
  for (std::size_t i = 0; i < gs.size(); ++i) {
    const double h = center_of(gs[i]).dot(up);
    if (o.rho[i] <= o.r_obj) heights.push_back(h);
    if (o.rho[i] <= 2 * o.r_obj) heights_wide.push_back(h + gs[i].bounding_radius());
  }
  o.h_ground = percentile(heights, 5);
  const double h_mid = percentile(heights, 50);
  o.z_safe = percentile(heights_wide, 99.9) + 3 * r;
  o.center = horizontal(median) + h_mid * up;
  return o;
}

// The candidate Gaussians for a site, in a seeded random order: on the object, opaque, above the
// ground, no larger than the tool.
std::vector<std::uint32_t> site_candidates(const CollisionWorld& world, const ObjectRegion& o, const Eigen::Vector3d& up,
                                           double r, std::uint64_t seed) {
  const auto& gs = world.gaussians();
  std::vector<std::uint32_t> pool;
  for (std::size_t i = 0; i < gs.size(); ++i) {
    const auto& g = gs[i];
    const double h = center_of(g).dot(up);
    const float smax = std::max({g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]});
    if (o.rho[i] <= o.r_obj && g.opacity >= 0.5f && h >= o.h_ground + 2 * r && smax <= 2 * r)
      pool.push_back(std::uint32_t(i));
  }
  std::mt19937_64 rng(seed);
  std::shuffle(pool.begin(), pool.end(), rng);
  return pool;
}

// With a tool of a shape (ProbeParams::tool_touch): how far the TCP goes along the approach (-n)
// from `start` before a part meets the surface, when the tool comes down from above to `start`
// touching nothing, meets the surface within `reach`, and no earlier than the sphere does after
// `travel` by more than a quarter of the tool radius; else nothing (the site is refused).
std::optional<double> tool_travel(SiteFinder& f, const Eigen::Vector3d& start, const Eigen::Vector3d& n, double travel,
                                  double reach) {
  const Eigen::Vector3d top = f.lift(start);
  const double drop = (start - top).norm();
  if (drop > 0 && std::isfinite(f.p.tool_touch(top, (start - top) / drop, drop))) return std::nullopt;
  const double met = f.p.tool_touch(start, -n, reach);
  if (!(met >= travel - 0.25 * f.p.tool_radius)) return std::nullopt;  // (NaN: meets nothing)
  return met;
}

// The site at Gaussian `g`, when it is a flat disc facing up and out whose surface the approach
// along its normal meets first, with nothing in the way from above.
std::optional<ProbeSite> site_at(const CollisionGaussian& g, const Eigen::Vector3d& object_center,
                                 const Eigen::Vector3d& up, double d_app, SiteFinder& f) {
  const double r = f.p.tool_radius;
  const Eigen::Vector3d c = center_of(g);
  const Eigen::Matrix3d R = rotation_matrix(g);
  int k_min_axis = 0;
  Eigen::Vector3d axes(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
  axes.minCoeff(&k_min_axis);
  std::array<double, 3> sorted{axes[0], axes[1], axes[2]};
  std::sort(sorted.begin(), sorted.end());
  if (sorted[0] > 0.5 * sorted[1]) return std::nullopt;  // not flat enough to define a normal
  Eigen::Vector3d n = R.col(k_min_axis).normalized();
  if (n.dot(c - object_center) < 0) n = -n;
  if (n.dot(up) < -0.2) return std::nullopt;  // underside: not reachable from above
  // First contact along the approach must be this surface, with nothing in the way.
  const Eigen::Vector3d start = c + d_app * n;
  double s_touch = NAN;
  const double step = r / 8;
  if (f.p.first_touch) {
    s_touch = d_app - f.p.first_touch(start, -n, d_app + r);
  } else {
    for (double s = d_app; s >= -r; s -= step) {
      if (f.contacts_at(c + s * n) > 0) {
        s_touch = s;
        break;
      }
    }
  }
  if (!(s_touch < d_app - step) || s_touch > r + 2 * sorted[2]) return std::nullopt;
  if (!f.segment_clear(f.lift(start), start)) return std::nullopt;
  if (f.p.tool_touch) {
    // The touch point is where the tool meets the surface, not the sphere of its largest
    // semi-axis: a stylus's tip is narrower, and stopped there it hovered over the surface.
    const std::optional<double> met = tool_travel(f, start, n, d_app - s_touch, d_app + r);
    if (!met) return std::nullopt;
    s_touch = d_app - *met;
  }
  ProbeSite site;
  site.surface_point = c;
  site.normal = n;
  site.touch_point = c + s_touch * n;
  site.gaussian_index = g.source_index;
  return site;
}

// Up to params.sites sites, spaced apart (the spacing halved on each of four passes when too few).
std::vector<ProbeSite> find_sites(const CollisionWorld& world, const ProbeParams& params, const ObjectRegion& o,
                                  SiteFinder& f) {
  const auto& gs = world.gaussians();
  const double r = params.tool_radius;
  const std::vector<std::uint32_t> pool = site_candidates(world, o, f.up, r, params.seed);
  std::vector<ProbeSite> sites;
  const double d_app = params.approach_distance * r;
  double spacing = std::max(6 * r, 0.15 * o.r_obj);
  const std::size_t max_attempts = std::min<std::size_t>(pool.size(), 6000);
  for (int pass = 0; pass < 4 && int(sites.size()) < params.sites; ++pass, spacing *= 0.5) {
    for (std::size_t a = 0; a < max_attempts && int(sites.size()) < params.sites; ++a) {
      const auto& g = gs[pool[a]];
      const Eigen::Vector3d c = center_of(g);
      bool near = false;
      for (const auto& s : sites) near = near || (s.surface_point - c).norm() < spacing;
      if (near) continue;
      if (std::optional<ProbeSite> site = site_at(g, o.center, f.up, d_app, f)) sites.push_back(*site);
    }
  }
  return sites;
}

// Visit sites in a short order (greedy nearest neighbour from the first).
void order_sites(std::vector<ProbeSite>& sites) {
  for (std::size_t i = 1; i + 1 < sites.size(); ++i) {
    std::size_t best = i;
    for (std::size_t j = i + 1; j < sites.size(); ++j)
      if ((sites[j].surface_point - sites[i - 1].surface_point).norm() <
          (sites[best].surface_point - sites[i - 1].surface_point).norm())
        best = j;
    std::swap(sites[i], sites[best]);
  }
}

// The waypoints: above each site, down to its touch point, the press, hold and release, back up;
// sets each site's t_touch.
std::vector<ProbeTrajectory::Waypoint> site_waypoints(std::vector<ProbeSite>& sites, const ProbeParams& params,
                                                      const SiteFinder& f) {
  const double r = params.tool_radius;
  const double d_app = params.approach_distance * r;
  std::vector<ProbeTrajectory::Waypoint> wps;
  double t = 0;
  const auto go = [&](const Eigen::Vector3d& x, double duration) {
    t += std::max(duration, 0.05);
    wps.push_back({t, x});
  };
  const auto travel = [&](const Eigen::Vector3d& x, double speed) {
    go(x, (x - wps.back().position).norm() / speed);
  };
  const Eigen::Vector3d first_start = sites[0].surface_point + d_app * sites[0].normal;
  wps.push_back({0.0, f.lift(first_start)});
  go(f.lift(first_start), 0.3);  // settle
  for (auto& s : sites) {
    const Eigen::Vector3d start = s.surface_point + d_app * s.normal;
    const Eigen::Vector3d press = s.touch_point - params.press_depth * r * s.normal;
    travel(f.lift(start), params.travel_speed);
    travel(start, params.travel_speed);
    travel(s.touch_point, params.approach_speed);
    s.t_touch = t;
    go(press, params.press_time);
    go(press, params.hold_time);
    go(s.touch_point, params.release_time);
    travel(start, 2 * params.approach_speed);
    travel(f.lift(start), params.travel_speed);
  }
  go(wps.back().position, 0.3);
  return wps;
}

}  // namespace

ProbeTrajectory generate_probe_trajectory(const CollisionWorld& world, const ProbeParams& params) {
  if (!(params.tool_radius > 0)) throw InputError("probe: tool radius must be > 0");
  if (params.sites < 1) throw InputError("probe: need at least one site");
  if (!(params.up.norm() > 0)) throw InputError("probe: 'up' must be a non-zero vector");
  SiteFinder f(world, params);
  const double r = params.tool_radius;
  const ObjectRegion o = object_region(world, f.up, r);
  f.z_safe = o.z_safe;
  std::vector<ProbeSite> sites = find_sites(world, params, o, f);
  if (sites.empty()) {
    const Eigen::Vector3d extent = world.bounds_hi() - world.bounds_lo();
    throw InputError("probe: found no reachable surface site (scene extent " +
                     std::to_string(extent.norm()) + ", tool radius " + std::to_string(r) +
                     "); try another seed, tool radius or up axis");
  }
  order_sites(sites);
  std::vector<ProbeTrajectory::Waypoint> wps = site_waypoints(sites, params, f);
  return ProbeTrajectory(std::move(wps), std::move(sites), r);
}

double default_tool_radius(const CollisionWorld& world) { return 0.01 * robust_extent(world); }

double press_depth_for_force(double force, double coupling_stiffness, double hand_stiffness) {
  if (!(force > 0) || !(coupling_stiffness > 0) || !(hand_stiffness > 0) || !std::isfinite(force))
    throw InputError("probe: the press force and the stiffnesses must be > 0");
  return force * (1.0 / coupling_stiffness + 1.0 / hand_stiffness);
}

ProbeParams default_probe_params(const CollisionWorld& world, double tool_radius, int sites, std::uint64_t seed,
                                 double press_depth_m) {
  ProbeParams pp;
  if (press_depth_m > 0) pp.press_depth = press_depth_m / tool_radius;
  pp.sites = sites;
  pp.seed = seed;
  pp.up = world.up();
  pp.tool_radius = tool_radius;
  pp.approach_speed = 2.0 * tool_radius;
  pp.travel_speed = 8.0 * tool_radius;
  return pp;
}

}  // namespace gshaptics
