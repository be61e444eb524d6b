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

// A bundle of parallel rays along u: its frame across u, a grid of about one cell per ray over
// the rays' feet, and the Gaussians near the bundle binned into the cells their reach meets.
struct SeenSurface::Bundle {
  struct Near {
    double key;          // the least depth a layer of theirs can have along u (mean's depth less reach)
    std::uint32_t i;     // index into gaussians_
    int x0, x1, y0, y1;  // the cells its disc meets
  };
  Eigen::Vector3d u, a, b;
  Eigen::Vector2d lo, cell;
  int side = 1;
  std::vector<Near> near;                   // by key, then file order
  std::vector<std::uint32_t> start, items;  // cell c holds items[start[c], start[c + 1]), indices into near

  [[nodiscard]] int index(double x, double lo_x, double c) const noexcept {
    return std::clamp(int(std::floor((x - lo_x) / c)), 0, side - 1);
  }
  [[nodiscard]] std::size_t cell_of(const Eigen::Vector3d& o) const noexcept {
    return std::size_t(index(o.dot(b), lo.y(), cell.y()) * side + index(o.dot(a), lo.x(), cell.x()));
  }
};

bool SeenSurface::frame_bundle(std::span<const Eigen::Vector3d> origins, const Eigen::Vector3d& u,
                               Bundle& bundle) const {
  bundle.u = u;
  bundle.a = u.unitOrthogonal();
  bundle.b = u.cross(bundle.a);
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(INFINITY), hi = -lo;
  for (const Eigen::Vector3d& o : origins) {
    const Eigen::Vector2d f(o.dot(bundle.a), o.dot(bundle.b));
    lo = lo.cwiseMin(f);
    hi = hi.cwiseMax(f);
  }
  if (!lo.allFinite() || !hi.allFinite()) return false;
  bundle.side = std::clamp(int(std::sqrt(double(origins.size())) / 2), 1, 128);
  bundle.lo = lo;
  bundle.cell = ((hi - lo) / bundle.side).cwiseMax(1e-12 * (1 + lo.cwiseAbs().maxCoeff()));
  // The Gaussians whose reach disc (padded for rounding) meets the rays' spread, by the least
  // depth a layer of theirs can have along any of the rays (their mean's depth less their reach:
  // the peak lies inside the reach), up to the rays' own offsets along u; then the file's order.
  for (std::size_t i = 0; i < gaussians_.size(); ++i) {
    const Entry& g = gaussians_[i];
    const Eigen::Vector2d f(g.mean.dot(bundle.a), g.mean.dot(bundle.b));
    const double r = g.reach * (1 + 1e-9) + 1e-12 * (1 + f.cwiseAbs().maxCoeff());
    if (f.x() + r < lo.x() || f.x() - r > hi.x() || f.y() + r < lo.y() || f.y() - r > hi.y()) continue;
    const double c = bundle.cell.x(), d = bundle.cell.y();
    bundle.near.push_back({g.mean.dot(u) - g.reach, std::uint32_t(i), bundle.index(f.x() - r, lo.x(), c),
                           bundle.index(f.x() + r, lo.x(), c), bundle.index(f.y() - r, lo.y(), d),
                           bundle.index(f.y() + r, lo.y(), d)});
  }
  std::sort(bundle.near.begin(), bundle.near.end(), [](const Bundle::Near& x, const Bundle::Near& y) {
    return x.key < y.key || (x.key == y.key && x.i < y.i);
  });
  return true;
}

void SeenSurface::bin_bundle(Bundle& bundle) {
  // Into every cell each meets, in the near list's order (a counting sort: sizes, then places).
  const std::size_t cells = std::size_t(bundle.side * bundle.side);
  const auto bin = [&](auto&& put) {
    for (std::size_t n = 0; n < bundle.near.size(); ++n) {
      const Bundle::Near& g = bundle.near[n];
      for (int y = g.y0; y <= g.y1; ++y)
        for (int x = g.x0; x <= g.x1; ++x) put(std::size_t(y * bundle.side + x), std::uint32_t(n));
    }
  };
  bundle.start.assign(cells + 1, 0);
  bin([&](std::size_t c, std::uint32_t) { ++bundle.start[c + 1]; });
  for (std::size_t c = 1; c < bundle.start.size(); ++c) bundle.start[c] += bundle.start[c - 1];
  bundle.items.resize(bundle.start.back());
  std::vector<std::uint32_t> fill(bundle.start.begin(), bundle.start.end() - 1);
  bin([&](std::size_t c, std::uint32_t n) { bundle.items[fill[c]++] = n; });
}

SeenDepth SeenSurface::first_seen_in_bundle(const Bundle& bundle, const Eigen::Vector3d& o,
                                            std::vector<Layer>& heap) const {
  // The ray's cell front to back: a layer found is composited once no Gaussian still to come can
  // precede it (their keys are lower bounds), and the ray stops at its surface.
  const std::size_t c = bundle.cell_of(o);
  const std::span<const std::uint32_t> in_cell(bundle.items.data() + bundle.start[c],
                                               bundle.start[c + 1] - bundle.start[c]);
  const Eigen::Vector3d& u = bundle.u;
  const double ou = o.dot(u);
  const auto later = [](const Layer& x, const Layer& y) { return x.t > y.t || (x.t == y.t && x.g > y.g); };
  SeenDepth out;
  double transmittance = 1;
  heap.clear();
  const auto composite_before = [&](double t_lo) {
    while (!heap.empty() && !out.hit && heap.front().t < t_lo) {
      std::pop_heap(heap.begin(), heap.end(), later);
      accumulate(u, std::span<const Layer>(&heap.back(), 1), out, transmittance, true);
      heap.pop_back();
    }
  };
  for (const std::uint32_t n : in_cell) {
    const Bundle::Near& g = bundle.near[n];
    const double t_lo = g.key - ou;
    composite_before(t_lo - 1e-9 * (std::abs(g.key) + std::abs(ou) + gaussians_[g.i].reach) - 1e-300);
    if (out.hit) break;
    Layer l;
    if (layer_of(g.i, o, u, 0, 1e300, l)) heap.push_back(l), std::push_heap(heap.begin(), heap.end(), later);
  }
  composite_before(INFINITY);
  return out;
}

void SeenSurface::first_seen_parallel(std::span<const Eigen::Vector3d> origins, const Eigen::Vector3d& dir,
                                      std::span<SeenDepth> out) const {
  if (origins.size() != out.size()) throw std::invalid_argument("first_seen_parallel: origins and out differ in size");
  std::fill(out.begin(), out.end(), SeenDepth{});
  const double len = dir.norm();
  if (!(len > 0) || origins.empty() || gaussians_.empty()) return;
  Bundle bundle;
  if (!frame_bundle(origins, dir / len, bundle)) return;
  bin_bundle(bundle);
  std::vector<Layer> heap;  // the layers found, least (t, file order) first
  for (std::size_t k = 0; k < origins.size(); ++k) out[k] = first_seen_in_bundle(bundle, origins[k], heap);
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
  double around = 0;  // the neighbours' mean depth
  for (int k = 0; k < 4; ++k) {
    const SeenDepth d = first_seen(origin + offsets[k], u, t_max);
    if (!d.hit) return std::nullopt;
    pts[k] = origin + offsets[k] + d.depth * u;
    around += 0.25 * d.depth;
  }
  Eigen::Vector3d n = (pts[0] - pts[1]).cross(pts[2] - pts[3]);
  if (!(n.norm() > 0)) return std::nullopt;
  n.normalize();
  if (n.dot(u) > 0) n = -n;
  SeenPoint sp;
  sp.depth = centre.depth;
  sp.point = origin + centre.depth * u;
  sp.normal = n;
  sp.kink = centre.depth - around;
  return sp;
}

}  // namespace gshaptics
