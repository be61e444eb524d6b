#include "gshaptics/fidelity/analytic_shape.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

#include "gshaptics/error.h"

namespace gshaptics {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kPlaneHalf = 0.2;
constexpr double kSphereR = 0.1;
constexpr double kCubeHalf = 0.1;
constexpr double kPlateHalf = 0.15;
constexpr double kCylR = 0.05, kCylHalfLength = 0.15;
constexpr double kCornerDepth = 0.2, kCornerHalfWidth = 0.1;
constexpr double kGrooveFace = 0.15, kGrooveHalfWidth = 0.1;
const double kC30 = std::cos(kPi / 6), kS30 = std::sin(kPi / 6);

double plate_half_thickness(ShapeKind k) { return k == ShapeKind::kPlate2mm ? 0.001 : 0.0025; }

Eigen::Vector3d box_half(ShapeKind k) {
  if (k == ShapeKind::kCube) return Eigen::Vector3d::Constant(kCubeHalf);
  return {kPlateHalf, kPlateHalf, plate_half_thickness(k)};
}


// V-groove face normals (into the free wedge) and in-face directions away from the groove line.
Eigen::Vector3d groove_normal(int side) { return {side == 0 ? -kC30 : kC30, 0, kS30}; }
Eigen::Vector3d groove_dir(int side) { return {side == 0 ? kS30 : -kS30, 0, kC30}; }

Eigen::Vector3d any_tangent(const Eigen::Vector3d& n) {
  const Eigen::Vector3d a = std::fabs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  return (a - a.dot(n) * n).normalized();
}

// Cell-centred samples of the rectangle origin + a u + b v, a in [0, la], b in [0, lb].
void grid(std::vector<SurfaceSample>& out, const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double la,
          const Eigen::Vector3d& v, double lb, const Eigen::Vector3d& normal, double spacing) {
  const int na = std::max(1, int(std::lround(la / spacing))), nb = std::max(1, int(std::lround(lb / spacing)));
  for (int i = 0; i < na; ++i)
    for (int j = 0; j < nb; ++j)
      out.push_back({origin + u * (la * (i + 0.5) / na) + v * (lb * (j + 0.5) / nb), normal, u});
}

}  // namespace

const std::vector<ShapeKind>& all_shapes() {
  static const std::vector<ShapeKind> kAll = {ShapeKind::kPlane,    ShapeKind::kSphere,   ShapeKind::kCube,
                                              ShapeKind::kPlate2mm, ShapeKind::kPlate5mm, ShapeKind::kCylinder,
                                              ShapeKind::kCorner90, ShapeKind::kVGroove60};
  return kAll;
}

std::string_view to_string(ShapeKind kind) {
  switch (kind) {
    case ShapeKind::kPlane: return "plane";
    case ShapeKind::kSphere: return "sphere";
    case ShapeKind::kCube: return "cube";
    case ShapeKind::kPlate2mm: return "plate-2mm";
    case ShapeKind::kPlate5mm: return "plate-5mm";
    case ShapeKind::kCylinder: return "cylinder";
    case ShapeKind::kCorner90: return "corner-90";
    case ShapeKind::kVGroove60: return "v-groove-60";
  }
  return "plane";
}

ShapeKind parse_shape(std::string_view name, const std::string& source) {
  for (ShapeKind k : all_shapes())
    if (to_string(k) == name) return k;
  throw InputError(source + ": unknown shape '" + std::string(name) +
                   "' (expected plane, sphere, cube, plate-2mm, plate-5mm, cylinder, corner-90, v-groove-60)");
}

double NormalCone::angle_deg(const Eigen::Vector3d& direction) const {
  const Eigen::Vector3d d = direction.normalized();
  // Projection onto the cone: the best of the projections onto every face of the cone (each
  // subset of generators with non-negative coefficients); inside it, the angle is 0.
  // On the cone's extreme rays the best is the generator itself (this also covers a direction in
  // the polar cone, whose projections all have negative coefficients).
  double best_cos = -1.0;
  const int n = count;
  for (int i = 0; i < n; ++i) best_cos = std::max(best_cos, generators[i].dot(d));
  for (int mask = 1; mask < (1 << n); ++mask) {
    Eigen::Matrix<double, 3, Eigen::Dynamic> G(3, 0);
    for (int i = 0; i < n; ++i)
      if (mask & (1 << i)) {
        G.conservativeResize(Eigen::NoChange, G.cols() + 1);
        G.col(G.cols() - 1) = generators[i];
      }
    const Eigen::VectorXd c = (G.transpose() * G).ldlt().solve(G.transpose() * d);
    if ((c.array() < -1e-12).any()) continue;
    const Eigen::Vector3d p = G * c;
    if (p.norm() < 1e-12) continue;
    best_cos = std::max(best_cos, p.normalized().dot(d));
  }
  return std::acos(std::clamp(best_cos, -1.0, 1.0)) * 180.0 / kPi;
}

Eigen::Vector3d NormalCone::axis() const {
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  for (int i = 0; i < count; ++i) s += generators[i];
  return s.normalized();
}

AnalyticShape::AnalyticShape(ShapeKind kind) : kind_(kind) {}

double AnalyticShape::signed_distance(const Eigen::Vector3d& p) const {
  switch (kind_) {
    case ShapeKind::kPlane: return p.z();
    case ShapeKind::kSphere: return p.norm() - kSphereR;
    case ShapeKind::kCylinder: return std::hypot(p.x(), p.y()) - kCylR;
    case ShapeKind::kCorner90: {
      if (p.x() >= 0 && p.z() >= 0) return std::min(p.x(), p.z());
      return -std::hypot(std::max(-p.x(), 0.0), std::max(-p.z(), 0.0));
    }
    case ShapeKind::kVGroove60: return std::min(p.dot(groove_normal(0)), p.dot(groove_normal(1)));
    default: {  // boxes
      const Eigen::Vector3d q = p.cwiseAbs() - box_half(kind_);
      return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
    }
  }
}

NormalCone AnalyticShape::normal_cone(const Eigen::Vector3d& p, double tolerance) const {
  NormalCone c;
  const auto add = [&c](const Eigen::Vector3d& n) {
    if (c.count < 3) c.generators[c.count++] = n.normalized();
  };
  switch (kind_) {
    case ShapeKind::kPlane: add(Eigen::Vector3d::UnitZ()); break;
    case ShapeKind::kSphere: add(p.norm() > 0 ? p : Eigen::Vector3d::UnitZ()); break;
    case ShapeKind::kCylinder: {
      const Eigen::Vector3d r(p.x(), p.y(), 0);
      add(r.norm() > 0 ? r : Eigen::Vector3d::UnitX());
      break;
    }
    case ShapeKind::kCorner90: {
      const double dx = std::fabs(p.x()), dz = std::fabs(p.z());
      const double m = std::min(dx, dz);
      if (dz <= m + tolerance) add(Eigen::Vector3d::UnitZ());
      if (dx <= m + tolerance) add(Eigen::Vector3d::UnitX());
      break;
    }
    case ShapeKind::kVGroove60: {
      const double d0 = std::fabs(p.dot(groove_normal(0))), d1 = std::fabs(p.dot(groove_normal(1)));
      const double m = std::min(d0, d1);
      if (d0 <= m + tolerance) add(groove_normal(0));
      if (d1 <= m + tolerance) add(groove_normal(1));
      break;
    }
    default: {
      const Eigen::Vector3d q = p.cwiseAbs() - box_half(kind_);
      if (q.maxCoeff() > 0) {  // outside: the axes where p is beyond the box are the active faces
        for (int i = 0; i < 3; ++i)
          if (q[i] > -tolerance) add(Eigen::Vector3d::Unit(i) * (p[i] >= 0 ? 1.0 : -1.0));
      } else {  // inside: the nearest faces
        const double m = q.maxCoeff();
        for (int i = 0; i < 3; ++i)
          if (q[i] >= m - tolerance) add(Eigen::Vector3d::Unit(i) * (p[i] >= 0 ? 1.0 : -1.0));
      }
    }
  }
  return c;
}

NormalCone AnalyticShape::sphere_cone(const Eigen::Vector3d& center, double radius) const {
  // A concave shape's two faces, by their outward normals (the free side): the sphere reaches a
  // face when its centre lies within `radius` of the face's plane.
  Eigen::Vector3d normals[2];
  switch (kind_) {
    case ShapeKind::kCorner90: normals[0] = Eigen::Vector3d::UnitZ(), normals[1] = Eigen::Vector3d::UnitX(); break;
    case ShapeKind::kVGroove60: normals[0] = groove_normal(0), normals[1] = groove_normal(1); break;
    default: return normal_cone(center);
  }
  if (!(center.dot(normals[0]) < radius && center.dot(normals[1]) < radius)) return normal_cone(center);
  NormalCone c;
  c.generators[0] = normals[0];
  c.generators[1] = normals[1];
  c.count = 2;
  return c;
}

std::vector<SurfaceSample> AnalyticShape::sample_surface(double spacing) const {
  std::vector<SurfaceSample> out;
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();
  switch (kind_) {
    case ShapeKind::kPlane:
      grid(out, {-kPlaneHalf, -kPlaneHalf, 0}, X, 2 * kPlaneHalf, Y, 2 * kPlaneHalf, Z, spacing);
      break;
    case ShapeKind::kSphere: {  // Fibonacci lattice: equal-area points
      const auto n = std::size_t(std::lround(4 * kPi * kSphereR * kSphereR / (spacing * spacing)));
      const double golden = kPi * (3.0 - std::sqrt(5.0));
      for (std::size_t i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (double(i) + 0.5) / double(n);
        const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
        const Eigen::Vector3d nrm(r * std::cos(golden * double(i)), r * std::sin(golden * double(i)), z);
        out.push_back({kSphereR * nrm, nrm, any_tangent(nrm)});
      }
      break;
    }
    case ShapeKind::kCylinder: {
      const int na = std::max(8, int(std::lround(2 * kPi * kCylR / spacing)));
      const int nz = std::max(1, int(std::lround(2 * kCylHalfLength / spacing)));
      for (int i = 0; i < na; ++i)
        for (int j = 0; j < nz; ++j) {
          const double a = 2 * kPi * (i + 0.5) / na;
          const Eigen::Vector3d nrm(std::cos(a), std::sin(a), 0);
          out.push_back({kCylR * nrm + Z * (-kCylHalfLength + 2 * kCylHalfLength * (j + 0.5) / nz), nrm, Z});
        }
      break;
    }
    case ShapeKind::kCorner90:
      grid(out, {0, -kCornerHalfWidth, 0}, X, kCornerDepth, Y, 2 * kCornerHalfWidth, Z, spacing);
      grid(out, {0, -kCornerHalfWidth, 0}, Z, kCornerDepth, Y, 2 * kCornerHalfWidth, X, spacing);
      break;
    case ShapeKind::kVGroove60:
      for (int side = 0; side < 2; ++side)
        grid(out, {0, -kGrooveHalfWidth, 0}, groove_dir(side), kGrooveFace, Y, 2 * kGrooveHalfWidth,
             groove_normal(side), spacing);
      break;
    default: {
      const Eigen::Vector3d h = box_half(kind_);
      for (int axis = 0; axis < 3; ++axis) {
        if (kind_ != ShapeKind::kCube && axis != 2) continue;  // plates: the two large faces
        const int a = (axis + 1) % 3, b = (axis + 2) % 3;
        for (double sgn : {1.0, -1.0}) {
          Eigen::Vector3d origin = -h;
          origin[axis] = sgn * h[axis];
          grid(out, origin, Eigen::Vector3d::Unit(a), 2 * h[a], Eigen::Vector3d::Unit(b), 2 * h[b],
               Eigen::Vector3d::Unit(axis) * sgn, spacing);
        }
      }
    }
  }
  return out;
}

bool AnalyticShape::has_convex_edges() const noexcept {
  return kind_ == ShapeKind::kCube || kind_ == ShapeKind::kPlate2mm || kind_ == ShapeKind::kPlate5mm;
}

int AnalyticShape::convex_borders(const SurfaceSample& sample, std::array<FaceBorder, 2>& out) const {
  if (!has_convex_edges()) return 0;
  const Eigen::Vector3d h = box_half(kind_);
  int axis = 0;
  sample.normal.cwiseAbs().maxCoeff(&axis);
  for (int k = 0; k < 2; ++k) {
    const int a = (axis + 1 + k) % 3;
    const double p = sample.position[a];
    out[std::size_t(k)].outward = Eigen::Vector3d::Unit(a) * (p >= 0 ? 1.0 : -1.0);
    out[std::size_t(k)].distance = std::max(0.0, h[a] - std::abs(p));
  }
  return 2;
}

std::vector<ContactSite> AnalyticShape::press_sites(int count, std::uint64_t seed, double margin) const {
  std::mt19937_64 rng(seed);
  const auto uni = [&rng](double lo, double hi) {
    return lo + (hi - lo) * double(rng() >> 11) * (1.0 / 9007199254740992.0);
  };
  std::vector<ContactSite> sites;
  for (int i = 0; i < count; ++i) {
    ContactSite s;
    switch (kind_) {
      case ShapeKind::kPlane: {
        const double e = kPlaneHalf - margin;
        s.point = {uni(-e, e), uni(-e, e), 0};
        break;
      }
      case ShapeKind::kSphere: {
        Eigen::Vector3d d;
        do d = {uni(-1, 1), uni(-1, 1), uni(-1, 1)};
        while (d.norm() > 1 || d.norm() < 0.1);
        s.normal = d.normalized();
        s.point = kSphereR * s.normal;
        break;
      }
      case ShapeKind::kCylinder: {
        const double a = uni(0, 2 * kPi);
        s.normal = {std::cos(a), std::sin(a), 0};
        s.point = kCylR * s.normal + Eigen::Vector3d(0, 0, uni(-kCylHalfLength + margin, kCylHalfLength - margin));
        break;
      }
      case ShapeKind::kCorner90:
      case ShapeKind::kVGroove60: {
        const double y = uni(-kCornerHalfWidth + margin, kCornerHalfWidth - margin);
        const int which = i % 3;  // floor/face 0, wall/face 1, the concave line
        const double along = uni(margin, (kind_ == ShapeKind::kCorner90 ? kCornerDepth : kGrooveFace) - margin);
        if (kind_ == ShapeKind::kCorner90) {
          if (which == 0) s = {{along, y, 0}, Eigen::Vector3d::UnitZ(), "face"};
          if (which == 1) s = {{0, y, along}, Eigen::Vector3d::UnitX(), "face"};
          if (which == 2) s = {{0, y, 0}, Eigen::Vector3d(1, 0, 1).normalized(), "concave"};
        } else {
          if (which < 2) s = {groove_dir(which) * along + Eigen::Vector3d(0, y, 0), groove_normal(which), "face"};
          if (which == 2) s = {{0, y, 0}, Eigen::Vector3d::UnitZ(), "concave"};
        }
        break;
      }
      default: {
        const Eigen::Vector3d h = box_half(kind_);
        if (kind_ != ShapeKind::kCube) {
          s.point = {uni(-h.x() + margin, h.x() - margin), uni(-h.y() + margin, h.y() - margin), h.z()};
          break;
        }
        // Cube: faces 40 %, edges 40 %, corners 20 % (deterministic by index).
        const int kind = i % 5;
        Eigen::Vector3d sign(uni(0, 1) < 0.5 ? -1 : 1, uni(0, 1) < 0.5 ? -1 : 1, uni(0, 1) < 0.5 ? -1 : 1);
        const int axis = int(uni(0, 3)) % 3;
        if (kind < 2) {  // a face: one coordinate on the face, two free
          s.point = {uni(-h.x() + margin, h.x() - margin), uni(-h.y() + margin, h.y() - margin),
                     uni(-h.z() + margin, h.z() - margin)};
          s.point[axis] = sign[axis] * h[axis];
          s.normal = Eigen::Vector3d::Unit(axis) * sign[axis];
        } else if (kind < 4) {  // an edge: one coordinate free
          s.point = sign.cwiseProduct(h);
          s.point[axis] = uni(-h[axis] + margin, h[axis] - margin);
          s.normal = sign;
          s.normal[axis] = 0;
          s.normal.normalize();
          s.feature = "edge";
        } else {  // a corner
          s.point = sign.cwiseProduct(h);
          s.normal = sign.normalized();
          s.feature = "corner";
        }
      }
    }
    sites.push_back(s);
  }
  return sites;
}

nlohmann::json AnalyticShape::describe() const {
  nlohmann::json j;
  j["shape"] = std::string(name());
  j["units"] = "m";
  switch (kind_) {
    case ShapeKind::kPlane:
      j["surface"] = {{"type", "plane"}, {"point", {0, 0, 0}}, {"normal", {0, 0, 1}},
                      {"extent", {{-kPlaneHalf, kPlaneHalf}, {-kPlaneHalf, kPlaneHalf}}}};
      break;
    case ShapeKind::kSphere:
      j["surface"] = {{"type", "sphere"}, {"center", {0, 0, 0}}, {"radius", kSphereR}};
      break;
    case ShapeKind::kCylinder:
      j["surface"] = {{"type", "cylinder"}, {"axis", {0, 0, 1}}, {"radius", kCylR}, {"z", {-kCylHalfLength, kCylHalfLength}},
                      {"caps", false}};
      break;
    case ShapeKind::kCorner90:
      j["surface"] = {{"type", "concave-corner"}, {"faces", {{{"normal", {0, 0, 1}}, {"x", {0, kCornerDepth}}},
                                                             {{"normal", {1, 0, 0}}, {"z", {0, kCornerDepth}}}}},
                      {"y", {-kCornerHalfWidth, kCornerHalfWidth}}, {"opening_deg", 90}};
      break;
    case ShapeKind::kVGroove60:
      j["surface"] = {{"type", "v-groove"}, {"line", "y axis"}, {"bisector", {0, 0, 1}}, {"opening_deg", 60},
                      {"face_length", kGrooveFace}, {"y", {-kGrooveHalfWidth, kGrooveHalfWidth}},
                      {"normals", {{-kC30, 0, kS30}, {kC30, 0, kS30}}}};
      break;
    default: {
      const Eigen::Vector3d h = box_half(kind_);
      j["surface"] = {{"type", "box"}, {"center", {0, 0, 0}}, {"half_extents", {h.x(), h.y(), h.z()}},
                      {"hollow", true}, {"covered_faces", kind_ == ShapeKind::kCube ? "all six" : "z = +-half thickness"}};
    }
  }
  return j;
}

}  // namespace gshaptics
