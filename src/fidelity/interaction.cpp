#include "gshaptics/fidelity/interaction.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>

#include "gshaptics/error.h"
#include "gshaptics/servo/collision_worker.h"
#include "gshaptics/servo/simulated_runtime.h"

namespace gshaptics {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kOnsetForce = 0.1;  // N

// Appends ticks moving the centre along `path` (arc length u in [0, length]) at `speed`.
void move_along(Script& s, double rate_hz, double length, double speed,
                const std::function<Eigen::Vector3d(double)>& at, const std::function<double(double)>& delta_at,
                bool loading, bool measured_middle, double path0, double margin) {
  const double dt = 1.0 / rate_hz;
  const auto n = std::size_t(std::ceil(length / (speed * dt)));
  for (std::size_t i = 0; i <= n; ++i) {
    const double u = std::min(length, double(i) * speed * dt);
    ScriptTick t;
    t.time = s.ticks.empty() ? 0.0 : s.ticks.back().time + dt;
    t.position = at(u);
    const double du = 1e-6;
    const double u2 = std::min(length, u + du), u1 = std::max(0.0, u2 - du);
    t.velocity = i == n ? Eigen::Vector3d::Zero() : Eigen::Vector3d((at(u2) - at(u1)) / (u2 - u1) * speed);
    t.delta = delta_at(u);
    t.path = path0 + u;
    t.loading = loading;
    t.measured = measured_middle && u >= margin && u <= length - margin;
    s.ticks.push_back(t);
  }
}

void hold_still(Script& s, double rate_hz, double seconds) {
  const double dt = 1.0 / rate_hz;
  const ScriptTick last = s.ticks.back();
  for (std::size_t i = 0; i < std::size_t(std::lround(seconds * rate_hz)); ++i) {
    ScriptTick t = last;
    t.time = s.ticks.back().time + dt;
    t.velocity.setZero();
    t.loading = false;
    t.measured = false;
    s.ticks.push_back(t);
  }
}

}  // namespace

std::string_view to_string(Scenario s) {
  switch (s) {
    case Scenario::kPress: return "press";
    case Scenario::kSlide: return "slide";
    case Scenario::kPushThrough: return "push-through";
  }
  return "press";
}

Eigen::Vector3d distance_gradient(const AnalyticShape& shape, const Eigen::Vector3d& p) {
  const double h = 1e-7;
  Eigen::Vector3d g;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(i) * h;
    g[i] = (shape.signed_distance(p + e) - shape.signed_distance(p - e)) / (2 * h);
  }
  return g.norm() > 0 ? Eigen::Vector3d(g.normalized()) : Eigen::Vector3d::UnitZ();
}

Script press_script(const AnalyticShape& shape, const ContactSite& site, double r, double depth, double rate_hz,
                    double speed, double hold, double start_off) {
  if (!(r > 0 && depth > 0 && rate_hz > 0 && speed > 0 && hold >= 0 && start_off > 0))
    throw InputError("press script: radius, depth, rate, speed and start offset must be > 0");
  Script s;
  s.scenario = depth > 0.015 ? Scenario::kPushThrough : Scenario::kPress;
  s.site = site;
  s.tool_radius = r;
  s.max_delta = depth;
  // Concave sites are pressed along the bisector: the faces see k = n . face normal of it.
  const NormalCone cone = shape.normal_cone(site.point);
  const double k = site.feature == "concave" ? site.normal.dot(cone.generators[0]) : 1.0;
  const double s0 = (r + start_off) / k, s1 = (r - depth) / k;
  const auto at = [&](double line) { return Eigen::Vector3d(site.point + site.normal * line); };
  const auto delta_of = [&](double line) { return r - k * line; };
  move_along(s, rate_hz, s0 - s1, speed, [&](double u) { return at(s0 - u); },
             [&](double u) { return delta_of(s0 - u); }, true, false, 0, 0);
  hold_still(s, rate_hz, hold);
  move_along(s, rate_hz, s0 - s1, speed, [&](double u) { return at(s1 + u); },
             [&](double u) { return delta_of(s1 + u); }, false, false, 0, 0);
  return s;
}

Script slide_script(const AnalyticShape& shape, double r, double rate_hz, double delta, double length, double speed) {
  if (!(r > delta && delta >= 0 && length > 0 && rate_hz > 0 && speed > 0))
    throw InputError("slide script: need radius > delta >= 0 and positive length, rate and speed");
  const double rho = r - delta;  // centre's distance from the surface
  std::function<Eigen::Vector3d(double)> centre;
  double lc = length;
  switch (shape.kind()) {
    case ShapeKind::kPlane:
      centre = [=](double u) { return Eigen::Vector3d(-length / 2 + u, 0, rho); };
      break;
    case ShapeKind::kSphere: {
      const double R = 0.1, a0 = -length / (2 * R);
      lc = (R + rho) * length / R;
      centre = [=](double u) {
        const double a = a0 + u / (R + rho);
        return Eigen::Vector3d((R + rho) * std::sin(a), 0, (R + rho) * std::cos(a));
      };
      break;
    }
    case ShapeKind::kCube: {
      const double h = 0.1, half = length / 2, arc = rho * kPi / 2;
      lc = length + arc;
      centre = [=](double u) {
        if (u <= half) return Eigen::Vector3d(h - half + u, 0, h + rho);
        if (u <= half + arc) {
          const double phi = (u - half) / rho;
          return Eigen::Vector3d(h + rho * std::sin(phi), 0, h + rho * std::cos(phi));
        }
        return Eigen::Vector3d(h + rho, 0, h - (u - half - arc));
      };
      break;
    }
    case ShapeKind::kCorner90: {
      // Along the floor into the wall, then up the wall: the centre meets the wall at (rho, rho).
      const double half = length / 2;
      centre = [=](double u) {
        if (u <= half) return Eigen::Vector3d(rho + half - u, 0, rho);
        return Eigen::Vector3d(rho, 0, rho + (u - half));
      };
      break;
    }
    default:
      throw InputError("slide script: shape '" + std::string(shape.name()) +
                       "' has no slide (plane, sphere, cube, corner-90)");
  }
  Script s;
  s.scenario = Scenario::kSlide;
  s.tool_radius = r;
  s.max_delta = delta;
  const Eigen::Vector3d c0 = centre(0), c1 = centre(lc);
  const Eigen::Vector3d n0 = distance_gradient(shape, c0), n1 = distance_gradient(shape, c1);
  s.site = {c0 - n0 * rho, n0, "face"};
  const double off = 0.02 + delta;
  move_along(s, rate_hz, off, 0.02, [&](double u) { return Eigen::Vector3d(c0 + n0 * (off - u)); },
             [&](double u) { return delta - (off - u); }, true, false, 0, 0);
  move_along(s, rate_hz, lc, speed, centre, [&](double) { return delta; }, false, true, 0, 0.005);
  move_along(s, rate_hz, off, 0.02, [&](double u) { return Eigen::Vector3d(c1 + n1 * u); },
             [&](double u) { return delta - u; }, false, false, lc, 0);
  return s;
}

namespace {
std::vector<ScriptedPose> script_poses(const Script& script) {
  std::vector<ScriptedPose> poses(script.ticks.size());
  for (std::size_t i = 0; i < poses.size(); ++i)
    poses[i] = {script.ticks[i].position, script.ticks[i].velocity, script.ticks[i].orientation};
  return poses;
}
}  // namespace

ScriptTrace play_script(ForceRenderer& renderer, const Script& script, double rate_hz, const PlayOptions& options) {
  if (script.ticks.empty()) throw InputError("play script: empty script");
  renderer.reset();
  ScriptedDevice device(script_poses(script), rate_hz);
  RuntimeConfig c;
  c.rate_hz = rate_hz;
  c.inline_query = options.inline_query;
  c.latency_ticks = options.latency_ticks;
  c.safety = options.safety;
  if (script.tool.count > 0)
    c.tool = tool_shape_for(script.tool);
  else
    c.tool.semi_axes = Eigen::Vector3d::Constant(script.tool_radius);
  c.log_capacity = script.ticks.size() + std::size_t(std::ceil((c.stop_timeout + 0.01) * rate_hz)) + 2;
  SimulatedRuntime rt(device, c, std::make_unique<BorrowedRenderer>(renderer));
  rt.run();
  const std::vector<TickRecord>& rec = rt.log().records();
  ScriptTrace tr;
  const std::size_t n = script.ticks.size();
  tr.force.assign(n, Eigen::Vector3d::Zero());
  tr.render_us.assign(n, 0.0f);
  tr.contacts.assign(n, 0);
  tr.torque.assign(n, Eigen::Vector3d::Zero());
  tr.proxy.assign(n, Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < n && i < rec.size(); ++i) {
    tr.force[i] = rec[i].force;
    tr.torque[i] = rec[i].torque;
    tr.proxy[i] = rec[i].proxy;
    tr.render_us[i] = rec[i].query_us;
    tr.contacts[i] = rec[i].counts.contacts;
  }
  return tr;
}

PressMetrics press_metrics(const AnalyticShape& shape, const Script& script, const ScriptTrace& trace) {
  PressMetrics m;
  const NormalCone cone = shape.normal_cone(script.site.point);
  const Eigen::Vector3d n = script.site.normal;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int fit = 0;
  std::size_t surface_onset = script.ticks.size();
  for (std::size_t i = 0; i < script.ticks.size(); ++i) {
    const ScriptTick& t = script.ticks[i];
    const Eigen::Vector3d& f = trace.force[i];
    const double fm = f.norm();
    // W = -sum F . v dt with v dt the tick's displacement, trapezoidal in F (exact for a spring
    // sampled at the same points in and out).
    if (i + 1 < script.ticks.size())
      m.energy_j -= 0.5 * (f + trace.force[i + 1]).dot(script.ticks[i + 1].position - t.position);
    if (fm >= kOnsetForce) {
      m.direction_deg.push_back(cone.angle_deg(f));
      if (t.delta <= 0.002) m.shallow_direction_deg.push_back(m.direction_deg.back());
    }
    if (!t.loading) continue;
    m.peak_force = std::max(m.peak_force, fm);
    if (std::isnan(m.onset_mm) && fm > kOnsetForce) m.onset_mm = t.delta * 1e3;
    if (surface_onset == script.ticks.size() && t.delta >= 0 && fm > kOnsetForce) surface_onset = i;
    if (t.delta >= 0.001 && t.delta <= 0.005) {
      const double x = t.delta * 1e3;
      sx += x, sy += fm, sxx += x * x, sxy += x * fm;
      ++fit;
    }
  }
  if (fit >= 3) {
    const double den = fit * sxx - sx * sx;
    if (den > 0) m.stiffness_n_per_mm = (fit * sxy - sx * sy) / den;
  }
  // Hold-through: from the onset on the surface, the deepest delta before the force first turns
  // inward (more than 90 degrees from the outward normal) or collapses below 10 % of the peak
  // reached so far.
  if (surface_onset < script.ticks.size()) {
    m.hold_through_mm = script.ticks[surface_onset].delta * 1e3;
    double peak_so_far = 0;
    for (std::size_t i = surface_onset; i < script.ticks.size() && script.ticks[i].loading; ++i) {
      const Eigen::Vector3d& f = trace.force[i];
      peak_so_far = std::max(peak_so_far, f.norm());
      if (!(f.dot(n) > 0 && f.norm() >= 0.1 * peak_so_far)) break;
      m.hold_through_mm = script.ticks[i].delta * 1e3;
    }
    m.never_lost = m.hold_through_mm >= script.max_delta * 1e3 - 0.1;
  }
  return m;
}

SlideMetrics slide_metrics(const AnalyticShape& shape, const Script& script, const ScriptTrace& trace) {
  SlideMetrics m;
  double s = 0, ss = 0, ft = 0, fn = 0;
  int count = 0, lost = 0;
  for (std::size_t i = 0; i < script.ticks.size(); ++i) {
    const ScriptTick& t = script.ticks[i];
    if (!t.measured) continue;
    const Eigen::Vector3d& f = trace.force[i];
    const double fm = f.norm();
    const Eigen::Vector3d nrm = distance_gradient(shape, t.position);
    const double f_n = f.dot(nrm);
    s += fm;
    ss += fm * fm;
    fn += f_n;
    ft += (f - f_n * nrm).norm();
    ++count;
    if (fm < kOnsetForce) ++lost;
    if (fm >= kOnsetForce) m.direction_deg.push_back(shape.sphere_cone(t.position, script.tool_radius).angle_deg(f));
    if (i > 0 && script.ticks[i - 1].measured)
      m.largest_step = std::max(std::isnan(m.largest_step) ? 0.0 : m.largest_step, (f - trace.force[i - 1]).norm());
  }
  if (count == 0) return m;
  m.mean_force = s / count;
  m.lost_share = double(lost) / count;
  const double var = std::max(0.0, ss / count - m.mean_force * m.mean_force);
  if (m.mean_force > 0) m.force_rsd = std::sqrt(var) / m.mean_force;
  if (fn > 0) m.tangential_over_normal = ft / fn;
  return m;
}

}  // namespace gshaptics
