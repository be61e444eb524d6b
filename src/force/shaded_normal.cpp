#include "gshaptics/force/shaded_normal.h"

#include <algorithm>
#include <cmath>
#include <Eigen/Cholesky>
#include <memory>
#include <vector>

#include "gshaptics/broadphase/bvh.h"
#include "gshaptics/narrowphase/k_min_batch.h"

namespace gshaptics {

namespace {

// A disc whose own normal (its shortest axis, turned toward c) lies more than acos(kAgree) ~ 73
// deg from the outward estimate, and beyond whose rim c lies, turns (fully at 90 deg) to the
// direction from its nearest rim point to c, as far as that direction agrees better with the
// estimate (over kGain of cosine): across a convex edge the other face's discs then point out,
// while in a concave groove, where the rim direction would point into the floor, they keep their
// normal. Such a disc also loses weight with its distance past the rim, in units of kRimFalloff
// kernel widths: it is not the surface nearest to c.
constexpr double kAgree = 0.3;
constexpr double kGain = 0.2;
constexpr double kRimFalloff = 0.5;

// What one Gaussian gives the sum at c, the parts that do not depend on the outward estimate
// (see the header): computed once a call and shared by the two passes.
struct Term {
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();  // shortest axis turned toward c
  Eigen::Vector3d rim = Eigen::Vector3d::Zero();   // unit direction from the nearest rim point to c (when beyond_rim)
  Eigen::Vector3d rad = Eigen::Vector3d::Zero();   // R A^-1 d / |A^-1 d|: the density gradient's direction
  Eigen::Vector3d at = Eigen::Vector3d::Zero();    // the Gaussian's centre relative to c (-d)
  double weight = 0;     // alpha exp(-q / 2)
  double flat = 0;       // 1 - a_min / a_mid
  double past = 0;       // distance past the rim, in kRimFalloff kernel widths
  bool beyond_rim = false;  // a disc (flat > 0) and c beyond its rim
};

// Term of g at c for a kernel width s (s2 = s^2), the support's q_cut (q_cutoff) and a rim
// falloff scale `rim`; false when g does not contribute (q > q_cut, or a floater beside the
// tool, see FreeBall).
inline bool term_of(const CollisionGaussian& g, const Eigen::Vector3d& c, double s2, double q_cut, double rim,
                    const FreeBall& ball, Term& out) noexcept {
  const Eigen::Vector3d d = c - Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
  const double d2 = d.squaredNorm();
  const double a0 = g.semi_axes[0], a1 = g.semi_axes[1], a2 = g.semi_axes[2];
  if (ball.radius > 0 && d.dot(ball.up) < 0.5 * ball.radius) {
    // Less than half the radius below the ball's centre (or above it), seen from the surface it
    // rests on: beside the tool, not under it. If its inscribed ball (radius a_min) also reaches
    // into the free ball, the proxy passed it (no blocker does: the proxy rests free of it, and
    // its inscribed ball lies inside it). The margin (1e-3 of the radius, ten times the proxy's
    // stand-off) keeps rounding from dropping a blocker.
    const double lim = ball.radius * (1.0 - 1e-3) + std::min({a0, a1, a2});
    if (d2 < lim * lim) return false;
  }
  // q >= |d|^2 / (a_max^2 + s^2): most of the box around c is dismissed before the rotation.
  // (The 1e-3 margin keeps rounding from dismissing one the exact q keeps.)
  const double a_max = g.radius;
  if (d2 > (q_cut + 1e-3 * q_cut) * (a_max * a_max + s2)) return false;
  // In the Gaussian's frame A = diag(a^2 + s^2): q = sum dl^2 / A, A^-1 d = R (dl / A).
  double r[9];
  rotation_from_quaternion<double>(g.quaternion[0], g.quaternion[1], g.quaternion[2], g.quaternion[3], r[0], r[1],
                                   r[2], r[3], r[4], r[5], r[6], r[7], r[8]);
  const Eigen::Matrix3d R = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(r);
  const Eigen::Vector3d dl = R.transpose() * d;
  const Eigen::Vector3d A(a0 * a0 + s2, a1 * a1 + s2, a2 * a2 + s2);
  const Eigen::Vector3d ad = dl.cwiseQuotient(A);
  const double q = dl.dot(ad);
  if (q > q_cut) return false;
  const double an2 = ad.squaredNorm();
  if (!(an2 > 0)) return false;
  const int jmin = thinnest_axis(g);
  const int ju = (jmin + 1) % 3, jv = (jmin + 2) % 3;
  out.flat = flatness(g);
  out.axis = R.col(jmin) * (dl[jmin] >= 0 ? 1.0 : -1.0);
  out.weight = double(g.opacity) * std::exp(-0.5 * q);
  if (ball.surface > 0 && out.flat > 0) {
    // A disc whose plane lies farther from c than the surface under the tool (FreeBall::surface)
    // is not under it: the far face of a concave crease.
    const double excess = (std::fabs(dl[jmin]) - ball.surface - 0.5 * rim) / (0.5 * rim);
    if (excess > 0) out.weight *= std::exp(-0.5 * out.flat * excess * excess);
  }
  out.rad = (R * ad) * (1.0 / std::sqrt(an2));
  out.at = -d;
  const double eu = dl[ju] / g.semi_axes[ju], ev = dl[jv] / g.semi_axes[jv];
  const double rho2 = eu * eu + ev * ev;  // > 1: c is beyond the disc's rim
  out.beyond_rim = out.flat > 0 && rho2 > 1.0;
  if (out.beyond_rim) {
    const double shrink = 1.0 - 1.0 / std::sqrt(rho2);
    Eigen::Vector3d off;  // from the rim point on the ray toward c's projection, to c
    off[jmin] = dl[jmin];
    off[ju] = dl[ju] * shrink;
    off[jv] = dl[jv] * shrink;
    out.rim = (R * off).normalized();  // (off is never zero: c is past the rim)
    out.past = std::sqrt(off[ju] * off[ju] + off[jv] * off[jv]) / (kRimFalloff * rim);
  }
  return true;
}

// The term's direction and weight for the outward estimate `outward` (zero in the first pass, in
// which every disc seen from beyond its rim takes the rim direction).
struct Sample {
  Eigen::Vector3d dir;
  double weight;
};
inline Sample sample(const Term& tm, const Eigen::Vector3d& outward, bool first_pass) noexcept {
  Eigen::Vector3d axis = tm.axis;
  double weight = tm.weight;
  const double agree = first_pass ? -1.0 : axis.dot(outward);
  if (tm.beyond_rim && agree < kAgree) {
    double t = std::min(1.0, (kAgree - agree) / kAgree);
    if (!first_pass) t *= std::clamp((tm.rim.dot(outward) - agree) / kGain, 0.0, 1.0);
    const Eigen::Vector3d blend = (1.0 - t) * axis + t * tm.rim;
    const double bn = blend.norm();
    if (bn > 1e-9) axis = blend / bn;
    weight *= std::exp(-0.5 * t * tm.past * tm.past);
  }
  return {tm.flat * axis + (1.0 - tm.flat) * tm.rad, weight};
}
inline Eigen::Vector3d contribution(const Term& tm, const Eigen::Vector3d& outward, bool first_pass) noexcept {
  const Sample sm = sample(tm, outward, first_pass);
  return sm.weight * sm.dir;
}

// The second pass's sum, corrected to first order where the field is one smooth surface: the
// local linear kernel regression of the Gaussians' directions on their centres, evaluated at c
// (Cleveland 1979; Fan 1992). The plain weighted sum is the Nadaraya-Watson estimate: where the
// Gaussians near c lie mostly to one side of it (a sparse or unevenly sampled surface) it reads
// the field at their weighted centroid, not at c, which on a curved surface is a tilt of
// (centroid offset) / (radius of curvature): 3-4 degrees on the 8 mm fidelity cylinder. The fit
// removes that: sum - W_f B^T (C_t + ridge^2 I)^-1 m_t, with m the fitted samples' weighted mean
// offset (m_t: in the tangent plane of the outward estimate), C_t their covariance in that
// plane, B the covariance of offset and direction, W_f their weight. Only samples whose
// direction agrees with the outward estimate are fitted (fully within acos(kFitFull) ~ 18 deg,
// fading to none at acos(kFitNone) ~ 32 deg): across an edge or a corner the directions are not
// a linear field. The correction also fades with the square of the fitted share of the weight,
// and the ridge (kFitRidge kernel widths) keeps the fit from extrapolating where the samples lie
// along a line.
constexpr double kFitFull = 0.95, kFitNone = 0.85;
constexpr double kFitRidge = 0.25;

class LocalLinearSum {
 public:
  explicit LocalLinearSum(const Eigen::Vector3d& outward) noexcept : outward_(outward) {}
  void add(const Term& tm) noexcept {
    const Sample sm = sample(tm, outward_, false);
    sum_ += sm.weight * sm.dir;
    weight_ += sm.weight;
    const double dn = sm.dir.norm();
    const double fit =
        dn > 0 ? std::clamp((sm.dir.dot(outward_) / dn - kFitNone) / (kFitFull - kFitNone), 0.0, 1.0) : 0.0;
    if (!(fit > 0)) return;
    const double w = fit * sm.weight;
    const Eigen::Vector3d wx = w * tm.at;
    fw_ += w;
    fx_ += wx;
    fn_ += w * sm.dir;
    fxx_ += wx * tm.at.transpose();
    fxn_ += wx * sm.dir.transpose();
  }
  // The corrected sum for a kernel width s (m).
  [[nodiscard]] Eigen::Vector3d result(double s) const noexcept {
    if (!(fw_ > 0) || !(weight_ > 0)) return sum_;
    const Eigen::Vector3d m = fx_ / fw_, nbar = fn_ / fw_;
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - outward_ * outward_.transpose();
    const double ridge = kFitRidge * s;
    const Eigen::Matrix3d C =
        P * (fxx_ / fw_ - m * m.transpose()) * P + ridge * ridge * Eigen::Matrix3d::Identity();
    const Eigen::Matrix3d B = fxn_ / fw_ - m * nbar.transpose();
    const Eigen::Vector3d y = C.ldlt().solve(P * m);
    const double share = fw_ / weight_;
    const Eigen::Vector3d out = sum_ - fw_ * share * share * (B.transpose() * y);
    return out.allFinite() ? out : sum_;
  }

 private:
  Eigen::Vector3d outward_;
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero(), fx_ = Eigen::Vector3d::Zero(), fn_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d fxx_ = Eigen::Matrix3d::Zero(), fxn_ = Eigen::Matrix3d::Zero();
  double weight_ = 0, fw_ = 0;
};

// The support of the sum at c for a tool of bounding radius `radius` and kernel width s (the
// header's shaded_normal): q <= q_cut.
inline double q_cutoff(double radius, double s, double tail = kShadingTail) noexcept {
  return (1 + radius / s) * (1 + radius / s) + tail;
}
// Calls f(first, count) for the BVH leaves that may hold such Gaussians: those whose box comes
// within s sqrt(q_cut) of c (a ball: the box around it alone would take about twice as many
// Gaussians off a volumetric scene).
template <typename F>
void for_each_kernel_leaf(const CollisionWorld& world, const Eigen::Vector3d& c, double s, double q_cut, F&& f) noexcept {
  const double half = s * std::sqrt(q_cut);
  float lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = round_down_to_float(c[k] - half);
    hi[k] = round_up_to_float(c[k] + half);
  }
  const double reach = half * half * (1 + 1e-6);
  world.bvh().for_each_overlapping_leaf_node(lo, hi, [&](const BvhNode& leaf) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double e = std::max({double(leaf.lo[k]) - c[k], c[k] - double(leaf.hi[k]), 0.0});
      d2 += e * e;
    }
    if (d2 <= reach) f(leaf.first, leaf.count);
    return true;
  });
}

// Calls f(term) for every contributing Gaussian near c, in BVH order.
// Returns how many Gaussians it visited.
template <typename F>
std::size_t for_each_term(const CollisionWorld& world, const Eigen::Vector3d& c, double q_cut, double s, double rim,
                          const FreeBall& ball, F&& f) noexcept {
  const CollisionGaussian* gs = world.gaussians().data();
  Term tm;
  std::size_t visited = 0;
  for_each_kernel_leaf(world, c, s, q_cut, [&](std::uint32_t first, std::uint32_t count) {
    visited += count;
    for (std::uint32_t k = first; k < first + count; ++k)
      if (term_of(gs[k], c, s * s, q_cut, rim, ball, tm)) f(tm);
  });
  return visited;
}

// The weighted sum of the Gaussians' directions at c (plain: the terms computed as they come).
Eigen::Vector3d direction_sum(const CollisionWorld& world, const Eigen::Vector3d& c, double q_cut, double s,
                              double rim, const FreeBall& ball, const Eigen::Vector3d& outward) noexcept {
  const bool first_pass = outward.isZero(0);
  if (!first_pass) {
    LocalLinearSum fit(outward);
    for_each_term(world, c, q_cut, s, rim, ball, [&](const Term& tm) { fit.add(tm); });
    return fit.result(s);
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for_each_term(world, c, q_cut, s, rim, ball, [&](const Term& tm) { sum += contribution(tm, outward, first_pass); });
  return sum;
}

Eigen::Vector3d finish(const Eigen::Vector3d& sum) noexcept {
  const double n = sum.norm();
  return n > 0 && std::isfinite(n) ? Eigen::Vector3d(sum / n) : Eigen::Vector3d::Zero();
}

}  // namespace

struct ShadingScratch::Terms {
  std::vector<Term> terms;
  // A reading spread over calls (ShadedNormalCache::read_ahead): the BVH leaves of its box, then
  // its terms in the same order as shaded_normal() takes them, then their local linear fit.
  struct Range {
    std::uint32_t first, count;
  };
  std::vector<Range> ranges;
  std::size_t n_ranges = 0, range_i = 0, offset = 0, n = 0, fit_i = 0, steps = 0;
  int phase = 0;  // 1: terms, 2: the fit
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), first = Eigen::Vector3d::Zero();
  double radius = 0, s = 0, rim = 0;
  FreeBall ball;
  LocalLinearSum fit{Eigen::Vector3d::Zero()};

  // Starts reading at c: false when the box holds more leaves than `ranges` (read it at once).
  bool begin(const CollisionWorld& world, const Eigen::Vector3d& at, double radius_in, double kernel,
             const FreeBall& ball_in, double min_width) noexcept {
    c = at;
    radius = radius_in;
    rim = kernel * radius;
    s = std::max(rim, min_width);
    ball = ball_in;
    n_ranges = 0;
    bool fits = true;
    for_each_kernel_leaf(world, c, s, q_cutoff(radius, s), [&](std::uint32_t f, std::uint32_t count) {
      if (n_ranges < ranges.size())
        ranges[n_ranges++] = {f, count};
      else
        fits = false;
    });
    range_i = offset = n = fit_i = steps = 0;
    first = Eigen::Vector3d::Zero();
    phase = 1;
    return fits;
  }
  // Advances the reading by up to `budget` steps (a Gaussian visited, or a term fitted): 1 when
  // it is done (the normal in `out`), 0 while it is not, -1 when its terms outgrow the scratch.
  int advance(const CollisionWorld& world, std::size_t budget, Eigen::Vector3d& out) noexcept {
    const CollisionGaussian* gs = world.gaussians().data();
    Term tm;
    while (phase == 1 && budget > 0) {
      if (range_i == n_ranges) {
        const double n1 = first.norm();
        if (!(n1 > 0) || !std::isfinite(n1)) {
          out = Eigen::Vector3d::Zero();
          phase = 0;
          return 1;
        }
        fit = LocalLinearSum(first / n1);
        phase = 2;
        break;
      }
      const Range& rg = ranges[range_i];
      const std::uint32_t k = rg.first + std::uint32_t(offset);
      ++steps;
      if (term_of(gs[k], c, s * s, q_cutoff(radius, s), rim, ball, tm)) {
        first += contribution(tm, Eigen::Vector3d::Zero(), true);
        if (n == terms.size()) return phase = 0, -1;
        terms[n++] = tm;
      }
      if (++offset == rg.count) offset = 0, ++range_i;
      --budget;
    }
    for (; phase == 2 && budget > 0 && fit_i < n; --budget, ++steps) fit.add(terms[fit_i++]);
    if (phase == 2 && fit_i == n) {
      out = finish(fit.result(s));
      phase = 0;
      return 1;
    }
    return 0;
  }
};

ShadingScratch::ShadingScratch(std::size_t capacity) : terms_(std::make_unique<Terms>()) {
  terms_->terms.resize(capacity);
  terms_->ranges.resize(std::max<std::size_t>(64, capacity / 4));
}
ShadingScratch::~ShadingScratch() = default;
ShadingScratch::ShadingScratch(const ShadingScratch& o) : ShadingScratch(o.capacity()) {}
ShadingScratch& ShadingScratch::operator=(const ShadingScratch& o) {
  if (this != &o) {
    terms_->terms.resize(o.capacity());
    terms_->ranges.resize(o.terms_->ranges.size());
    terms_->phase = 0;
  }
  return *this;
}
std::size_t ShadingScratch::capacity() const noexcept { return terms_->terms.size(); }

Eigen::Vector3d shaded_normal(const CollisionWorld& world, const Eigen::Vector3d& c, double radius, double kernel,
                              const FreeBall& ball, double min_width, double tail) noexcept {
  const double rim = kernel * radius, s = std::max(rim, min_width), q_cut = q_cutoff(radius, s, tail);
  const Eigen::Vector3d first = direction_sum(world, c, q_cut, s, rim, ball, Eigen::Vector3d::Zero());
  const double n1 = first.norm();
  if (!(n1 > 0) || !std::isfinite(n1)) return Eigen::Vector3d::Zero();
  return finish(direction_sum(world, c, q_cut, s, rim, ball, first / n1));
}

Eigen::Vector3d shaded_normal(const CollisionWorld& world, const Eigen::Vector3d& c, double radius, double kernel,
                              ShadingScratch& scratch, const FreeBall& ball, double min_width) noexcept {
  const double rim = kernel * radius, s = std::max(rim, min_width), q_cut = q_cutoff(radius, s);
  std::vector<Term>& terms = scratch.terms_->terms;
  std::size_t n = 0;
  bool overflow = false;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  const std::size_t visited = for_each_term(world, c, q_cut, s, rim, ball, [&](const Term& tm) {
    first += contribution(tm, Eigen::Vector3d::Zero(), true);
    if (n < terms.size())
      terms[n++] = tm;
    else
      overflow = true;
  });
  scratch.last_terms_ = n;
  scratch.last_overflow_ = overflow;
  scratch.last_steps_ = visited + n;
 
  const double n1 = first.norm();
  if (!(n1 > 0) || !std::isfinite(n1)) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d outward = first / n1;
  if (overflow) return finish(direction_sum(world, c, q_cut, s, rim, ball, outward));  // more than it holds: the plain pass
  LocalLinearSum fit(outward);
  for (std::size_t i = 0; i < n; ++i) fit.add(terms[i]);
  return finish(fit.result(s));
}

const Eigen::Vector3d& ShadedNormalCache::read_ahead(const CollisionWorld& world, const Eigen::Vector3d& at,
                                                     double scale, double kernel, double reuse, ShadingScratch& scratch,
                                                     std::size_t budget, const FreeBall& ball,
                                                     double min_width) noexcept {
  ShadingScratch::Terms& pending = *scratch.terms_;
  // The field's turn bounds how far a reading is kept (reuse_within), but a reading that costs
  // more than the tick's budget is kept at least as far as a reading ahead needs to be prepared:
  // twice the proxy's motion this tick times the ticks its steps take at the budget. On a fast
  // slide the tick's cost wins; at rest and on slow presses, where a normal held over a steep
  // field turns into energy, the tolerance holds.
  const double largest_reuse = reuse;
  reuse = reuse_within(reuse);
  if (reuse < largest_reuse && valid_ && budget > 0 && scratch.last_steps_ > budget)
    reuse = std::min(largest_reuse, std::max(reuse, 2.0 * (at - last_at_).norm() * double(scratch.last_steps_) /
                                                        double(budget)));
  if (pending_ && pending.phase == 0) pending_ = false;  // (the scratch served another reading meanwhile)
  path_ += valid_ ? (at - last_at_).norm() : 0.0;
  last_at_ = at;
  if (!(valid_ && (at - at_).norm() <= reuse)) {
    // Due: the reading prepared ahead if it was made for a point within `reuse` of `at` (finished
    // now if it is not yet), else a new one.
    const bool near = (at - pending_at_).norm() <= reuse;
    Eigen::Vector3d out = ready_normal_;
    int done = ready_ && near ? 1 : 0;
    if (pending_ && near) {
      done = pending.advance(world, SIZE_MAX, out);
      if (done == 1) scratch.last_steps_ = pending.steps;
    }
    pending_ = ready_ = ahead_blocked_ = false;
    pending.phase = 0;
    calls_ = 0;
    path_ = 0;
    if (done == 1) {
      take(out, pending_at_);
      ++reads_;
      return normal_;
    }
    return read(world, at, scale, kernel, largest_reuse, scratch, ball, min_width);
  }
  if (budget == 0) return normal_;
  // A reading ahead is started only where one costs more than a tick's budget, and only on a
  // steady motion: it took `calls_` calls to move half of `reuse` on a nearly straight path, so
  // about as many remain, and the reading, made for where the proxy will then be, is spread
  // evenly over them. A cheaper reading, or one on a faster or wandering motion, is made whole
  // when due. So is one on a motion so slow that readings are rare (more than kAheadCalls calls
  // to half of `reuse`): spread over that many ticks it only adds to many ticks what one paid
  // (on the real scenes' probe runs it raised the p99 by 2-9 us and left the maximum as it
  // was; bench/RESULTS.md).
  constexpr std::size_t kAheadCalls = 8;
  constexpr double kStraight = 0.8;  // displacement over path length
  ++calls_;
  const double moved = (at - at_).norm();
  const std::size_t share = (scratch.last_steps_ + calls_ - 1) / calls_;
  if (!pending_ && !ready_ && !ahead_blocked_ && scratch.last_steps_ > budget && moved > 0.5 * reuse &&
      moved >= kStraight * path_ && share <= budget && calls_ <= kAheadCalls) {
    ahead_share_ = share;
    pending_at_ = at + (at - at_);  // as far on again as it came
    pending_ = pending.begin(world, pending_at_, scale, kernel, ball, min_width);
    if (!pending_) {
      pending.phase = 0;
      ahead_blocked_ = true;  // (too many leaves: this stretch reads at once)
    }
  }
  if (pending_) {
    const int done = pending.advance(world, ahead_share_, ready_normal_);
    if (done != 0) pending_ = false;
    if (done == 1) scratch.last_steps_ = pending.steps, ready_ = true;  // (taken when due)
    if (done < 0) ahead_blocked_ = true;  // (more terms than the scratch holds: this stretch reads at once)
  }
  return normal_;
}

double shading_spacing(const CollisionWorld& world, std::span<const Contact> blockers) noexcept {
  double spacing = 0;
  for (const Contact& b : blockers) spacing = std::max(spacing, middle_semi_axis(world.gaussians()[b.slot]));
  return spacing;
}

double shading_scale(const CollisionWorld& world, std::span<const Contact> blockers, double radius) noexcept {
  return std::max(radius, shading_spacing(world, blockers));
}

}  // namespace gshaptics
