#include "gshaptics/force/seen_solid.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace gshaptics {

namespace {

constexpr double kMinAlpha = 1.0 / 255.0;  // the 3DGS rasterizer's skip threshold
constexpr double kMaxAlpha = 0.99;         // and its clamp
constexpr double kLn2 = 0.69314718055994530942;
constexpr int kStack = 128;

double form(const double* p, const Eigen::Vector3d& v, const Eigen::Vector3d& w) noexcept {
  return v.x() * (p[0] * w.x() + p[1] * w.y() + p[2] * w.z()) + v.y() * (p[1] * w.x() + p[3] * w.y() + p[4] * w.z()) +
         v.z() * (p[2] * w.x() + p[4] * w.y() + p[5] * w.z());
}

// The segment o + t u, t in [ta, tb], against a node's box (slab test).
bool segment_hits_box(const BvhNode& n, const Eigen::Vector3d& o, const Eigen::Vector3d& inv, double ta,
                      double tb) noexcept {
  for (int k = 0; k < 3; ++k) {
    double t1 = (double(n.lo[k]) - o[k]) * inv[k];
    double t2 = (double(n.hi[k]) - o[k]) * inv[k];
    if (std::isnan(t1) || std::isnan(t2)) {  // parallel to the slab and on its plane
      if (o[k] < n.lo[k] || o[k] > n.hi[k]) return false;
      continue;
    }
    if (t1 > t2) std::swap(t1, t2);
    ta = std::max(ta, t1);
    tb = std::min(tb, t2);
    if (ta > tb) return false;
  }
  return true;
}

}  // namespace

SeenSolid::SeenSolid(const CollisionWorld& world) {
  const double sigma = world.config().sigma;
  std::vector<Entry> entries;
  std::vector<BvhBox> boxes;
  entries.reserve(world.size());
  boxes.reserve(world.size());
  for (const CollisionGaussian& g : world.gaussians()) {
    const double o = std::min<double>(g.opacity, kMaxAlpha);
    if (!(o >= kMinAlpha)) continue;
    const Eigen::Matrix3d r =
        Eigen::Quaterniond(g.quaternion[0], g.quaternion[1], g.quaternion[2], g.quaternion[3]).normalized().toRotationMatrix();
    const Eigen::Vector3d s =
        (Eigen::Vector3d(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]) / sigma).cwiseMax(1e-12);
    const Eigen::Matrix3d cov = r * s.cwiseAbs2().asDiagonal() * r.transpose();
    const Eigen::Matrix3d p = r * s.cwiseAbs2().cwiseInverse().asDiagonal() * r.transpose();
    Entry e;
    for (int k = 0; k < 3; ++k) e.mean[k] = g.center[k];
    e.p[0] = p(0, 0), e.p[1] = p(0, 1), e.p[2] = p(0, 2), e.p[3] = p(1, 1), e.p[4] = p(1, 2), e.p[5] = p(2, 2);
    e.opacity = o;
    // alpha >= 1/255 needs the Mahalanobis radius <= sqrt(2 ln(255 o)): that ellipsoid's box.
    const double reach = std::sqrt(2.0 * std::log(o / kMinAlpha));
    BvhBox b;
    for (int k = 0; k < 3; ++k) {
      const double half = reach * std::sqrt(cov(k, k));
      b.lo[k] = round_down_to_float(e.mean[k] - half);
      b.hi[k] = round_up_to_float(e.mean[k] + half);
    }
    entries.push_back(e);
    boxes.push_back(b);
  }
  if (entries.empty()) return;
  bvh_ = Bvh::build(boxes, 8);
  entries_.resize(entries.size());
  const std::vector<std::uint32_t>& order = bvh_.order();
  for (std::size_t k = 0; k < order.size(); ++k) entries_[k] = entries[order[k]];
  bvh_.release_order();
}

void SeenSolid::gather(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double ta, double tb,
                       SeenScratch& s) const noexcept {
  s.gathered = 0;
  s.overflow = false;
  const std::span<const BvhNode> nodes = bvh_.nodes();
  if (nodes.empty()) return;
  const Eigen::Vector3d inv = u.cwiseInverse();
  std::uint32_t stack[kStack];
  int top = 0;
  std::uint32_t i = 0;
  for (;;) {
    const BvhNode& n = nodes[i];
    if (segment_hits_box(n, o, inv, ta, tb)) {
      if (n.count == 0 && top < kStack) {
        stack[top++] = n.first;
        i = i + 1;
        continue;
      }
      for (std::uint32_t k = n.first; k < n.first + n.count; ++k) {
        const Entry& e = entries_[k];
        const Eigen::Vector3d w(e.mean[0] - o.x(), e.mean[1] - o.y(), e.mean[2] - o.z());
        const double uPu = form(e.p, u, u), uPw = form(e.p, u, w);
        const double t = uPw / uPu;
        if (!(t >= ta && t <= tb)) continue;
        const double alpha = std::min(kMaxAlpha, e.opacity * std::exp(-0.5 * std::max(0.0, form(e.p, w, w) - uPw * t)));
        if (alpha < kMinAlpha) continue;
        if (s.gathered == s.layers.size()) {
          s.overflow = true;
          return;
        }
        s.layers[s.gathered++] = {t, -std::log1p(-alpha)};
      }
    }
    if (top == 0) return;
    i = stack[--top];
  }
}

SeenHit SeenSolid::first_inside(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double t_back, double t0,
                                double t1, SeenScratch& s) const noexcept {
  SeenHit hit;
  t_back = std::min(t_back, t0);
  gather(o, u, t_back, t1, s);
  if (s.overflow) {
    hit.hit = true;
    hit.t = t0;
    return hit;
  }
  std::sort(s.layers.begin(), s.layers.begin() + std::ptrdiff_t(s.gathered),
            [](const SeenScratch::Layer& a, const SeenScratch::Layer& b) { return a.t < b.t; });
  // Composite from t_back in depth order: the optical depth only grows when a layer is passed,
  // so the first depth at which it reaches ln 2 is a layer's peak.
  double tau = 0;
  for (std::size_t k = 0; k < s.gathered; ++k) {
    tau += s.layers[k].tau;
    if (tau >= kLn2) {
      hit.hit = true;
      hit.t = std::max(s.layers[k].t, t0);
      hit.layers = std::uint32_t(k + 1);
      return hit;
    }
  }
  return hit;
}

double SeenSolid::eye_distance(const Eigen::Vector3d& c, const Eigen::Vector3d& u, double max_back,
                               SeenScratch& s) const noexcept {
  double eye = 0;
  (void)push(c, u, 0, max_back, 0, true, eye, s);  // a push of no length: only its eye
  return eye;
}

SeenHit SeenSolid::push(const Eigen::Vector3d& c, const Eigen::Vector3d& u, double lead, double max_back, double len,
                        bool leaving, double& eye, SeenScratch& s) const noexcept {
  SeenHit hit;
  eye = 0;
  gather(c, u, -max_back, lead + len, s);
  if (s.overflow) {
    hit.hit = true;  // blocked where it stands
    return hit;
  }
  const auto first = s.layers.begin(), last = s.layers.begin() + std::ptrdiff_t(s.gathered);
  std::sort(first, last, [](const SeenScratch::Layer& a, const SeenScratch::Layer& b) { return a.t < b.t; });
  // The eye (eye_distance): back from c until a surface hides it.
  std::size_t from = 0;  // the first layer in front of the eye
  double tau = 0;
  eye = max_back;
  for (std::size_t k = s.gathered; k-- > 0;) {
    if (s.layers[k].t > 0) continue;
    tau += s.layers[k].tau;
    if (tau >= kLn2) {
      eye = -s.layers[k].t;
      from = k + 1;
      break;
    }
  }
  // Forward from the eye. A surface crossed behind the leading point holds the tool where it
  // stands, unless the tool is `leaving` it (the shell it rested in, seen from the side it
  // lifts off to).
  tau = 0;
  for (std::size_t k = from; k < s.gathered; ++k) {
    tau += s.layers[k].tau;
    if (tau >= kLn2) {
      if (s.layers[k].t < lead && leaving) return hit;
      hit.hit = true;
      hit.t = std::max(0.0, s.layers[k].t - lead);
      hit.layers = std::uint32_t(k + 1 - from);
      return hit;
    }
  }
  return hit;
}

Eigen::Vector3d SeenSolid::normal(const Eigen::Vector3d& point, const Eigen::Vector3d& u, double h, double reach,
                                  double back, SeenScratch& s) const noexcept {
  const Eigen::Vector3d a = u.unitOrthogonal(), b = u.cross(a);
  const Eigen::Vector3d offsets[4] = {h * a, -h * a, h * b, -h * b};
  Eigen::Vector3d pts[4];
  bool found[4];
  int count = 0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d o = point + offsets[k];
    const SeenHit hk = first_inside(o, u, -back, -reach, reach, s);
    found[k] = hk.hit && !s.overflow;
    if (found[k]) pts[k] = o + hk.t * u, ++count;
  }
  Eigen::Vector3d n = -u;
  if (count == 4) {
    n = (pts[0] - pts[1]).cross(pts[2] - pts[3]);
  } else if (count == 3) {
    // Three points: the plane through them (the missing one's partner with `point`).
    const int miss = !found[0] ? 0 : !found[1] ? 1 : !found[2] ? 2 : 3;
    const Eigen::Vector3d da = miss < 2 ? (miss == 0 ? Eigen::Vector3d(point - pts[1]) : Eigen::Vector3d(pts[0] - point))
                                        : Eigen::Vector3d(pts[0] - pts[1]);
    const Eigen::Vector3d db = miss >= 2 ? (miss == 2 ? Eigen::Vector3d(point - pts[3]) : Eigen::Vector3d(pts[2] - point))
                                         : Eigen::Vector3d(pts[2] - pts[3]);
    n = da.cross(db);
  }
  if (!(n.norm() > 0) || !n.allFinite()) return -u;
  n.normalize();
  return n.dot(u) > 0 ? Eigen::Vector3d(-n) : n;
}

}  // namespace gshaptics
