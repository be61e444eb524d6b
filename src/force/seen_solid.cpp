#include "gshaptics/force/seen_solid.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <numbers>
#include <optional>
#include <array>
#include <cmath>
#include <limits>

#include "gshaptics/percentile.h"

namespace gshaptics {

namespace {

constexpr double kMinAlpha = 1.0 / 255.0;  // the 3DGS rasterizer's skip threshold
constexpr double kMaxAlpha = 0.99;         // and its clamp
constexpr double kLn2 = 0.69314718055994530942;

// W v for the whitening W = diag(1/s) R^T stored row-major: the Gaussian's frame in units of
// its scales, where the Mahalanobis distance is the Euclidean one. (Evaluating v^T Sigma^-1 v
// with Sigma^-1 expanded cancels catastrophically for needle-thin Gaussians.)
inline Eigen::Vector3d whiten(const double* m, const Eigen::Vector3d& v) noexcept {
  return {m[0] * v.x() + m[1] * v.y() + m[2] * v.z(), m[3] * v.x() + m[4] * v.y() + m[5] * v.z(),
          m[6] * v.x() + m[7] * v.y() + m[8] * v.z()};
}

}  // namespace

SeenSolid::Bound SeenSolid::bound_of(const Entry& e, double radius) noexcept {
  // The float centre is off by half a float ulp a coordinate; the padding covers that and the
  // rounding of the test in gather().
  const double pad = 1e-6 * (std::max({std::abs(e.mean[0]), std::abs(e.mean[1]), std::abs(e.mean[2])}) + radius);
  Bound b;
  for (int k = 0; k < 3; ++k) b.center[k] = static_cast<float>(e.mean[k]);
  b.radius = round_up_to_float(radius + pad);
  return b;
}

SeenSolid::SeenSolid(const CollisionWorld& world) : world_(&world) {
  const double sigma = world.config().sigma;
  std::vector<BvhBox> boxes;
  std::vector<double> middle_scales;
  middle_scales.reserve(world.size());
  entries_.reserve(world.size());
  bounds_.reserve(world.size());
  slots_.reserve(world.size());
  boxes.reserve(world.size());
  for (std::size_t slot = 0; slot < world.gaussians().size(); ++slot) {
    const CollisionGaussian& g = world.gaussians()[slot];
    const double o = std::min<double>(g.opacity, kMaxAlpha);
    if (!(o >= kMinAlpha)) continue;
    const Eigen::Matrix3d r =
        Eigen::Quaterniond(g.quaternion[0], g.quaternion[1], g.quaternion[2], g.quaternion[3]).normalized().toRotationMatrix();
    const Eigen::Vector3d s =
        (Eigen::Vector3d(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]) / sigma).cwiseMax(1e-12);
    const Eigen::Matrix3d cov = r * s.cwiseAbs2().asDiagonal() * r.transpose();
    const Eigen::Matrix3d wm = s.cwiseInverse().asDiagonal() * r.transpose();
    Entry e;
    for (int k = 0; k < 3; ++k) e.mean[k] = g.center[k];
    for (int j = 0; j < 9; ++j) e.m[j] = wm(j / 3, j % 3);
    e.opacity = o;
    e.log_reach = std::log(o / kMinAlpha);
    // alpha >= 1/255 needs the Mahalanobis radius <= sqrt(2 ln(255 o)): that ellipsoid's box.
    const double reach = std::sqrt(2.0 * e.log_reach);
    BvhBox b;
    for (int k = 0; k < 3; ++k) {
      const double half = reach * std::sqrt(cov(k, k));
      b.lo[k] = round_down_to_float(e.mean[k] - half);
      b.hi[k] = round_up_to_float(e.mean[k] + half);
    }
    entries_.push_back(e);
    boxes.push_back(b);
    bounds_.push_back(bound_of(e, reach * s.maxCoeff()));
    slots_.push_back(std::uint32_t(slot));
    middle_scales.push_back(s.sum() - s.maxCoeff() - s.minCoeff());
  }
  if (entries_.empty()) return;
  typical_scale_ = percentile(std::move(middle_scales), 50);
  Bvh binary = Bvh::build(boxes, 2, BvhSplit::kSah);
  std::vector<BvhBox>().swap(boxes);
  permute_to_order(std::span<std::uint32_t>(binary.mutable_order()), std::span<Entry>(entries_),
                   std::span<Bound>(bounds_), std::span<std::uint32_t>(slots_));
  binary.release_order();
  bvh_ = WideBvh::collapse(binary);
}

void SeenSolid::sort_by_depth(std::vector<SeenScratch::Layer>::iterator first,
                              std::vector<SeenScratch::Layer>::iterator last) const noexcept {
  // Layers at the same depth in the Gaussians' own order (their slots in the world), so the
  // compositing, to the last bit, does not depend on the order the tree reported them in.
  std::sort(first, last, [this](const SeenScratch::Layer& a, const SeenScratch::Layer& b) {
    return a.t < b.t || (a.t == b.t && slots_[a.entry] < slots_[b.entry]);
  });
}

void SeenSolid::gather(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double ta, double tb,
                       SeenScratch& s, bool append) const noexcept {
  if (!append) s.gathered = 0;
  s.overflow = false;
  ++s.work.walks;
  const double len2 = u.squaredNorm(), inv_len2 = 1 / len2, inv_len = std::sqrt(inv_len2);
  bvh_.for_each_leaf_on_segment(o, u, ta, tb, [&](std::uint32_t first, std::uint32_t count) {
    s.work.entries += count;
    for (std::uint32_t k = first; k < first + count; ++k) {
      // The entry's ball first: a peak with alpha >= 1/255 lies in it, so a line passing
      // beside it, or meeting it outside [ta, tb], has no layer here.
      const Bound& ball = bounds_[k];
      const double bx = ball.center[0] - o.x(), by = ball.center[1] - o.y(), bz = ball.center[2] - o.z();
      const double along = (bx * u.x() + by * u.y() + bz * u.z()) * inv_len2;
      const double r = ball.radius * inv_len;
      if (along + r < ta || along - r > tb) continue;
      const double w2 = bx * bx + by * by + bz * bz;
      if (w2 - along * along * len2 > double(ball.radius) * ball.radius + 1e-9 * w2) continue;
      const Entry& e = entries_[k];
      const Eigen::Vector3d w(e.mean[0] - o.x(), e.mean[1] - o.y(), e.mean[2] - o.z());
      const Eigen::Vector3d wu = whiten(e.m, u), ww = whiten(e.m, w);
      const double t = wu.dot(ww) / wu.squaredNorm();
      if (!(t >= ta && t <= tb)) continue;
      // Half the squared Mahalanobis distance of the ray from the mean (at the peak); past
      // log_reach the alpha is below 1/255 and the layer is skipped without an exp.
      const double half_d2 = 0.5 * (ww - t * wu).squaredNorm();
      if (half_d2 > e.log_reach) continue;
      const double alpha = std::min(kMaxAlpha, e.opacity * std::exp(-half_d2));
      if (alpha < kMinAlpha) continue;
      if (s.gathered == s.layers.size()) {
        s.overflow = true;
        return false;
      }
      s.layers[s.gathered++] = {t, -std::log1p(-alpha), k};
      ++s.work.layers;
    }
    return true;
  });
}

void SeenSolid::gather_more(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double ta, double tb, double shared,
                            SeenScratch& s) const noexcept {
  const std::size_t before = s.gathered;
  gather(o, u, ta, tb, s, /*append=*/true);
  // A layer peaking exactly at the shared end was gathered by the earlier range already.
  std::size_t end = before;
  for (std::size_t k = before; k < s.gathered; ++k)
    if (s.layers[k].t != shared) s.layers[end++] = s.layers[k];
  s.gathered = end;
}

SeenHit SeenSolid::first_inside(const Eigen::Vector3d& o, const Eigen::Vector3d& u, double t_back, double t0,
                                double t1, SeenScratch& s, double t_guess) const noexcept {
  SeenHit hit;
  t_back = std::min(t_back, t0);
  // In two stages when a guess is given: the layers up to the guess first, then, only when they
  // do not reach ln 2, the rest. The first crossing depends only on the layers before it, and
  // every layer of the second stage lies deeper than every one of the first, so the answer is
  // the one-stage answer.
  const double split = std::isfinite(t_guess) ? std::clamp(t_guess, t_back, t1) : t1;
  double tau = 0;
  std::size_t done = 0;  // layers composited so far
  for (int stage = 0; stage < 2; ++stage) {
    const double ta = stage == 0 ? t_back : split, tb = stage == 0 ? split : t1;
    if (stage == 1 && !(tb > ta)) break;
    if (stage == 0)
      gather(o, u, ta, tb, s);
    else
      gather_more(o, u, ta, tb, split, s);
    if (s.overflow) {
      hit.hit = true;
      hit.t = t0;
      return hit;
    }
    const std::size_t end = s.gathered;
    sort_by_depth(s.layers.begin() + std::ptrdiff_t(done), s.layers.begin() + std::ptrdiff_t(end));
    // Composite from t_back in depth order: the optical depth only grows when a layer is passed,
    // so the first depth at which it reaches ln 2 is a layer's peak.
    for (std::size_t k = done; k < end; ++k) {
      tau += s.layers[k].tau;
      if (tau >= kLn2) {
        hit.hit = true;
        hit.t = std::max(s.layers[k].t, t0);
        hit.layers = std::uint32_t(k + 1);
        return hit;
      }
    }
    done = end;
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
                        bool leaving, double& eye, SeenScratch& s, double t_guess) const noexcept {
  SeenHit hit;
  const double eye_guess = eye;
  eye = 0;
  // Both looks read in stages, and each stage's layers all lie beyond every earlier stage's, so
  // the answer is the one-stage answer (first_inside's argument): ahead of c, up to the guess
  // first and the rest only when those do not reach ln 2; behind c, ranges growing x4 from
  // kFirstStage of max_back (from the second on, from the eye guess) until a surface hides c (a
  // surface near behind spares the long look).
  const double end = lead + len;
  const double split = std::isfinite(t_guess) ? std::clamp(lead + t_guess, 0.0, end) : end;
  double near = split;  // how far ahead the layers are read
  int stage = 0;        // the next range past the guess
  std::optional<std::size_t> around;
  BackLook back{max_back};
  if (eye_guess > 0 && eye_guess < max_back) back.guess = kEyeGuessMargin * eye_guess;
  const std::size_t ahead =
      end > 0 ? read_ahead(c, u, back, split, end, std::isfinite(t_guess), near, stage, around, s) : 0;
  // The layers between the eye and c composite to less than ln 2 (that is where the eye is), so
  // a surface needs a layer peaking ahead of c: with none there, the eye is not searched (a free
  // tool away from the surfaces).
  if (end > 0 && !s.overflow && ahead == 0) return hit;
  if (!(end > 0)) s.gathered = 0;
  std::array<Span, kStages> behind;
  const int stages = look_back(c, u, back, end > 0, around, behind, eye, s);
  if (s.overflow) {
    eye = 0;
    hit.hit = true;  // blocked where it stands
    return hit;
  }
  // Forward from the eye: the stages behind c from the farthest read, then the layers ahead. A
  // surface crossed behind the leading point holds the tool where it stands, unless the tool is
  // `leaving` it (the shell it rested in, seen from the side it lifts off to).
  double tau = 0;
  std::uint32_t passed = 0;
  const auto composite = [&](std::size_t first, std::size_t last) {
    for (std::size_t k = first; k < last; ++k) {
      tau += s.layers[k].tau;
      ++passed;
      if (tau >= kLn2) {
        hit.hit = !(s.layers[k].t < lead && leaving);
        hit.t = hit.hit ? std::max(0.0, s.layers[k].t - lead) : 0.0;
        hit.layers = hit.hit ? passed : 0;
        return true;
      }
    }
    return false;
  };
  for (int st = stages; st-- > 0;)
    if (composite(behind[std::size_t(st)].first, behind[std::size_t(st)].last)) return hit;
  if (composite(0, ahead)) return hit;
  // The rest of the ranges past the guess.
  for (; near < end; ++stage) {
    const double next = stage_end(split, end, stage + 1);
    const std::size_t more = s.gathered;
    gather_more(c, u, near, next, near, s);
    if (s.overflow) {
      eye = 0;
      hit.hit = true;
      return hit;
    }
    sort_by_depth(s.layers.begin() + std::ptrdiff_t(more), s.layers.begin() + std::ptrdiff_t(s.gathered));
    if (composite(more, s.gathered)) return hit;
    near = next;
  }
  return hit;
}

std::size_t SeenSolid::read_ahead(const Eigen::Vector3d& c, const Eigen::Vector3d& u, const BackLook& back,
                                  double split, double end, bool guessed, double& near, int& stage,
                                  std::optional<std::size_t>& around, SeenScratch& s) const noexcept {
  // With a guess (a resting tool's lines, which meet a surface near it), one traversal reads the
  // layers around c: the first range ahead and the look back's first stage,
  // [-back.first, 0) (the look back takes them when it is searched). Without one (a
  // free tool, usually far from every surface), the first range ahead alone.
  around.reset();
  gather(c, u, guessed ? -back.end(0) : 0.0, split, s);
  if (guessed && s.overflow) {
    gather(c, u, 0.0, split, s);  // (read apart after all)
  } else if (guessed) {
    const auto first = s.layers.begin();
    const auto behind = std::partition(first, first + std::ptrdiff_t(s.gathered),
                                       [](const SeenScratch::Layer& l) { return l.t >= 0; });
    around = s.gathered - std::size_t(behind - first);
  }
  // The ranges past the guess until one holds a layer.
  const std::size_t read_around = around.value_or(0);
  const bool first_empty = s.gathered == read_around;  // no layer ahead in the first read
  for (; !s.overflow && s.gathered == read_around && near < end; ++stage) {
    const double next = stage_end(split, end, stage + 1);
    gather_more(c, u, near, next, near, s);
    near = next;
  }
  const std::size_t ahead = s.gathered - read_around;
  // (Layers those ranges found come after the first stage behind: before it now.)
  if (read_around > 0 && ahead > 0 && first_empty)
    std::rotate(s.layers.begin(), s.layers.begin() + std::ptrdiff_t(read_around),
                s.layers.begin() + std::ptrdiff_t(s.gathered));
  sort_by_depth(s.layers.begin(), s.layers.begin() + std::ptrdiff_t(ahead));
  return ahead;
}

int SeenSolid::look_back(const Eigen::Vector3d& c, const Eigen::Vector3d& u, const BackLook& back, bool shared_zero,
                         std::optional<std::size_t> around, std::array<Span, kStages>& behind, double& eye,
                         SeenScratch& s) const noexcept {
  // Back from c until a surface hides it: the layers of each stage after those gathered, sorted,
  // and composited from c backwards. (A layer peaking on a stage's near end belongs to the
  // stage before, nearer c: gather_more leaves it out; one at c itself to the look ahead, when
  // there is one.)
  double tau = 0;
  double near = 0;
  eye = back.max_back;
  int stages = 0;
  for (int st = 0; st < kStages; ++st) {
    const double far = back.end(st);
    if (st > 0 && !(far > near)) break;
    std::size_t first = s.gathered;
    if (st == 0 && around)
      first -= *around;  // read already (push())
    else if (st > 0 || shared_zero)
      gather_more(c, u, -far, -near, -near, s);
    else
      gather(c, u, -far, 0.0, s, /*append=*/true);
    if (s.overflow) return stages;
    sort_by_depth(s.layers.begin() + std::ptrdiff_t(first), s.layers.begin() + std::ptrdiff_t(s.gathered));
    behind[std::size_t(stages++)] = {first, s.gathered};
    for (std::size_t k = s.gathered; k-- > first;) {
      tau += s.layers[k].tau;
      if (tau >= kLn2) {
        eye = -s.layers[k].t;
        behind[std::size_t(stages - 1)].first = k + 1;  // the layers in front of the eye
        return stages;
      }
    }
    near = far;
  }
  return stages;
}

SeenHit SeenSolid::normal_ray(const Eigen::Vector3d& point, const Eigen::Vector3d& u, int k, double h, double reach,
                              double back, SeenScratch& s, double phase) const noexcept {
  // (Never seen from behind the eye: a nearer eye than the search's start would let a surface
  // that hides `point` from that eye, a groove's other face, make the reading.)
  const double from = -std::min(reach, back);
  SeenHit hit = first_inside(normal_ray_origin(point, u, k, h, phase), u, -back, from, reach, s);
  hit.hit = hit.hit && !s.overflow;
  // (Its shade from the layers in its window only: those in front lie between the contact's eye
  // and the surface there, a face that hides the ray's point or a floater, and their normals are
  // not the surface's under the tool; a ray hidden from the eye altogether reads no shade.)
  if (hit.hit) hit.shade = shade(u, hit, s, from);
  return hit;
}

Eigen::Vector3d SeenSolid::wall_normal(const Eigen::Vector3d& u, const Eigen::Vector3d& axis, const SeenHit& hit,
                                       const SeenScratch& scratch) const noexcept {
  Eigen::Vector3d n = shade(u, hit, scratch);
  if (!(n.dot(u) < 0)) n = -u;
  n -= n.dot(axis) * axis;
  const double len = n.norm();
  if (len > 1e-3) return n / len;
  n = -u + u.dot(axis) * axis;
  return n.normalized();
}

Eigen::Vector3d SeenSolid::shade(const Eigen::Vector3d& u, const SeenHit& hit, const SeenScratch& s,
                                 double t_from) const noexcept {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  if (!hit.hit || s.overflow) return sum;
  double transmittance = 1;
  const std::size_t end = std::min<std::size_t>(hit.layers, s.gathered);
  for (std::size_t k = 0; k < end; ++k) {
    const SeenScratch::Layer& l = s.layers[k];
    const double* m = entries_[l.entry].m;
    // Sigma^-1 u = W^T (W u): the normal of the Gaussian's depth plane along u.
    const Eigen::Vector3d wu = whiten(m, u);
    const Eigen::Vector3d p(m[0] * wu.x() + m[3] * wu.y() + m[6] * wu.z(), m[1] * wu.x() + m[4] * wu.y() + m[7] * wu.z(),
                            m[2] * wu.x() + m[5] * wu.y() + m[8] * wu.z());
    const double norm = p.norm();
    const double alpha = -std::expm1(-l.tau);
    if (norm > 0 && std::isfinite(norm) && !(l.t < t_from)) sum -= (transmittance * alpha / norm) * p;
    transmittance *= 1 - alpha;
  }
  return sum;
}

Eigen::Vector3d SeenSolid::ring_direction(const Eigen::Vector3d& u, int k, double phase) noexcept {
  const Eigen::Vector3d a = u.unitOrthogonal(), b = u.cross(a);
  const double angle = 2 * std::numbers::pi * k / kNormalRays + phase;
  return std::cos(angle) * a + std::sin(angle) * b;
}

Eigen::Vector3d SeenSolid::normal_ray_origin(const Eigen::Vector3d& point, const Eigen::Vector3d& u, int k,
                                             double h, double phase) noexcept {
  return point + h * ring_direction(u, k, phase);
}

double SeenSolid::shade_slope(const Eigen::Vector3d& n, const Eigen::Vector3d& u, const Eigen::Vector3d& e) noexcept {
  // The surface the shade n faces out of: t grows into it along u, so its slope dt/dx along e
  // is n.e / (-n.u); edge-on or facing away, no finite slope.
  const double facing = -n.dot(u);
  if (!(facing > 1e-6 * n.norm())) return std::numeric_limits<double>::infinity();
  return n.dot(e) / facing;
}

std::array<Eigen::Vector3d, SeenSolid::kNormalRays / 2> SeenSolid::ring_axes(const Eigen::Vector3d& u,
                                                                             double phase) noexcept {
  std::array<Eigen::Vector3d, kNormalRays / 2> axes;
  for (int k = 0; k < kNormalRays / 2; ++k) axes[std::size_t(k)] = ring_direction(u, k, phase);
  return axes;
}

std::array<bool, SeenSolid::kNormalRays> SeenSolid::past_crease(const Eigen::Vector3d& u,
                                                                  const std::array<SeenHit, kNormalRays>& hits,
                                                                  double h) noexcept {
  return past_crease(u, ring_axes(u), hits, h);
}

std::array<bool, SeenSolid::kNormalRays> SeenSolid::past_crease(const Eigen::Vector3d& u, const RingAxes& axes,
                                                                  const std::array<SeenHit, kNormalRays>& hits,
                                                                  double h) noexcept {
  std::array<bool, kNormalRays> past{};
  if (!(h > 0)) return past;
  // Per axis (rays k and k + kNormalRays / 2 at +-h along ring_direction(k); t grows into the
  // surface) two measures, one a ray each, that a smooth surface makes alike on both sides and a
  // crease within h (a groove's other face, the far side of an edge) does not:
  // - the depth's one-sided slope from the point (t = 0) to the ray, outward: on a smooth surface
  //   the mean slope plus the curvature times h / 2 (their sum is about the curvature times h, a
  //   tilt cancels); a crease makes one steep and leaves the other flat;
  // - the ray's shade slope outward less that depth slope: about 0 for a tilt and the curvature
  //   times h / 2 for a curvature, on both sides; a ray that reads a face its chord does not run
  //   along (a groove's other face where it stands over the point's face, a few mm shallower,
  //   60 deg off in shade) unlike the other side.
  // Where they differ by more than kCreaseSlope (depths) or kCreaseShade (shades), the ray whose
  // measure is over twice the other's is past the crease. A crease at the point itself (both
  // alike) leaves both.
  for (int axis = 0; axis < kNormalRays / 2; ++axis) {
    const std::size_t ahead = std::size_t(axis), behind = std::size_t(axis + kNormalRays / 2);
    if (!hits[ahead].hit || !hits[behind].hit) continue;
    const auto far_side = [&](double up, double down) {
      if (up > 2 * down) past[ahead] = true;
      else if (down > 2 * up) past[behind] = true;
    };
    const double up = hits[ahead].t / h, down = hits[behind].t / h;
    if (std::fabs(up + down) > kCreaseSlope) {  // g+ - g- = (t+ + t-) / h
      far_side(std::fabs(up), std::fabs(down));
      continue;
    }
    const Eigen::Vector3d& e = axes[std::size_t(axis)];
    const double off_up = shade_slope(hits[ahead].shade, u, e) - up;
    const double off_down = shade_slope(hits[behind].shade, u, -e) - down;
    if (std::fabs(off_up - off_down) > kCreaseShade) far_side(std::fabs(off_up), std::fabs(off_down));
  }
  return past;
}

Eigen::Vector3d SeenSolid::normal_from(const Eigen::Vector3d& u, const std::array<SeenHit, kNormalRays>& hits,
                                       double h, double phase) noexcept {
  const RingAxes axes = ring_axes(u, phase);
  return on_crest(u, axes, hits, h, shaded_normal(u, axes, hits, h));
}

bool SeenSolid::creased(const Eigen::Vector3d& u, const std::array<SeenHit, kNormalRays>& hits, double h,
                        double phase) noexcept {
  for (const SeenHit& x : hits)
    if (!x.hit) return true;
  const RingAxes axes = ring_axes(u, phase);
  const std::array<bool, kNormalRays> past = past_crease(u, axes, hits, h);
  for (const bool p : past)
    if (p) return true;
  for (int axis = 0; axis < kNormalRays / 2; ++axis)
    if (crest_weight(hits[std::size_t(axis)].t / h, hits[std::size_t(axis + kNormalRays / 2)].t / h) > 0) return true;
  return false;
}

Eigen::Vector3d SeenSolid::on_crest(const Eigen::Vector3d& u, const RingAxes& axes,
                                    const std::array<SeenHit, kNormalRays>& hits, double h,
                                    const Eigen::Vector3d& n) noexcept {
  const double facing = -n.dot(u);
  if (!(h > 0) || !(facing > 1e-6)) return n;
  // The plane t = g . x through the point (t grows into the surface along u) has the normal
  // -u + g. A rigid sphere held at the point touches the surface where its plane is over every
  // ray's depth, t_k >= g . (h e_k): along an axis, g . e in [-down, up] (one-sided slopes); on
  // a convex crease that holds 0, so the plane facing the push. Elsewhere n's own slope stays.
  Eigen::Vector3d g = (n - n.dot(u) * u) / facing, turn = Eigen::Vector3d::Zero();
  bool any = false;
  for (int axis = 0; axis < kNormalRays / 2; ++axis) {
    const SeenHit& ahead = hits[std::size_t(axis)];
    const SeenHit& behind = hits[std::size_t(axis + kNormalRays / 2)];
    const double up = ahead.hit ? ahead.t / h : 1.0, down = behind.hit ? behind.t / h : 1.0;
    const double w = crest_weight(up, down);
    if (!(w > 0)) continue;
    const Eigen::Vector3d& e = axes[std::size_t(axis)];
    turn -= w * g.dot(e) * e;  // (both sides fall away: 0 is in [-down, up])
    any = true;
  }
  if (!any) return n;
  g += (4.0 / kNormalRays) * turn;  // the least-squares gradient's change (exact for 4 rays)
  return (g - u).normalized();
}

Eigen::Vector3d SeenSolid::shaded_normal(const Eigen::Vector3d& u, const RingAxes& axes,
                                         const std::array<SeenHit, kNormalRays>& hits, double h) noexcept {
  const std::array<bool, kNormalRays> past = past_crease(u, axes, hits, h);
  Eigen::Vector3d map = Eigen::Vector3d::Zero();
  bool all = true;
  for (int k = 0; k < kNormalRays; ++k) {
    const SeenHit& x = hits[std::size_t(k)];
    if (x.hit && !past[std::size_t(k)]) map += x.shade;
    all = all && x.hit;
  }
  if (!(map.norm() > 0) || !map.allFinite()) return -u;
  map.normalize();
  if (map.dot(u) > 0) map = -map;
  if (!all || !(h > 0)) return map;
  // The seen depth's own slope over the ring, by least squares over its opposite pairs (ray k
  // and k + kNormalRays / 2 at +-h along ring_direction(k), evenly spread over half a turn:
  // the gradient is 4 / kNormalRays times the sum of each pair's slope along its direction); a
  // hit's t grows into the surface. (One-sided from the point, t = 0, for a pair with a ray past
  // a crease.)
  const auto grad = [&](int ahead, int behind) {
    if (past[std::size_t(ahead)]) return -hits[std::size_t(behind)].t / h;
    if (past[std::size_t(behind)]) return hits[std::size_t(ahead)].t / h;
    return (hits[std::size_t(ahead)].t - hits[std::size_t(behind)].t) / (2 * h);
  };
  Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
  for (int axis = 0; axis < kNormalRays / 2; ++axis)
    gradient += grad(axis, axis + kNormalRays / 2) * axes[std::size_t(axis)];
  const Eigen::Vector3d slope = (-u + (4.0 / kNormalRays) * gradient).normalized();
  const Eigen::Vector3d n = map + slope;
  return n.norm() > 1e-12 && n.allFinite() ? Eigen::Vector3d(n.normalized()) : map;
}

Eigen::Vector3d SeenSolid::normal(const Eigen::Vector3d& point, const Eigen::Vector3d& u, double h, double reach,
                                  double back, SeenScratch& s, double phase) const noexcept {
  std::array<SeenHit, kNormalRays> hits;
  for (int k = 0; k < kNormalRays; ++k) hits[std::size_t(k)] = normal_ray(point, u, k, h, reach, back, s, phase);
  return normal_from(u, hits, h, phase);
}

double SeenNormalReading::phase(int i) noexcept {
  // 0, 1/2, 1/4, 3/4 of the ring's period (its rays repeat every 2 pi / kNormalRays): each
  // reading at a spot halves the largest gap its rays left.
  static constexpr std::array<double, kPhases> kOrder{0.0, 0.5, 0.25, 0.75};
  return 2 * std::numbers::pi / SeenSolid::kNormalRays * kOrder[std::size_t(i % kPhases)];
}

const Eigen::Vector3d& SeenNormalReading::update(const SeenSolid& solid, const Eigen::Vector3d& point,
                                                 const Eigen::Vector3d& u, double h, double back, double reuse,
                                                 SeenScratch& scratch) noexcept {
  if (!fresh_) {  // (SeenSolid::normal(), its rays kept)
    for (int k = 0; k < SeenSolid::kNormalRays; ++k)
      hits_[std::size_t(k)] = solid.normal_ray(point, u, k, h, h, back, scratch, phase(0));
    fresh_ = true;
    pending_ = -1;
    next_phase_ = 1;
    return start_spot(point, SeenSolid::normal_from(u, hits_, h, phase(0)), SeenSolid::creased(u, hits_, h, phase(0)));
  }
  if (pending_ < 0) {
    // A new spot once the point moved `reuse` from the last; else the spot's next turn of the
    // ring, until kPhases of them.
    const bool moved = (point - at_).norm() >= reuse;
    if (!moved && spot_readings_ >= kPhases) return normal_;
    pending_ = 0;
    refining_ = !moved;
    pending_at_ = moved ? point : at_;
    pending_back_ = back;
    pending_h_ = h;
    if (moved) next_phase_ = 0;  // (turned rings at successive spots of a slide made its normal wander)
    pending_phase_ = phase(next_phase_);
    next_phase_ = (next_phase_ + 1) % kPhases;
  }
  hits_[std::size_t(pending_)] =
      solid.normal_ray(pending_at_, u, pending_, pending_h_, pending_h_, pending_back_, scratch, pending_phase_);
  if (++pending_ < SeenSolid::kNormalRays) return normal_;
  pending_ = -1;
  const Eigen::Vector3d n = SeenSolid::normal_from(u, hits_, pending_h_, pending_phase_);
  const bool creased = SeenSolid::creased(u, hits_, pending_h_, pending_phase_);
  if (refining_ && creased) {  // (a turned ring met a crease the spot's first did not: no more turns)
    spot_readings_ = kPhases;
    return normal_;
  }
  if (refining_) {
    sum_ += n;
    ++spot_readings_;
    if (sum_.norm() > 1e-9) normal_ = sum_.normalized();
    settling_ = true;
    return normal_;
  }
  return start_spot(pending_at_, n, creased);
}

const Eigen::Vector3d& SeenNormalReading::start_spot(const Eigen::Vector3d& at, const Eigen::Vector3d& n,
                                                     bool creased) noexcept {
  normal_ = sum_ = n;
  at_ = at;
  spot_readings_ = creased ? kPhases : 1;  // (a creased spot is not read with the ring turned)
  settling_ = false;
  return normal_;
}

}  // namespace gshaptics
