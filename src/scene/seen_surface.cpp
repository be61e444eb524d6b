#include "gshaptics/scene/seen_surface.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace gshaptics {

namespace {

constexpr double kMinAlpha = 1.0 / 255.0;  // the 3DGS rasterizer's skip threshold
constexpr double kMaxAlpha = 0.99;         // and its clamp
constexpr double kMinScale = 1e-9;

// W v for the whitening W = diag(1/s) R^T stored row-major: the Gaussian's frame in units of
// its scales, where the Mahalanobis distance is the Euclidean one. (Evaluating v^T Sigma^-1 v
// with Sigma^-1 expanded cancels catastrophically for needle-thin Gaussians.)
inline Eigen::Vector3d whiten(const double* m, const Eigen::Vector3d& v) noexcept {
  return {m[0] * v.x() + m[1] * v.y() + m[2] * v.z(), m[3] * v.x() + m[4] * v.y() + m[5] * v.z(),
          m[6] * v.x() + m[7] * v.y() + m[8] * v.z()};
}

}  // namespace

SeenSurface::SeenSurface(const GaussianScene& scene) {
  gaussians_.reserve(scene.size());
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const double o = std::min<double>(scene.opacities[i], kMaxAlpha);
    if (!(o >= kMinAlpha)) continue;
    const Eigen::Vector4f& q = scene.rotations[i];
    Eigen::Quaterniond rot(q[0], q[1], q[2], q[3]);
    if (!(rot.norm() > 0)) rot = Eigen::Quaterniond::Identity();
    const Eigen::Matrix3d r = rot.normalized().toRotationMatrix();
    Eigen::Vector3d s = scene.scales[i].cast<double>().cwiseMax(kMinScale);
    const Eigen::Matrix3d w = s.cwiseInverse().asDiagonal() * r.transpose();
    Entry e;
    e.mean = scene.means[i].cast<double>();
    for (int j = 0; j < 9; ++j) e.m[j] = w(j / 3, j % 3);
    e.opacity = o;
    e.precision = r * s.cwiseAbs2().cwiseInverse().asDiagonal() * r.transpose();
    // alpha = o exp(-r^2/2) >= 1/255 needs r^2 <= 2 ln(255 o); r = |x - mu| / sigma at most.
    e.reach = std::sqrt(2.0 * std::log(o / kMinAlpha)) * s.maxCoeff();
    // (o exp(-r2 / 2) < 1/255 from r2 > 2 ln(255 o); the margin is far above exp's rounding.)
    e.r2_far = 2.0 * std::log(o / kMinAlpha) + 1e-6;
    if (!std::isfinite(e.reach) || !e.mean.allFinite()) continue;
    gaussians_.push_back(e);
  }
  build_bvh();
}

void SeenSurface::build_bvh() {
  if (gaussians_.empty()) return;
  std::vector<BvhBox> boxes(gaussians_.size());
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (std::size_t i = 0; i < gaussians_.size(); ++i) {
    const Entry& g = gaussians_[i];
    for (int k = 0; k < 3; ++k) {
      boxes[i].lo[k] = round_down_to_float(g.mean[k] - g.reach);
      boxes[i].hi[k] = round_up_to_float(g.mean[k] + g.reach);
      lo[k] = std::min<double>(lo[k], boxes[i].lo[k]);
      hi[k] = std::max<double>(hi[k], boxes[i].hi[k]);
    }
  }
  centre_ = 0.5 * (lo + hi);
  radius_ = 0.5 * (hi - lo).norm() * (1 + 1e-9) + 1e-12;
  const Bvh binary = Bvh::build(boxes, 4, BvhSplit::kSah);
  order_ = binary.order();
  bvh_ = WideBvh::collapse(binary);
}

SeenDepth SeenSurface::median_depth(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_max) const {
  const double len = dir.norm();
  if (!(len > 0) || gaussians_.empty()) return {};
  const Eigen::Vector3d u = dir / len;
  // Every box the infinite line meets lies along it within radius_ of centre_'s foot.
  const double foot = (centre_ - origin).dot(u);
  std::vector<std::uint32_t> candidates;
  gather(origin, u, foot - radius_, foot + radius_, candidates);
  return composite_whole(origin, u, t_max, candidates);
}

SeenDepth SeenSurface::first_seen(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_max) const {
  const double len = dir.norm();
  if (!(len > 0) || gaussians_.empty()) return {};
  const Eigen::Vector3d u = dir / len;
  const double foot = (centre_ - origin).dot(u);
  const double last = std::min(t_max, foot + radius_);
  // Chunks (a, b] of the ray, doubling from a 1/256 of the scene's span: a layer belongs to the
  // chunk its peak lies in, and its reach box meets the chunk there (the peak is inside its
  // reach), so the chunks in turn give the layers in median_depth()'s order.
  SeenDepth out;
  double transmittance = 1, a = std::max(0.0, foot - radius_), step = radius_ / 128;
  std::vector<std::uint32_t> candidates;
  std::vector<Layer> layers;
  bool first = true;
  while (!out.hit && a < last) {
    const double b = std::min(last, a + step);
    candidates.clear();
    layers.clear();
    gather(origin, u, a, b, candidates);
    add_layers(origin, u, first ? 0.0 : a, b >= last ? t_max : b, candidates, layers);
    accumulate(u, layers, out, transmittance, true);
    first = false;
    a = b;
    step *= 2;
  }
  return out;
}

void SeenSurface::first_seen_parallel(std::span<const Eigen::Vector3d> origins, const Eigen::Vector3d& dir,
                                      std::span<SeenDepth> out) const {
  if (origins.size() != out.size()) throw std::invalid_argument("first_seen_parallel: origins and out differ in size");
  std::fill(out.begin(), out.end(), SeenDepth{});
  const double len = dir.norm();
  if (!(len > 0) || origins.empty() || gaussians_.empty()) return;
  const Eigen::Vector3d u = dir / len, a = u.unitOrthogonal(), b = u.cross(a);
  // The rays' feet across u, and a grid of about one cell per ray over them.
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(INFINITY), hi = -lo;
  for (const Eigen::Vector3d& o : origins) {
    const Eigen::Vector2d f(o.dot(a), o.dot(b));
    lo = lo.cwiseMin(f);
    hi = hi.cwiseMax(f);
  }
  if (!lo.allFinite() || !hi.allFinite()) return;
  const int side = std::clamp(int(std::sqrt(double(origins.size())) / 2), 1, 128);
  const Eigen::Vector2d cell = ((hi - lo) / side).cwiseMax(1e-12 * (1 + lo.cwiseAbs().maxCoeff()));
  const auto index = [&](double x, double lo_x, double c) { return std::clamp(int(std::floor((x - lo_x) / c)), 0, side - 1); };
  // The Gaussians whose reach disc (padded for rounding) meets the rays' spread, by the least
  // depth a layer of theirs can have along any of the rays (their mean's depth less their reach:
  // the peak lies inside the reach), up to the rays' own offsets along u; then the file's order.
  struct Near {
    double key;
    std::uint32_t i;
    int x0, x1, y0, y1;  // the cells its disc meets
  };
  std::vector<Near> near;
  for (std::size_t i = 0; i < gaussians_.size(); ++i) {
    const Entry& g = gaussians_[i];
    const Eigen::Vector2d f(g.mean.dot(a), g.mean.dot(b));
    const double r = g.reach * (1 + 1e-9) + 1e-12 * (1 + f.cwiseAbs().maxCoeff());
    if (f.x() + r < lo.x() || f.x() - r > hi.x() || f.y() + r < lo.y() || f.y() - r > hi.y()) continue;
    near.push_back({g.mean.dot(u) - g.reach, std::uint32_t(i), index(f.x() - r, lo.x(), cell.x()),
                    index(f.x() + r, lo.x(), cell.x()), index(f.y() - r, lo.y(), cell.y()), index(f.y() + r, lo.y(), cell.y())});
  }
  std::sort(near.begin(), near.end(), [](const Near& x, const Near& y) { return x.key < y.key || (x.key == y.key && x.i < y.i); });
  // Into every cell each meets, in that order: a ray then composites its cell front to back and
  // stops at its surface.
  std::vector<std::uint32_t> start(std::size_t(side * side) + 1, 0), items;
  const auto bin = [&](auto&& put) {
    for (std::size_t n = 0; n < near.size(); ++n)
      for (int y = near[n].y0; y <= near[n].y1; ++y)
        for (int x = near[n].x0; x <= near[n].x1; ++x) put(std::size_t(y * side + x), std::uint32_t(n));
  };
  bin([&](std::size_t c, std::uint32_t) { ++start[c + 1]; });
  for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
  items.resize(start.back());
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  bin([&](std::size_t c, std::uint32_t n) { items[fill[c]++] = n; });
  std::vector<Layer> heap;  // the layers found, least (t, file order) first
  const auto later = [](const Layer& x, const Layer& y) { return x.t > y.t || (x.t == y.t && x.g > y.g); };
  for (std::size_t k = 0; k < origins.size(); ++k) {
    const Eigen::Vector3d& o = origins[k];
    const std::size_t c = std::size_t(index(o.dot(b), lo.y(), cell.y()) * side + index(o.dot(a), lo.x(), cell.x()));
    const std::span<const std::uint32_t> in_cell(items.data() + start[c], start[c + 1] - start[c]);
    const double ou = o.dot(u);
    heap.clear();
    double transmittance = 1;
    SeenDepth& out_k = out[k];
    const auto composite_before = [&](double t_lo) {  // every layer found that no later one can precede
      while (!heap.empty() && !out_k.hit && heap.front().t < t_lo) {
        std::pop_heap(heap.begin(), heap.end(), later);
        accumulate(u, std::span<const Layer>(&heap.back(), 1), out_k, transmittance, true);
        heap.pop_back();
      }
    };
    for (const std::uint32_t n : in_cell) {
      const std::uint32_t i = near[n].i;
      const double t_lo = near[n].key - ou;
      composite_before(t_lo - 1e-9 * (std::abs(near[n].key) + std::abs(ou) + gaussians_[i].reach) - 1e-300);
      if (out_k.hit) break;
      Layer l;
      if (layer_of(i, o, u, 0, 1e300, l)) heap.push_back(l), std::push_heap(heap.begin(), heap.end(), later);
    }
    composite_before(INFINITY);
  }
}

SeenDepth SeenSurface::median_depth_exhaustive(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                               double t_max) const {
  const double len = dir.norm();
  if (!(len > 0)) return {};
  std::vector<std::uint32_t> all(gaussians_.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = std::uint32_t(i);
  return composite_whole(origin, dir / len, t_max, all);
}

SeenDepth SeenSurface::composite_whole(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double t_max,
                                       std::span<const std::uint32_t> candidates) const {
  SeenDepth out;
  std::vector<Layer> layers;
  add_layers(origin, u, 0, t_max, candidates, layers);
  double transmittance = 1;
  accumulate(u, layers, out, transmittance, false);
  return out;
}

void SeenSurface::gather(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double ta, double tb,
                         std::vector<std::uint32_t>& candidates) const {
  bvh_.for_each_leaf_on_segment(origin, u, ta, tb, [&](std::uint32_t first, std::uint32_t count) {
    for (std::uint32_t k = first; k < first + count; ++k) {
      const Entry& g = gaussians_[order_[k]];
      const Eigen::Vector3d w = g.mean - origin;
      // (add_layers()' own first test, so only what it keeps is sorted.)
      if ((w - w.dot(u) * u).squaredNorm() <= g.reach * g.reach) candidates.push_back(order_[k]);
    }
  });
  std::sort(candidates.begin(), candidates.end());
}

bool SeenSurface::layer_of(std::uint32_t i, const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double after,
                           double upto, Layer& layer) const {
  const Entry& g = gaussians_[i];
  const Eigen::Vector3d w = g.mean - origin;
  const double along = w.dot(u);
  if ((w - along * u).squaredNorm() > g.reach * g.reach) return false;  // the ray misses its reach
  const Eigen::Vector3d wu = whiten(g.m, u), ww = whiten(g.m, w);
  const double t = wu.dot(ww) / wu.squaredNorm();
  if (!(t > after) || t > upto) return false;
  // The ray's squared Mahalanobis distance from the mean, at its peak.
  const double r2 = (ww - t * wu).squaredNorm();
  if (r2 > g.r2_far) return false;
  const double alpha = std::min(kMaxAlpha, g.opacity * std::exp(-0.5 * r2));
  if (alpha < kMinAlpha) return false;
  layer = {t, alpha, &g};
  return true;
}

void SeenSurface::add_layers(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double after, double upto,
                             std::span<const std::uint32_t> candidates, std::vector<Layer>& layers) const {
  Layer l;
  for (const std::uint32_t i : candidates)
    if (layer_of(i, origin, u, after, upto, l)) layers.push_back(l);
  std::stable_sort(layers.begin(), layers.end(), [](const Layer& a, const Layer& b) { return a.t < b.t; });
}

void SeenSurface::accumulate(const Eigen::Vector3d& u, std::span<const Layer> layers, SeenDepth& out,
                             double& transmittance, bool stop) const {
  const double half = std::log(2.0);
  for (const Layer& l : layers) {
    out.optical_depth -= std::log1p(-l.alpha);
    ++out.composited;
    if (out.hit) continue;
    const Eigen::Vector3d pu = l.g->precision * u;
    out.shade -= transmittance * l.alpha * pu.normalized();
    transmittance *= 1 - l.alpha;
    if (out.optical_depth >= half) {
      out.hit = true;
      out.depth = l.t;
      if (stop) return;
    }
  }
}

std::optional<SeenPoint> SeenSurface::surface_point(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                                    double h, double t_max) const {
  const double len = dir.norm();
  if (!(len > 0) || !(h > 0)) return std::nullopt;
  const Eigen::Vector3d u = dir / len;
  const SeenDepth centre = first_seen(origin, u, t_max);
  if (!centre.hit) return std::nullopt;
  const Eigen::Vector3d a = u.unitOrthogonal();
  const Eigen::Vector3d b = u.cross(a);
  Eigen::Vector3d pts[4];
  const Eigen::Vector3d offsets[4] = {h * a, -h * a, h * b, -h * b};
  for (int k = 0; k < 4; ++k) {
    const SeenDepth d = first_seen(origin + offsets[k], u, t_max);
    if (!d.hit) return std::nullopt;
    pts[k] = origin + offsets[k] + d.depth * u;
  }
  Eigen::Vector3d n = (pts[0] - pts[1]).cross(pts[2] - pts[3]);
  if (!(n.norm() > 0)) return std::nullopt;
  n.normalize();
  if (n.dot(u) > 0) n = -n;
  SeenPoint sp;
  sp.depth = centre.depth;
  sp.point = origin + centre.depth * u;
  sp.normal = n;
  return sp;
}

}  // namespace gshaptics
