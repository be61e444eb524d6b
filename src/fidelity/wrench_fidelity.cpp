#include "gshaptics/fidelity/wrench_fidelity.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <random>

#include "gshaptics/error.h"

namespace gshaptics {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180;
constexpr double kTieLift = 1e-9;       // parts whose lifts agree this closely (m) touch together
constexpr double kForceOnset = 0.1;     // N: the direction of F is scored from here
constexpr double kTorqueOnset = 0.5;    // N: the torque is scored from here
constexpr double kLeverFloor = 0.001;   // m: below this analytic lever the torque is taken as zero

// Sigma^-1 of a posed part.
Eigen::Matrix3d inverse_shape(const ToolEllipsoid& e) {
  const Eigen::Matrix3d r = e.rotation.toRotationMatrix();
  return r * e.semi_axes.cwiseInverse().cwiseAbs2().asDiagonal() * r.transpose();
}

// One part against the feature: the lift along u to just touch, the contact point and the
// normal (feature -> tool) on the lifted part. lift -inf: it never touches.
struct PartContact {
  double lift = -INFINITY;
  Eigen::Vector3d point = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::UnitZ();
};

PartContact part_contact(const ToolEllipsoid& e, const ContactFeature& f, const Eigen::Vector3d& u) {
  PartContact pc;
  if (f.kind == ContactFeature::Kind::kPlane) {
    const Eigen::Vector3d& m = f.direction;
    const double mu = m.dot(u);
    if (!(mu > 0)) return pc;
    const Eigen::Vector3d foot = e.surface_point(-m);  // the part's point deepest along -m
    const double gap = m.dot(foot - f.point);
    pc.lift = -gap / mu;
    pc.point = foot + u * pc.lift;
    pc.normal = m;
    return pc;
  }
  const Eigen::Matrix3d a = inverse_shape(e);
  const Eigen::Vector3d& d = f.direction;
  const Eigen::Vector3d ad = a * d;
  const double dad = d.dot(ad);
  const Eigen::Matrix3d p = a - ad * ad.transpose() / dad;
  const Eigen::Vector3d w0 = f.point - e.center;
  const double qa = u.dot(p * u), qb = u.dot(p * w0), qc = w0.dot(p * w0) - 1;
  const double disc = qb * qb - qa * qc;
  if (!(qa > 0) || disc < 0) return pc;
  pc.lift = (qb + std::sqrt(disc)) / qa;
  const Eigen::Vector3d w = w0 - pc.lift * u;  // line point - lifted centre, before sliding along the line
  const double s = -d.dot(a * w) / dad;
  pc.point = f.point + s * d;
  const Eigen::Vector3d outward = a * (pc.point - (e.center + pc.lift * u));
  pc.normal = -outward.normalized();
  return pc;
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const double c = a.normalized().dot(b.normalized());
  return std::acos(std::clamp(c, -1.0, 1.0)) / kDeg;
}

Eigen::Quaterniond about(const Eigen::Vector3d& axis, double deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * kDeg, axis));
}

// Moves `guess` along up so that the case's tool just touches.
void settle(WrenchCase& c, const Eigen::Vector3d& guess) {
  c.touch = guess;
  const AnalyticContact a = analytic_contact(c, guess);
  if (!std::isfinite(a.lift)) throw InputError("wrench case '" + c.name + "': the tool never touches its feature");
  c.touch = guess + c.up * a.lift;
}

}  // namespace

AnalyticContact analytic_contact(const WrenchCase& c, const Eigen::Vector3d& tcp) {
  std::array<ToolEllipsoid, kMaxToolParts> parts{};
  const int n = c.tool.posed(tcp, c.orientation, parts);
  std::array<PartContact, kMaxToolParts> pc{};
  AnalyticContact out;
  for (int j = 0; j < n; ++j) {
    pc[std::size_t(j)] = part_contact(parts[std::size_t(j)], c.feature, c.up);
    out.lift = std::max(out.lift, pc[std::size_t(j)].lift);
  }
  if (!std::isfinite(out.lift)) return out;
  Eigen::Vector3d point = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::Zero();
  for (int j = 0; j < n; ++j) {
    const PartContact& p = pc[std::size_t(j)];
    if (!(p.lift >= out.lift - kTieLift)) continue;
    point += p.point + c.up * (out.lift - p.lift);
    normal += p.normal;
    ++out.parts;
  }
  out.point = point / double(out.parts);
  out.normal = normal.normalized();
  return out;
}

std::vector<WrenchCase> wrench_cases(ShapeKind shape, const WrenchTools& tools, int sites, std::uint64_t seed) {
  if (sites < 1) throw InputError("wrench cases: sites must be >= 1");
  tools.stylus.validate("wrench cases: stylus");
  tools.disc.validate("wrench cases: disc");
  std::mt19937_64 rng(seed * 7919 + 36);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<WrenchCase> out;
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ(), y = Eigen::Vector3d::UnitY();
  if (shape == ShapeKind::kPlane) {
    struct Kind {
      const char* name;
      const CompoundTool* tool;
      Eigen::Quaterniond tilt;
    };
    const Kind kinds[] = {{"stylus tip-first 0 deg", &tools.stylus, about(y, 0)},
                          {"stylus tip-first 30 deg", &tools.stylus, about(y, 30)},
                          {"stylus tip-first 60 deg", &tools.stylus, about(y, 60)},
                          {"stylus side-on", &tools.stylus, about(y, 90)},
                          {"disc flat", &tools.disc, about(y, 0)},
                          {"disc tilted 30 deg", &tools.disc, about(y, 30)}};
    for (const Kind& k : kinds)
      for (int i = 0; i < sites; ++i) {
        WrenchCase c;
        c.name = k.name;
        c.shape = shape;
        c.tool = *k.tool;
        const double yaw = 360 * unit(rng), r = 0.05 * std::sqrt(unit(rng)), phi = 2 * kPi * unit(rng);
        c.orientation = about(z, yaw) * k.tilt;
        c.up = z;
        c.feature = {ContactFeature::Kind::kPlane, Eigen::Vector3d::Zero(), z};
        settle(c, Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), 0.2));
        out.push_back(c);
      }
  } else if (shape == ShapeKind::kCube) {
    // The stylus runs from its tip (outside the side face, below the top) up over a top edge at
    // 30 deg, touching the edge with its third part (at 11 L / 18 from the tip) at the end of
    // that part's short axis; which of the four top edges, and where along it, is drawn.
    const double half = 0.1, tilt = 30;
    for (int i = 0; i < sites; ++i) {
      WrenchCase c;
      c.name = "stylus across an edge";
      c.shape = shape;
      c.tool = tools.stylus;
      const int part = std::min(2, c.tool.count - 1);
      const Eigen::Quaterniond yaw = about(z, 90.0 * std::floor(4 * unit(rng)));
      const double along = -0.05 + 0.1 * unit(rng);
      const Eigen::Vector3d edge = yaw * Eigen::Vector3d(half, along, half);
      const Eigen::Vector3d axis = yaw * Eigen::Vector3d(-std::cos(tilt * kDeg), 0, std::sin(tilt * kDeg));
      const Eigen::Vector3d side = yaw * Eigen::Vector3d(std::sin(tilt * kDeg), 0, std::cos(tilt * kDeg));
      c.orientation = Eigen::Quaterniond::FromTwoVectors(z, axis);
      c.up = z;
      c.feature = {ContactFeature::Kind::kLine, edge, yaw * y};
      const ToolPart& p = c.tool.parts[std::size_t(part)];
      const double radius = p.semi_axes.head<2>().minCoeff();
      settle(c, edge + side * radius - c.orientation * p.offset);
      out.push_back(c);
    }
  }
  return out;
}

Script wrench_script(const WrenchCase& c, double depth, double rate_hz, double speed, double hold, double start_off) {
  if (!(depth > 0 && rate_hz > 0 && speed > 0 && hold >= 0 && start_off > 0))
    throw InputError("wrench script: depth, rate, speed and start offset must be > 0");
  Script s;
  s.scenario = Scenario::kPress;
  s.tool = c.tool;
  s.max_delta = depth;
  const AnalyticContact at_touch = analytic_contact(c, c.touch);
  s.site = {at_touch.point, c.up, c.feature.kind == ContactFeature::Kind::kLine ? "edge" : "face"};
  const double dt = 1.0 / rate_hz, travel = start_off + depth;
  const auto n = std::size_t(std::ceil(travel / (speed * dt)));
  const auto push = [&](double delta, const Eigen::Vector3d& v, bool loading) {
    ScriptTick t;
    t.time = s.ticks.empty() ? 0.0 : s.ticks.back().time + dt;
    t.position = c.touch - c.up * delta;
    t.velocity = v;
    t.orientation = c.orientation;
    t.delta = delta;
    t.loading = loading;
    s.ticks.push_back(t);
  };
  for (std::size_t i = 0; i <= n; ++i)
    push(-start_off + std::min(travel, double(i) * speed * dt), i == n ? Eigen::Vector3d::Zero() : Eigen::Vector3d(-c.up * speed), true);
  for (std::size_t i = 0; i < std::size_t(std::lround(hold * rate_hz)); ++i) push(depth, Eigen::Vector3d::Zero(), false);
  for (std::size_t i = 0; i <= n; ++i)
    push(depth - std::min(travel, double(i) * speed * dt), i == n ? Eigen::Vector3d::Zero() : Eigen::Vector3d(c.up * speed), false);
  return s;
}

WrenchMetrics wrench_metrics(const WrenchCase& c, const Script& script, const ScriptTrace& trace, bool proxy,
                             double tau_limit) {
  WrenchMetrics m;
  m.press = press_metrics(AnalyticShape(c.shape), script, trace);
  std::vector<double> levers;
  if (proxy) m.deepest_part_mm = -INFINITY;
  for (std::size_t i = 0; i < script.ticks.size() && i < trace.force.size(); ++i) {
    const ScriptTick& t = script.ticks[i];
    if (proxy) m.deepest_part_mm = std::max(m.deepest_part_mm, analytic_contact(c, trace.proxy[i]).lift * 1e3);
    const Eigen::Vector3d& f = trace.force[i];
    const double fm = f.norm();
    if (fm < kForceOnset) continue;
    const AnalyticContact a = analytic_contact(c, t.position);
    m.force_dir_deg.push_back(angle_deg(f, a.normal));
    if (fm < kTorqueOnset) continue;
    const Eigen::Vector3d resting = t.position + c.up * a.lift;
    const Eigen::Vector3d expected = (a.point - resting).cross(fm * a.normal);
    const Eigen::Vector3d& tau = trace.torque[i];
    const double lever = expected.norm() / fm;
    levers.push_back(lever * 1e3);
    if (lever < kLeverFloor) {
      m.zero_lever_mm.push_back(tau.norm() / fm * 1e3);
      continue;
    }
    m.torque_ratio.push_back(tau.norm() / std::min(expected.norm(), tau_limit));
    m.torque_dir_deg.push_back(tau.norm() > 0 ? angle_deg(tau, expected) : 180.0);
  }
  if (!levers.empty()) {
    std::nth_element(levers.begin(), levers.begin() + std::ptrdiff_t(levers.size() / 2), levers.end());
    m.analytic_lever_mm = levers[levers.size() / 2];
  }
  return m;
}

}  // namespace gshaptics
