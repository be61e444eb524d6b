#include "gshaptics/collision/sweep_query.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "gshaptics/broadphase/bvh.h"
#include "gshaptics/narrowphase/k_min.h"

namespace gshaptics {

namespace {

constexpr double kNever = std::numeric_limits<double>::infinity();

// The quadratic "inside E_lambda" in t, for one lambda: qa t^2 + qb t + qc <= 0.
struct Quadratic {
  double qa, qb, qc;
};

// Entry time into E_lambda (smaller root), or +infinity when the line misses it or left it before
// t = 0 (convexity: it never comes back).
inline double entry_time(const Quadratic& q) noexcept {
  if (!(q.qa > 0)) return q.qc <= 0 ? -kNever : kNever;  // no motion across: inside or never
  const double disc = q.qb * q.qb - 4 * q.qa * q.qc;
  if (!(disc >= 0)) return kNever;
  const double sq = std::sqrt(disc);
  // Stable roots: q = -(qb + sign(qb) sq) / 2; roots q / qa and qc / q.
  const double h = -0.5 * (q.qb + (q.qb >= 0 ? sq : -sq));
  double t1 = h / q.qa, t2 = h != 0 ? q.qc / h : t1;
  if (t1 > t2) std::swap(t1, t2);
  return t2 < 0 ? kNever : t1;
}

// Evaluates the quadratic for a lambda in a frame where both shapes are diagonal: Sigma_g =
// diag(a2) and Sigma_t = r2 I there (for a spherical tool the Gaussian's own frame; for an
// ellipsoidal one, see sweep_time), so that M = (lambda Sigma_g + (1 - lambda) Sigma_t)^-1 is
// diagonal too. `back` maps that frame's M d to the world's.
struct PairSweep {
  Eigen::Vector3d dg, ug, a2;
  double r2 = 0;
  Eigen::Matrix3d back;

  Quadratic at(double lambda, Eigen::Vector3d* m_d = nullptr, double t = 0) const noexcept {
    const double w_inv = 1.0 / (lambda * (1.0 - lambda));
    double qa = 0, qb = 0, qc = 0;
    Eigen::Vector3d md;
    for (int j = 0; j < 3; ++j) {
      const double inv_m = 1.0 / (lambda * a2[j] + (1.0 - lambda) * r2);
      qa += ug[j] * ug[j] * inv_m;
      qb += ug[j] * dg[j] * inv_m;
      qc += dg[j] * dg[j] * inv_m;
      md[j] = (dg[j] - t * ug[j]) * inv_m;
    }
    if (m_d != nullptr) *m_d = back * md;
    return {qa, -2 * qb, qc - w_inv};
  }
};

// The member of the family that is exact for a sphere of radius r against the ellipsoid along
// the offset's direction: there the ellipsoid's radius is rho = |d| / |diag(1/a) d| and the
// sphere touches it at |d| = rho + r, where lambda = r / (rho + r) gives the smallest member
// (min over lambda of rho^2 / (1 - lambda) + r^2 / lambda). `dl`: the offset in the Gaussian's
// frame. A tight lower bound of the contact time (a disc under a sliding tool: lambda near 1,
// where lambda = 1/2 is loose by 40 % of r). 1/2 when degenerate.
inline double geometric_lambda(const CollisionGaussian& g, const double* dl, double r) noexcept {
  double d2 = 0, e2 = 0;
  for (int j = 0; j < 3; ++j) {
    const double a = g.semi_axes[j];
    if (!(a > 0)) return 0.5;
    d2 += dl[j] * dl[j];
    e2 += (dl[j] / a) * (dl[j] / a);
  }
  if (!(d2 > 0) || !(e2 > 0)) return 0.5;
  const double rho = std::sqrt(d2 / e2);
  return std::clamp(r / (rho + r), 1e-6, 1.0 - 1e-6);
}

// lambda from s = ln(lambda / (1 - lambda)).
inline double lambda_of(double s) noexcept { return 1.0 / (1.0 + std::exp(-s)); }

// |diag(a) R^T v|^2: the squared support of the ellipsoid (rotation R, semi-axes a) along v,
// times |v|^2 (v need not be unit).
inline double support_sq(const Eigen::Matrix3d& R, const float* a, const Eigen::Vector3d& v) noexcept {
  double h2 = 0;
  for (int j = 0; j < 3; ++j) {
    const double vr = v[0] * R(0, j) + v[1] * R(1, j) + v[2] * R(2, j);
    h2 += double(a[j]) * a[j] * vr * vr;
  }
  return h2;
}

// Whether the ellipsoid (rotation R, semi-axes a) whose centre is at v from a point (or from the
// nearest point of a line, v across it) stays beyond `reach` of it: along v's direction none of
// it is nearer than d - h, d = |v| and h its support, so d - h > reach suffices; tested as
// d^2 - reach d > |diag(a) R^T v| = d h (one square root, no division; margins outward).
inline bool beyond_reach(const Eigen::Vector3d& v, double reach, const Eigen::Matrix3d& R, const float* a) noexcept {
  const double d2 = v.squaredNorm(), lhs = d2 - reach * std::sqrt(d2);
  return lhs > 0 && lhs * lhs > support_sq(R, a, v) * (1 + 4e-9);
}

// An elongated ellipsoid (semi-axes a >= b >= c, a > b) lies inside the capsule of radius b round
// the segment of half-length a - b on its long axis: a point x of it has |x_perp|^2 <= b^2 (1 -
// x_a^2 / a^2), within b of the segment. So a Gaussian, within its bounding radius of its
// centre, touches the part only when its centre comes within that radius + b of the axis's
// line (no nearer than the segment). Beside a stylus lying on a layer the bounding sphere
// (radius a) lets through every Gaussian within a of the part's centre; this keeps those within
// about b of its axis. Kept apart from the candidates' loop (its own call, for elongated parts
// only): inlined there, it slowed the spheres' loop by 5-8 %.
struct Capsule {
  Eigen::Vector3d axis, m_across;  // the long axis (world, unit); the motion's part across it
  double radius = 0, m_across2 = 0, m_across_len = 0;  // (the length with a rounding's margin, outward)
  Capsule() = default;
  [[gnu::noinline]] Capsule(const Eigen::Vector3d& long_axis, double b, const Eigen::Vector3d& motion)
      : axis(long_axis), m_across(motion - motion.dot(long_axis) * long_axis),
        radius(b * (1 + 1e-9)),  // (a rounding's margin, outward)
        m_across2(m_across.squaredNorm()), m_across_len(std::sqrt(m_across2) * (1 + 1e-9)) {}
  // The earliest t in [0, 1] at which a centre at `rel` from the part's start (the part moving by
  // the motion) comes within `r_g` + b of the axis: 0 when it is already, kNever when never.
  [[gnu::noinline]] double entry_time(const Eigen::Vector3d& rel, double r_g) const noexcept {
    const double reach = r_g + radius;
    const Eigen::Vector3d across = rel - rel.dot(axis) * axis;
    const double cc = across.squaredNorm() - reach * reach;
    if (cc <= 0) return 0;
    const double bc = across.dot(m_across), dc = bc * bc - m_across2 * cc;
    if (dc < 0 || bc <= 0) return kNever;
    return cc / (bc + std::sqrt(dc));  // (the smaller root, without cancellation)
  }
  // Whether a Gaussian (centre at `rel` from the part's start; rotation R, semi-axes a) stays
  // farther than b from the axis's line until `bar`: along n, the unit direction from the line to
  // its centre (across the axis), no point of it is nearer the line than |across| - h(n), h(n) =
  // |diag(a) R^T n| its support, and the line moves by at most bar |m_across|. Tighter than the
  // bounding sphere for the flat Gaussians of a layer under a stylus lying on it (their support
  // toward the axis is their thickness). (The infinite line: the part's ends are left out, so it
  // never rules out too much.)
  [[gnu::noinline]] bool clear_until(const Eigen::Vector3d& rel, const Eigen::Matrix3d& R, const float* a,
                                     double bar) const noexcept {
    return beyond_reach(rel - rel.dot(axis) * axis, radius * (1 + 1e-9) + std::max(0.0, bar) * m_across_len, R, a);
  }
};

// A flat ellipsoid (smallest semi-axis c under half the middle one) lies between the two planes
// at +-c along its shortest axis n; a Gaussian reaches h_g(n) = |diag(a) R_g^T n| along n from its
// centre. So the two touch only while the centre is within c + h_g(n) of the part's mid-plane
// (a separating axis that moves with the part). Under a disc tilted onto a layer the motion's
// slab lets through the disc's whole footprint; this keeps the Gaussians near the disc's plane.
// Its own call, as the capsule's.
struct FlatSlab {
  Eigen::Vector3d n;  // the shortest axis (world, unit)
  double c = 0, nm = 0;  // half-thickness; the motion along n
  FlatSlab() = default;
  [[gnu::noinline]] FlatSlab(const Eigen::Vector3d& short_axis, double half, const Eigen::Vector3d& motion)
      : n(short_axis), c(half * (1 + 1e-9)), nm(motion.dot(short_axis)) {}
  // The earliest t in [0, 1] at which anything within `reach` of `rel` along n (from the part's
  // start) is within the slab: 0 when it is already, kNever when never. A BVH leaf passes its
  // bounding sphere's radius.
  [[gnu::noinline]] double entry_time(const Eigen::Vector3d& rel, double reach) const noexcept {
    const double total = c + reach, s = n.dot(rel);
    if (std::fabs(s) <= total) return 0;
    // s - t nm must come within +-total: from the near side, moving toward the plane.
    if (s > 0 ? !(nm > 0) : !(nm < 0)) return kNever;
    return (std::fabs(s) - total) / std::fabs(nm);
  }
  // The same for a Gaussian (its rotation R and semi-axes a): its reach along n is
  // |diag(a) R^T n|.
  [[gnu::noinline]] double entry_time(const Eigen::Vector3d& rel, const Eigen::Matrix3d& R,
                                      const float* a) const noexcept {
    return entry_time(rel, std::sqrt(support_sq(R, a, n)) * (1 + 1e-9));  // (margin outward)
  }
};

struct PartBounds {
  Eigen::Vector3d c0, half;  // centre at the start; half extent of the tool's box
  float lo[3], hi[3];
  double r_tool, h_tool, r2_tool;
  bool spherical;
  // An ellipsoidal part: its covariance diag(b^2) in the world (xx, yy, zz, xy, xz, yz) and
  // W = diag(1/b) R_t^T, for the family members' bound.
  double st[6];
  Eigen::Matrix3d w;
  // diag(b) R_t^T: the part's support along a world direction n is |bt n|.
  Eigen::Matrix3d bt;
  bool capsule;  // elongated: its capsule bound applies (Capsule)
  bool flat;     // flat: its slab along the shortest axis applies (FlatSlab)
  // Fills the constants (not the boxes) for `tool` moved by `motion` (m_hat its direction).
  // Out of line: inlined, it grew sweep_parts past the size at which GCC inlines the candidates'
  // loop whole, and the spheres' loop ran 5-8 % slower.
  [[gnu::noinline]] void set(const ToolEllipsoid& tool, const Eigen::Vector3d& motion, const Eigen::Vector3d& m_hat,
                             Capsule& capsule_of, FlatSlab& slab_of) noexcept {
    c0 = tool.center;
    r_tool = tool.bounding_radius();
    const Eigen::Vector3d& b = tool.semi_axes;
    spherical = std::fabs(b.x() - b.y()) <= 1e-12 * b.x() && std::fabs(b.x() - b.z()) <= 1e-12 * b.x();
    r2_tool = b.x() * b.x();
    if (spherical) {
      // (No rotation: the box and the extent along the motion are the radius's, as
      // aabb_half_extent() and the general formula give them to rounding.)
      half = Eigen::Vector3d::Constant(b.maxCoeff());
      h_tool = b.maxCoeff();
      capsule = flat = false;
      return;
    }
    half = tool.aabb_half_extent();
    const Eigen::Matrix3d Rt = tool.rotation.normalized().toRotationMatrix();
    h_tool = (tool.semi_axes.cwiseProduct(Rt.transpose() * m_hat)).norm();  // tool extent along m
    {
      const Eigen::Matrix3d S = Rt * b.cwiseAbs2().asDiagonal() * Rt.transpose();
      st[0] = S(0, 0), st[1] = S(1, 1), st[2] = S(2, 2), st[3] = S(0, 1), st[4] = S(0, 2), st[5] = S(1, 2);
      w = b.cwiseInverse().asDiagonal() * Rt.transpose();
      bt = b.asDiagonal() * Rt.transpose();
    }
    int i_long = 0;
    const double a_long = b.maxCoeff(&i_long), b_mid = b.sum() - a_long - b.minCoeff();
    capsule = a_long > 1.5 * b_mid;
    if (capsule) capsule_of = Capsule(Rt.col(i_long), b_mid, motion);
    int i_short = 0;
    const double c_short = b.minCoeff(&i_short);
    flat = c_short < 0.5 * b_mid;
    if (flat) slab_of = FlatSlab(Rt.col(i_short), c_short, motion);
  }
};

// Whether anything in `leaf` (within the bounding sphere of its box) can reach the part's
// capsule or slab by `bar` (a fraction of the motion): the swept box of a stylus or disc lying
// across a layer holds many leaves far from its axis or plane. Out of line, as PartBounds::set.
[[gnu::noinline]] bool leaf_within_reach(const BvhNode& leaf, const PartBounds& q, const Capsule& capsule,
                                         const FlatSlab& slab, double bar) noexcept {
  Eigen::Vector3d mid, half_diag;
  for (int k = 0; k < 3; ++k) {
    mid[k] = 0.5 * (double(leaf.lo[k]) + double(leaf.hi[k]));
    half_diag[k] = 0.5 * (double(leaf.hi[k]) - double(leaf.lo[k]));
  }
  const Eigen::Vector3d rel = mid - q.c0;
  const double r_leaf = half_diag.norm() * (1 + 1e-9);
  if (q.capsule && capsule.entry_time(rel, r_leaf) > bar) return false;
  return !(q.flat && slab.entry_time(rel, r_leaf) > bar);
}

// Whether a leaf's box comes within a spherical part's radius of its centre's path up to `bar`
// (the segment from c0 to c0 + bar motion): the box's distance from the segment's midpoint, less
// the segment's half-length, bounds its distance from the segment below (the distance is
// 1-Lipschitz along it). A sphere resting on a layer spans a box whose floor holds hundreds of
// Gaussians; only those under its cap can touch it.
[[gnu::always_inline]] inline bool leaf_near_sphere_path(const BvhNode& leaf, const PartBounds& q,
                                                         const Eigen::Vector3d& motion, double bar) noexcept {
  const double t = 0.5 * std::max(0.0, bar);
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double m = q.c0[k] + t * motion[k];
    const double e = std::max({double(leaf.lo[k]) - m, m - double(leaf.hi[k]), 0.0});
    d2 += e * e;
  }
  const double reach = (q.r_tool + t * motion.norm()) * (1 + 1e-9);  // (a rounding's margin, outward)
  return d2 <= reach * reach;
}

}  // namespace

namespace {

// The pair's frame (PairSweep): the Gaussian's own for a spherical tool; for an ellipsoidal one,
// the frame where both shapes are diagonal. d0: the Gaussian's centre less the tool's (world).
PairSweep pair_frame(const Eigen::Vector3d& d0, const Eigen::Matrix3d& Rg, const Eigen::Vector3d& a,
                     const ToolEllipsoid& tool, const Eigen::Vector3d& motion) noexcept {
  PairSweep p;
  const Eigen::Vector3d& b = tool.semi_axes;
  const bool spherical = std::fabs(b.x() - b.y()) <= 1e-12 * b.x() && std::fabs(b.x() - b.z()) <= 1e-12 * b.x();
  if (spherical) {
    p.dg = Rg.transpose() * d0;
    p.ug = Rg.transpose() * motion;
    p.a2 = a.cwiseAbs2();
    p.r2 = b.x() * b.x();
    p.back = Rg;
  } else {
    // An ellipsoidal tool: both shapes diagonal at once (simultaneous diagonalisation, e.g.
    // Golub & Van Loan, "Matrix Computations", Sec. 8.7). W = diag(1/b) R_t^T turns the tool into
    // the unit sphere and W Sigma_g W^T = Q Lambda Q^T; the quadratic forms are invariant, so in
    // the frame Q^T W the pair is the spherical case with a^2 = Lambda and r = 1 (Newton's
    // method below included), and the world's M d is W^T Q times that frame's.
    const Eigen::Matrix3d Rt = tool.rotation.normalized().toRotationMatrix();
    const Eigen::Matrix3d W = b.cwiseInverse().asDiagonal() * Rt.transpose();
    const Eigen::Matrix3d WR = W * Rg;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(WR * a.cwiseAbs2().asDiagonal() * WR.transpose());
    const Eigen::Matrix3d& Q = eig.eigenvectors();
    p.dg = Q.transpose() * (W * d0);
    p.ug = Q.transpose() * (W * motion);
    p.a2 = eig.eigenvalues().cwiseMax(0.0);
    p.r2 = 1.0;
    p.back = W.transpose() * Q;
  }
  return p;
}

// The maximum of t_e over s = ln(lambda / (1 - lambda)), refined by Brent's method on
// [centre - half, centre + half] from the point centre (where t_e is t_centre); `stop` when an
// evaluation proves the contact later than stop_above; `edge` when it ended at the bracket's
// edge (the maximum may lie outside).
struct Refined {
  double t, s;
  bool stop;
  bool edge = false;
};

// (Out of line: with a third call site, below, GCC's inlining of it slowed the stylus's
// fidelity-cube bench set by 0.3-0.5 us p99; out of line at all three, by 0.1-0.2.)
[[gnu::noinline]] Refined brent_refine(const PairSweep& p, double centre, double t_centre, double half,
                                    double stop_above) noexcept {
  // Brent's method (Brent 1973, "Algorithms for Minimization without Derivatives", ch. 5):
  // parabolic steps through the three best points, golden-section steps where a parabola is not
  // trusted. It needs 8-15 evaluations where plain golden section needs 34 for a bracket of
  // 1e-6 in s; t_e is smooth and flat at its maximum, so t* is
  // exact to far below the proxy's stand-off. Non-finite values (inside every E_lambda at t = 0:
  // -infinity) force golden steps.
  constexpr double kCGold = 0.3819660112501051;
  constexpr double kTol = 1e-6;
  double lo = centre - half, hi = centre + half;
  double x = centre, w = centre, v = centre;
  double fx = -t_centre, fw = fx, fv = fx;  // minimising -t_e
  double d = 0, e = 0;
  for (int it = 0; it < 40; ++it) {
    const double m = 0.5 * (lo + hi);
    const double tol2 = 2 * kTol;
    if (std::fabs(x - m) <= tol2 - 0.5 * (hi - lo)) break;
    bool golden = true;
    if (std::fabs(e) > kTol && std::isfinite(fx) && std::isfinite(fw) && std::isfinite(fv)) {
      double r = (x - w) * (fx - fv), q = (x - v) * (fx - fw);
      double pp = (x - v) * q - (x - w) * r;
      q = 2 * (q - r);
      if (q > 0) pp = -pp;
      q = std::fabs(q);
      const double e_prev = e;
      if (std::fabs(pp) < std::fabs(0.5 * q * e_prev) && pp > q * (lo - x) && pp < q * (hi - x)) {
        e = d;
        d = pp / q;
        const double u = x + d;
        if (u - lo < tol2 || hi - u < tol2) d = m >= x ? kTol : -kTol;
        golden = false;
      }
    }
    if (golden) {
      e = x >= m ? lo - x : hi - x;
      d = kCGold * e;
    }
    const double u = std::fabs(d) >= kTol ? x + d : x + (d >= 0 ? kTol : -kTol);
    const double tu = entry_time(p.at(lambda_of(u)));
    if (tu > stop_above) return Refined{tu, 0, true};
    const double fu = -tu;
    if (fu <= fx) {
      (u >= x ? lo : hi) = x;
      v = w, fv = fw;
      w = x, fw = fx;
      x = u, fx = fu;
    } else {
      (u < x ? lo : hi) = u;
      if (fu <= fw || w == x) {
        v = w, fv = fw;
        w = u, fw = fu;
      } else if (fu <= fv || v == x || v == w) {
        v = u, fv = fu;
      }
    }
  }
  return Refined{-fx, x, false, std::fabs(x - (centre - half)) < 1e-3 || std::fabs(x - (centre + half)) < 1e-3};
}

// Newton's method on the stationarity of t_e in s (diagonal shapes in the pair's frame, so
// the derivatives are a few sums): F(t, lambda) = sum e_j^2 / m_j -
// 1 / w with e = dg - t ug, m_j = lambda a_j^2 + (1 - lambda) r^2, w = lambda (1 - lambda);
// t_e(lambda) is F's smaller root, dt_e/dlambda = -F_l / F_t, and the maximum is the root of
// phi(lambda) = F_l(t_e(lambda), lambda). Quadratic convergence from a warm start (3-4 steps
// where Brent's method takes 8-15). Every iterate's t_e is a lower bound of t*, so it is as
// safe as the search it replaces; it gives up (edge = true: the caller runs Brent's method)
// when a step would not climb (phi' >= 0), leaves s0 +- 2, or does not settle in 8 steps.
// `t_first` receives t_e at s0 (the first iterate: the caller's fallback starts there).
Refined newton_refine(const PairSweep& p, double s0, double stop_above, double& t_first) noexcept {
  double s = s0;
  double t_best = -kNever, s_best = s0;
  t_first = -kNever;
  for (int it = 0; it < 8; ++it) {
    const double lam = lambda_of(s);
    const double w = lam * (1.0 - lam), w1 = 1.0 - 2.0 * lam;
    double inv[3], qa = 0, qb = 0, qc = 0;
    for (int j = 0; j < 3; ++j) {
      inv[j] = 1.0 / (lam * p.a2[j] + (1.0 - lam) * p.r2);
      qa += p.ug[j] * p.ug[j] * inv[j];
      qb += p.ug[j] * p.dg[j] * inv[j];
      qc += p.dg[j] * p.dg[j] * inv[j];
    }
    const double t = entry_time({qa, -2 * qb, qc - 1.0 / w});
    if (it == 0) t_first = t;
    if (t > stop_above) return Refined{t, s, true};
    if (!std::isfinite(t)) break;
    if (t > t_best) t_best = t, s_best = s;
    double f_l = w1 / (w * w), f_ll = -2.0 * (w + w1 * w1) / (w * w * w), f_t = 0, f_lt = 0;
    for (int j = 0; j < 3; ++j) {
      const double e = p.dg[j] - t * p.ug[j], m1 = p.a2[j] - p.r2;
      const double ei = e * inv[j], mi = m1 * inv[j];
      f_l -= ei * ei * m1;
      f_ll += 2.0 * ei * ei * mi * m1;  // e^2 m'^2 / m^3
      f_t -= 2.0 * p.ug[j] * ei;
      f_lt += 2.0 * ei * p.ug[j] * mi;  // e ug m' / m^2
    }
    if (!(f_t < 0)) break;  // not entering: no entry-time derivative
    const double dt_dl = -f_l / f_t;
    const double phi1 = f_ll + f_lt * dt_dl;
    if (!(phi1 < 0)) break;
    double ds = -f_l / (phi1 * w);
    if (!std::isfinite(ds)) break;
    // The step's gain on the local quadratic model, 0.5 (dt/ds) ds: under 1e-13 of the motion,
    // t is the maximum to that accuracy (one step fewer than waiting for the step to vanish).
    if (std::fabs(ds) < 1e-9 || 0.5 * std::fabs(dt_dl * w * ds) < 1e-13) return Refined{t_best, s_best, false, false};
    ds = std::clamp(ds, -1.0, 1.0);
    s += ds;
    if (std::fabs(s - s0) > 2.0 || std::fabs(s) > 16.0) break;
  }
  return Refined{t_best, s_best, false, true};
}

}  // namespace

double sweep_time(const CollisionGaussian& g, const ToolEllipsoid& tool, const Eigen::Vector3d& motion,
                  Eigen::Vector3d* normal, double stop_above, double* s_io) noexcept {
  const Eigen::Vector3d cg(g.center[0], g.center[1], g.center[2]);
  const Eigen::Vector3d d0 = cg - tool.center;
  const Eigen::Vector3d& b = tool.semi_axes;
  const Eigen::Matrix3d Rg = rotation_matrix(g);
  const Eigen::Vector3d a(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
  const PairSweep p = pair_frame(d0, Rg, a, tool, motion);
  double best_s = 0, best_t = -kNever;
  // Warm start: the caller's s (this Gaussian's maximiser at the last sweep, which moves little
  // from tick to tick) is evaluated first, then refined on +-2; a maximum at the bracket's edge
  // falls back to the full scan below. Any s gives a lower bound of t*, so a stale start can only
  // cost evaluations, never report a later contact.
  if (s_io != nullptr && std::isfinite(*s_io)) {
    const double s0 = std::clamp(*s_io, -16.0, 16.0);
    double t0;  // (t_e at s0: Newton's first iterate, which also stops the search when it is past stop_above)
    const Refined nr = newton_refine(p, s0, stop_above, t0);
    if (nr.stop) return nr.t;
    if (!nr.edge) {
      best_t = nr.t, best_s = nr.s;
    } else {
      const Refined r = brent_refine(p, s0, t0, 2.0, stop_above);
      if (r.stop) return r.t;
      if (!r.edge) best_t = r.t, best_s = r.s;
    }
  }
  if (best_t == -kNever) {
    // Coarse scan of s = ln(lambda / (1 - lambda)) over [-16, 16] in steps of 4, then Brent's
    // method around the best point. Every evaluation is a lower bound of t*, so it may stop as
    // soon as one says "never" or "later than stop_above".
    // From the middle outward: lambda = 1/2 is usually near the maximum, so a Gaussian that
    // cannot be the first contact is dismissed after one or two evaluations.
    for (int i = 0; i <= 8; ++i) {
      const double s = 4.0 * ((i + 1) / 2) * (i % 2 ? 1 : -1);
      const double t = entry_time(p.at(lambda_of(s)));
      if (t > stop_above) return t;
      if (t > best_t) best_t = t, best_s = s;
    }
    const Refined r = brent_refine(p, best_s, best_t, 4.0, stop_above);
    if (r.stop) return r.t;
    if (r.t > best_t) best_t = r.t, best_s = r.s;
  }
  if (best_t <= 0) {
    // The searches say the pair touches at the start. Where the two are a hair apart, the members
    // whose E_lambda leaves the start outside form a narrow window of lambda that the scan's steps
    // and a warm start's Newton steps can miss (a cached start once reported a contact at t = 0
    // for a part 0.09 mm from a Gaussian, moving off it). The static test decides: K(lambda) =
    // 1 - lambda (1 - lambda) d^T M d is convex (Gilitschenski & Hanebeck; k_min.h), and the
    // start lies outside the member minimising it iff the pair is apart; then that member's entry
    // time (later, or never) is the better bound, refined as any other. This runs on 34 of
    // 287,000 calls on the stylus's fidelity-cube bench set.
    // (k_min: bracketed Newton steps on K'; the same lambda as the family's here, weighing the
    // Gaussian's shape.)
    const double lam = std::clamp(
        k_min(pair_coefficients(d0, Rg, a, tool.rotation.normalized().toRotationMatrix(), b)).lambda, 1e-12,
        1.0 - 1e-12);
    const double t = entry_time(p.at(lam));
    if (t > stop_above) return t;
    if (t > best_t) {
      best_t = t, best_s = std::log(lam / (1.0 - lam));
      const Refined r = brent_refine(p, best_s, best_t, 2.0, stop_above);
      if (r.stop) return r.t;
      if (r.t > best_t) best_t = r.t, best_s = r.s;
    }
  }
  if (s_io != nullptr) *s_io = best_s;
  const double t_star = std::max(0.0, best_t);
  Eigen::Vector3d md;
  (void)p.at(lambda_of(best_s), &md, t_star);
  const double len = md.norm();
  const Eigen::Vector3d n = len > 0 ? Eigen::Vector3d(-md / len) : Eigen::Vector3d(-motion.normalized());
  // Touching (or overlapping by rounding) at the start and moving away or along the surface:
  // this Gaussian does not block the motion.
  if (best_t <= 0 && motion.dot(n) >= 0) return kNever;
  if (normal != nullptr) *normal = n;
  return t_star;
}

SweepQuery::SweepQuery(const CollisionWorld& world, std::size_t max_candidates, double reuse_margin)
    : world_(&world),
      scratch_(std::max<std::size_t>(1, max_candidates)),
      reuse_margin_(std::isfinite(reuse_margin) ? std::max(0.0, reuse_margin) : 0.0) {
  if (reuse_margin_ > 0) {
    near_slot_.resize(kMaxParts * kNearCapacity);
    near_clear_.resize(kMaxParts * kNearCapacity);
    near_tmp_slot_.resize(kNearCapacity);
    near_tmp_clear_.resize(kNearCapacity);
  }
}

SweepHit SweepQuery::first_contact(const ToolEllipsoid& tool, const Eigen::Vector3d& motion,
                                   std::span<const std::uint32_t> ignore,
                                   std::span<const std::uint32_t> hints, BlockFilter filter,
                                   double limit, double tolerance) noexcept {
  return first_contact(std::span<const ToolEllipsoid>(&tool, 1), motion, ignore, hints, filter, limit, tolerance);
}

SweepHit SweepQuery::first_contact(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& motion,
                                   std::span<const std::uint32_t> ignore,
                                   std::span<const std::uint32_t> hints, BlockFilter filter,
                                   double limit, double tolerance) noexcept {
  SweepHit hit;
  sweep_parts(parts, motion, ignore, hints, filter, limit, tolerance, true, {&hit, 1});
  return hit;
}

void SweepQuery::first_contacts(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& motion,
                                std::span<SweepHit> hits, std::span<const std::uint32_t> hints,
                                BlockFilter filter, double tolerance) noexcept {
  for (SweepHit& h : hits) h = {};
  if (hits.size() < parts.size()) return;
  sweep_parts(parts, motion, {}, hints, filter, 1.0, tolerance, false, hits);
}

void SweepQuery::build_near(std::uint32_t p, const ToolEllipsoid& tool, const Eigen::Vector3d& axis, double half_len,
                            double rho, const Eigen::Vector3d& half) noexcept {
  NearList& nl = near_[p];
  nl.valid = false;
  nl.c0 = tool.center;
  nl.axis = axis;
  nl.half_len = half_len;
  nl.rotation = tool.rotation;
  nl.semi_axes = tool.semi_axes;
  nl.rho = rho;
  for (int k = 0; k < 3; ++k) {
    nl.lo[k] = round_down_to_float(tool.center[k] - half[k] - reuse_margin_);
    nl.hi[k] = round_up_to_float(tool.center[k] + half[k] + reuse_margin_);
  }
  // An entry with more clearance than this never passes (a sweep moves the core by at most
  // twice the margin, or takes the BVH).
  const double keep = (rho + 2 * reuse_margin_) * (1 + 1e-9);  // (the largest limit a sweep uses)
  // Gathered here, then sorted into the part's list by clearance bucket (a counting sort): a
  // sweep reads only the buckets up to its limit.
  std::uint32_t* tmp_slot = near_tmp_slot_.data();
  float* tmp_clear = near_tmp_clear_.data();
  std::array<std::uint8_t, kNearCapacity>& tmp_bucket = near_tmp_bucket_;
  std::array<std::uint32_t, kNearBuckets + 1> start{};
  const double width = 2 * reuse_margin_ / (kNearBuckets - 1);
  nl.width = width;  // (bucket_of)
  const CollisionGaussian* gs = world_->gaussians().data();
  std::uint32_t n = 0;
  bool full = false;
  world_->bvh().for_each_overlapping_leaf_node(nl.lo, nl.hi, [&](const BvhNode& leaf) {
    for (std::uint32_t k = leaf.first; k < leaf.first + leaf.count; ++k) {
      const CollisionGaussian& g = gs[k];
      const float gr = g.bounding_radius();
      bool out = false;
      for (int j = 0; j < 3; ++j) out = out || g.center[j] + gr < nl.lo[j] || g.center[j] - gr > nl.hi[j];
      if (out) continue;
      // Its clearance from the core: v runs from the core's nearest point to its centre; the
      // distance to the segment is convex with gradient v / |v| there, so no point of the
      // Gaussian is nearer the core than |v| - h, h its support along v (beyond_reach).
      const Eigen::Vector3d v = nl.from_core(nl.c0, g.center);
      const double d2 = v.squaredNorm();
      double c = -kNever;
      if (d2 > 0) {
        const double d = std::sqrt(d2), h = std::sqrt(support_sq(rotation_matrix(g), g.semi_axes, v)) / d;
        c = d - h - 1e-9 * (d + h);  // (a rounding's margin, inward)
      }
      if (c > keep) continue;
      if (n == kNearCapacity) {
        full = true;
        return false;
      }
      tmp_slot[n] = k;
      tmp_clear[n] = round_down_to_float(c);
      const auto b = std::uint8_t(nl.bucket_of(c));
      tmp_bucket[n] = b;
      ++start[b + 1u];
      ++n;
    }
    return true;
  });
  for (std::size_t b = 0; b < kNearBuckets; ++b) start[b + 1] += start[b];
  nl.bucket_end = {};
  for (std::size_t b = 0; b < kNearBuckets; ++b) nl.bucket_end[b] = start[b + 1];
  std::uint32_t* slot = near_slot_.data() + std::size_t(p) * kNearCapacity;
  float* clear = near_clear_.data() + std::size_t(p) * kNearCapacity;
  if (!full)
    for (std::uint32_t i = 0; i < n; ++i) {
      const std::uint32_t at = start[tmp_bucket[i]]++;
      slot[at] = tmp_slot[i];
      clear[at] = tmp_clear[i];
    }
  nl.valid = !full;
  // (After each overflow in a row, twice as long.)
  nl.overflows = full ? std::min<std::uint32_t>(nl.overflows + 1, 12) : 0;
  nl.backoff = full ? kNearBackoff << (nl.overflows - 1) : 0;
}

// One call of sweep_parts: its state and its stages, in the order run() takes them. (The stages
// were lambdas of one 340-line function; as members they read the same state.)
struct SweepQuery::PartsSweep {
  SweepQuery& sq;
  std::span<const ToolEllipsoid> parts;
  const Eigen::Vector3d& motion;
  std::span<const std::uint32_t> ignore;
  BlockFilter filter;
  bool shared;
  std::span<SweepHit> hits;
  double len2 = 0, len = 0, tol = 0;
  Eigen::Vector3d m_hat = Eigen::Vector3d::Zero();
  // What a Gaussian must beat to count: the limit until a contact is found, then that contact
  // less the tolerance (a near-tie is not searched to the end). One bar for all parts (the
  // earliest contact of the rigid tool), or one a part (each part's own first contact).
  std::array<double, kMaxParts> bars{};
  // Each part's bounds' constants and swept box; the BVH is traversed once, over the union of
  // the boxes (lo, hi).
  std::array<PartBounds, kMaxParts> pd;
  std::array<Capsule, kMaxParts> caps;
  std::array<FlatSlab, kMaxParts> flats;
  float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  bool several = false;
  const CollisionGaussian* gs = nullptr;
  std::size_t n = 0;  // candidates in sq.scratch_
  std::array<double, kMaxParts> near_limit{};

  PartsSweep(SweepQuery& query, std::span<const ToolEllipsoid> tool_parts, const Eigen::Vector3d& tool_motion,
             std::span<const std::uint32_t> ignored_slots, BlockFilter block_filter, bool one_bar,
             std::span<SweepHit> out) noexcept
      : sq(query), parts(tool_parts), motion(tool_motion), ignore(ignored_slots), filter(block_filter),
        shared(one_bar), hits(out) {}
  double& bar_of(std::uint32_t p) noexcept { return bars[shared ? 0 : p]; }
  // This Gaussian's maximiser from its last exact search against this part (a direct-mapped
  // cache) starts it; one part keys by the slot alone.
  static std::size_t cache_slot(std::uint32_t k, std::uint32_t p) noexcept { return (k + 977u * p) % kStartCache; }
  bool ignored(std::uint32_t k) const noexcept {
    bool out = false;
    for (std::uint32_t s : ignore) out = out || s == k;
    return out;
  }

  bool set_up(double limit, double tolerance) noexcept;
  void sweep_boxes() noexcept;
  void exact(std::uint32_t k, std::uint32_t p) noexcept;
  [[gnu::always_inline]] double lower_bound(std::uint32_t k, std::uint32_t p) noexcept;
  [[gnu::always_inline]] double sphere_member_bound(const CollisionGaussian& g, const PartBounds& q,
                                                    const Eigen::Vector3d& rel, const Eigen::Matrix3d& R,
                                                    std::uint32_t k, std::uint32_t p, double bar) noexcept;
  [[gnu::always_inline]] double ellipsoid_member_bound(const CollisionGaussian& g, const PartBounds& q,
                                                       const Eigen::Vector3d& rel, const Eigen::Matrix3d& R,
                                                       std::uint32_t k, std::uint32_t p, double bar) noexcept;
  void consider(std::uint32_t k, std::uint32_t p) noexcept;
  void test_hints(std::span<const std::uint32_t> hints) noexcept;
  std::uint32_t settled_parts() noexcept;
  std::uint32_t serve_near_lists(std::span<const std::uint32_t> hints, std::uint32_t settled) noexcept;
  void traverse_bvh(std::uint32_t skip) noexcept;
  void scan_near_lists(std::uint32_t served) noexcept;
  void test_sorted() noexcept;
};

// Validates the call and fills each part's constants; false: nothing to search (no hit).
bool SweepQuery::PartsSweep::set_up(double limit, double tolerance) noexcept {
  len2 = motion.squaredNorm();
  if (parts.empty() || parts.size() > kMaxParts || !motion.allFinite() || !(len2 > 0) || !(limit > 0)) return false;
  for (const ToolEllipsoid& tool : parts)
    if (!tool.valid()) return false;
  tol = std::isfinite(tolerance) ? std::max(0.0, tolerance) : 0.0;
  bars.fill(std::min(limit, 1.0));
  len = std::sqrt(len2);
  m_hat = motion / len;
  for (std::size_t p = 0; p < parts.size(); ++p) pd[p].set(parts[p], motion, m_hat, caps[p], flats[p]);
  several = parts.size() > 1;
  gs = sq.world_->gaussians().data();
  return true;
}

// Each part's box swept up to its bar (nothing later counts), and their union.
void SweepQuery::PartsSweep::sweep_boxes() noexcept {
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const ToolEllipsoid& tool = parts[p];
    PartBounds& q = pd[p];
    const Eigen::Vector3d c1 = tool.center + motion * std::max(0.0, bar_of(std::uint32_t(p)));
    const Eigen::Vector3d& h = q.half;
    for (int k = 0; k < 3; ++k) {
      q.lo[k] = round_down_to_float(std::min(tool.center[k], c1[k]) - h[k]);
      q.hi[k] = round_up_to_float(std::max(tool.center[k], c1[k]) + h[k]);
      lo[k] = p == 0 ? q.lo[k] : std::min(lo[k], q.lo[k]);
      hi[k] = p == 0 ? q.hi[k] : std::max(hi[k], q.hi[k]);
    }
  }
}

// The exact search of Gaussian k against part p; a contact before the bar lowers it.
void SweepQuery::PartsSweep::exact(std::uint32_t k, std::uint32_t p) noexcept {
  if (filter.known_to_pass != nullptr && filter.known_to_pass(filter.context, k)) return;
  Eigen::Vector3d nrm;
  ++sq.counts_.exact;
  const std::size_t slot_h = cache_slot(k, p);
  const bool cached = sq.start_slot_[slot_h] == k && sq.start_part_[slot_h] == p;
  double s_start = cached ? double(sq.start_s_[slot_h]) : std::numeric_limits<double>::quiet_NaN();
  double& bar = bar_of(p);
  const double t = sweep_time(gs[k], parts[p], motion, &nrm, bar, &s_start);
  if (std::isfinite(s_start)) {
    sq.start_slot_[slot_h] = k;
    sq.start_part_[slot_h] = std::uint8_t(p);
    sq.start_s_[slot_h] = float(s_start);
    sq.start_lambda_[slot_h] = lambda_of(double(sq.start_s_[slot_h]));
  }
  if (t <= bar && filter.blocks != nullptr && !filter.blocks(filter.context, k)) {
    ++sq.counts_.passed;  // reached first, but let through: it prunes nothing
    return;
  }
  if (t <= bar) {
    bar = t - tol;
    hits[shared ? 0 : p] = {true, t, k, nrm, int(p)};
  }
}

// Bounds of one candidate against one part: the earliest fraction of the motion at which they
// could touch (kNever: not within the motion or past the bar). Forced inline: it has two call
// sites, and as a call the candidates' loop ran 5-10 % slower.
inline double SweepQuery::PartsSweep::lower_bound(std::uint32_t k, std::uint32_t p) noexcept {
  const CollisionGaussian& g = gs[k];
  const PartBounds& q = pd[p];
  if (several) {
    // The part's own swept box first (the traversal's box is the union of the parts').
    const float gr = g.bounding_radius();
    for (int j = 0; j < 3; ++j)
      if (g.center[j] + gr < q.lo[j] || g.center[j] - gr > q.hi[j]) return kNever;
  }
  const Eigen::Vector3d rel = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]) - q.c0;
  const double reach = double(g.bounding_radius()) + q.r_tool;
  // Bounding spheres: the earliest the two could touch along the path (capsule test).
  const double bq = rel.dot(motion), cq = rel.squaredNorm() - reach * reach;
  double t_lb;
  if (cq <= 0) {
    t_lb = 0;
  } else {
    const double disc = bq * bq - len2 * cq;
    if (disc < 0 || bq <= 0) return kNever;
    t_lb = (bq - std::sqrt(disc)) / len2;
    if (t_lb > 1.0) return kNever;
  }
  if (q.capsule) {
    // (Before the rotation's and the slab's arithmetic: beside a stylus lying on a layer it
    // rules out most of the part's bounding sphere.)
    const double t_cap = caps[p].entry_time(rel, double(g.bounding_radius()));
    if (t_cap > bar_of(p)) return kNever;
    t_lb = std::max(t_lb, t_cap);
  }
  // Slab bound along the motion: the ellipsoid's extent along it is sqrt(sum (a_j m.R_j)^2),
  // tight for flat Gaussians met face-on, where the sphere bound is loose.
  const Eigen::Matrix3d R = rotation_matrix(g);
  if (q.capsule && caps[p].clear_until(rel, R, g.semi_axes, bar_of(p))) return kNever;
  t_lb = std::max(t_lb, (rel.dot(m_hat) - std::sqrt(support_sq(R, g.semi_axes, m_hat)) - q.h_tool) / len);
  const double bar = bar_of(p);
  if (t_lb > bar) return t_lb;
  const double te = q.spherical ? sphere_member_bound(g, q, rel, R, k, p, bar)
                                : ellipsoid_member_bound(g, q, rel, R, k, p, bar);
  return te == kNever ? kNever : std::max(t_lb, te);
}

// Members of the family for a spherical part: each one's entry time is a lower bound of the
// exact one, far tighter than the spheres and slabs for the Gaussians beside a sliding tool.
// First the member exact along the offset's direction (geometric_lambda; lambda = 1/2, the
// bound used before, is loose by 40 % of the tool radius for a disc under the tool), then, for a
// Gaussian searched before, its maximiser at that search (then the bound is close to the
// contact time itself, and the candidates sort nearly as the exact search would order them).
// Computed here, they spare most candidates the exact search. kNever: out of reach.
inline double SweepQuery::PartsSweep::sphere_member_bound(const CollisionGaussian& g, const PartBounds& q,
                                                   const Eigen::Vector3d& rel, const Eigen::Matrix3d& R,
                                                   std::uint32_t k, std::uint32_t p, double bar) noexcept {
  // Support toward the tool's centre: no point of the Gaussian is nearer it than |rel| -
  // h(rel / |rel|), and the centre moves by at most bar |motion| (the capsule's test for a
  // point axis).
  if (beyond_reach(rel, q.r_tool * (1 + 1e-9) + std::max(0.0, bar) * len * (1 + 1e-9), R, g.semi_axes))
    return kNever;
  const std::size_t hs = cache_slot(k, p);
  double dg[3], ug[3];
  for (int j = 0; j < 3; ++j) {
    dg[j] = R(0, j) * rel[0] + R(1, j) * rel[1] + R(2, j) * rel[2];
    ug[j] = R(0, j) * motion[0] + R(1, j) * motion[1] + R(2, j) * motion[2];
  }
  const auto member = [&](double lam) {
    const double w_inv = 1.0 / (lam * (1.0 - lam));
    double qa = 0, qb = 0, qc = 0;
    for (int j = 0; j < 3; ++j) {
      const double inv = 1.0 / (lam * (double(g.semi_axes[j]) * g.semi_axes[j]) + (1.0 - lam) * q.r2_tool);
      qa += ug[j] * ug[j] * inv;
      qb += ug[j] * dg[j] * inv;
      qc += dg[j] * dg[j] * inv;
    }
    return entry_time({qa, -2 * qb, qc - w_inv});
  };
  double te = member(geometric_lambda(g, dg, q.r_tool));
  if (te <= bar && sq.start_slot_[hs] == k && sq.start_part_[hs] == p) te = std::max(te, member(sq.start_lambda_[hs]));
  if (te > 1.0) return kNever;
  return te - 1e-12;  // (a rounding's margin below the exact search's value)
}

// The same members for an ellipsoidal part, in the world frame: the member lambda is
// {x : x^T K^-1 x <= 1 / (lambda (1 - lambda))} with K = lambda Sigma_g + (1 - lambda) Sigma_t,
// the form the exact search reads in its whitened frame (the quadratic forms are
// frame-invariant), here through K's adjugate: no eigendecomposition. Its lambda: the geometric
// one with the part's radius along the offset, |d| / |W d|, or this Gaussian's maximiser at its
// last search against this part. A flat part's slab bound comes first. kNever: out of reach.
inline double SweepQuery::PartsSweep::ellipsoid_member_bound(const CollisionGaussian& g, const PartBounds& q,
                                                      const Eigen::Vector3d& rel, const Eigen::Matrix3d& R,
                                                      std::uint32_t k, std::uint32_t p, double bar) noexcept {
  double t_flat = -kNever;
  if (q.flat) {
    t_flat = flats[p].entry_time(rel, R, g.semi_axes);
    if (t_flat > 1.0) return kNever;
  }
  // A separating axis along the centres' direction n: the Gaussian reaches h_g(n) toward the part
  // and the part h_t(n) = |diag(b) R_t^T n| toward it, and the gap between them closes at most at
  // n.motion. Under the sharp tip of an upright stylus part (curvature radius b^2 / a) the
  // capsule's round end lets through every Gaussian within about b of the tip; this keeps those
  // under the tip itself.
  double t_sep = -kNever;
  if (const double d = rel.norm(); d > 0) {
    const Eigen::Vector3d nv = rel / d;
    const double gap = d - (std::sqrt(support_sq(R, g.semi_axes, nv)) + (q.bt * nv).norm()) * (1 + 1e-9) - 1e-12 * d;
    if (gap > 0) {
      const double closing = nv.dot(motion);
      if (!(closing > 0)) return kNever;
      t_sep = gap / closing;
      if (t_sep > 1.0) return kNever;
      if (t_sep > bar) return t_sep;
    }
  }
  double sg[6] = {0, 0, 0, 0, 0, 0};
  for (int j = 0; j < 3; ++j) {
    const double a2 = double(g.semi_axes[j]) * g.semi_axes[j];
    const double x = R(0, j), y = R(1, j), z = R(2, j);
    sg[0] += a2 * x * x, sg[1] += a2 * y * y, sg[2] += a2 * z * z;
    sg[3] += a2 * x * y, sg[4] += a2 * x * z, sg[5] += a2 * y * z;
  }
  const auto member = [&](double lam) {
    double km[6];
    for (int j = 0; j < 6; ++j) km[j] = lam * sg[j] + (1.0 - lam) * q.st[j];
    // Adjugate of [[k0 k3 k4] [k3 k1 k5] [k4 k5 k2]].
    const double c00 = km[1] * km[2] - km[5] * km[5], c11 = km[0] * km[2] - km[4] * km[4],
                 c22 = km[0] * km[1] - km[3] * km[3], c01 = km[4] * km[5] - km[3] * km[2],
                 c02 = km[3] * km[5] - km[4] * km[1], c12 = km[3] * km[4] - km[0] * km[5];
    const double det = km[0] * c00 + km[3] * c01 + km[4] * c02;
    if (!(det > 0)) return -kNever;  // (degenerate: no bound)
    const auto form = [&](const double* x, const double* y) {
      return x[0] * (c00 * y[0] + c01 * y[1] + c02 * y[2]) + x[1] * (c01 * y[0] + c11 * y[1] + c12 * y[2]) +
             x[2] * (c02 * y[0] + c12 * y[1] + c22 * y[2]);
    };
    const double d[3] = {rel[0], rel[1], rel[2]}, u[3] = {motion[0], motion[1], motion[2]};
    const double inv_det = 1.0 / det;
    return entry_time({form(u, u) * inv_det, -2 * form(u, d) * inv_det,
                       form(d, d) * inv_det - 1.0 / (lam * (1.0 - lam))});
  };
  double dl[3];
  for (int j = 0; j < 3; ++j) dl[j] = R(0, j) * rel[0] + R(1, j) * rel[1] + R(2, j) * rel[2];
  const double wd = (q.w * rel).norm();
  const double r_dir = wd > 0 ? rel.norm() / wd : q.r_tool;
  const std::size_t hs = cache_slot(k, p);
  double te = member(geometric_lambda(g, dl, r_dir));
  if (te <= bar && sq.start_slot_[hs] == k && sq.start_part_[hs] == p) te = std::max(te, member(sq.start_lambda_[hs]));
  if (te > 1.0) return kNever;
  // (The exact search reads the same forms in another frame: a wider margin for its rounding.)
  return std::max({t_flat, t_sep, te - 1e-9});
}

// A candidate whose bound is within its part's bar goes to the sorted list (or, past its
// capacity, to an exact test now). The bar only falls and the candidates are tested in bound
// order up to it: one whose bound is past it (the best contact so far, from the hints) is never
// tested.
void SweepQuery::PartsSweep::consider(std::uint32_t k, std::uint32_t p) noexcept {
  const double t_lb = lower_bound(k, p);
  if (t_lb > bar_of(p)) return;
  if (ignored(k)) return;
  ++sq.counts_.prefiltered;
  if (n < sq.scratch_.size())
    sq.scratch_[n++] = {t_lb, k, p};
  else if (t_lb <= bar_of(p))
    exact(k, p);
}

// The hints first (the last tick's blockers, usually the first contact again): their exact
// searches set the bar that prunes the rest. For a compound tool, only against the parts the
// hint's bounds do not rule out (each hint is usually one part's blocker, out of the others'
// reach).
void SweepQuery::PartsSweep::test_hints(std::span<const std::uint32_t> hints) noexcept {
  for (std::uint32_t hint : hints)
    if (!ignored(hint) && hint < sq.world_->size())
      for (std::uint32_t p = 0; p < parts.size(); ++p)
        if (!several || lower_bound(hint, p) <= bar_of(p)) exact(hint, p);
}

// A part whose bar fell below 0 (a hint within the tolerance of the start) is settled: every
// lower bound and every exact search's contact is >= 0, so no other Gaussian can beat it, and
// its candidates are not looked at (the same answer; on the 8 mm cube a third of the
// candidates' bounds were of such parts).
std::uint32_t SweepQuery::PartsSweep::settled_parts() noexcept {
  std::uint32_t settled = 0;
  for (std::uint32_t p = 0; p < parts.size(); ++p)
    if (bar_of(p) < 0) settled |= 1u << p;
  return settled;
}

// The parts served by their near lists (reuse_margin_), each with the clearance up to which an
// entry can still touch it in this sweep (near_limit); returns their bits.
std::uint32_t SweepQuery::PartsSweep::serve_near_lists(std::span<const std::uint32_t> hints,
                                                       std::uint32_t settled) noexcept {
  std::uint32_t served = 0;
  if (!(sq.reuse_margin_ > 0)) return served;
  const double margin = sq.reuse_margin_;
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const ToolEllipsoid& tool = parts[p];
    const PartBounds& q = pd[p];
    if ((settled >> p) & 1u) continue;
    NearList& nl = sq.near_[p];
    const double bar_p = std::max(0.0, bar_of(std::uint32_t(p)));
    bool fits = nl.valid && nl.rotation.coeffs() == tool.rotation.coeffs() && nl.semi_axes == tool.semi_axes;
    for (int k = 0; k < 3 && fits; ++k) fits = q.lo[k] >= nl.lo[k] && q.hi[k] <= nl.hi[k];
    // (A list is rebuilt once the part has drifted a quarter margin from where it was built:
    // each sweep reads the entries up to its drift more, whose bounds rule out most of them.)
    fits = fits && (tool.center - nl.c0).norm() <= kNearDrift * margin;
    // (Built only for a sweep with hints: a tool that touched at its last sweep. One that moves
    // free would rebuild as often as it crosses a margin, for sweeps the BVH serves cheaply.)
    // A list that overflowed (a large part in a dense scene) is not tried again for a while.
    if (!fits && nl.backoff > 0) {
      --nl.backoff;
    } else if (!fits && !hints.empty() && bar_p * len <= 0.5 * margin) {
      // The core: an elongated part's segment of half-length a - b on its long axis (the part
      // lies within b of it, Capsule), any other part's centre (within its largest semi-axis).
      const Eigen::Vector3d& b = tool.semi_axes;
      const double a_long = b.maxCoeff(), b_mid = b.sum() - a_long - b.minCoeff();
      sq.build_near(std::uint32_t(p), tool, q.capsule ? caps[p].axis : Eigen::Vector3d::Zero(),
                    q.capsule ? a_long - b_mid : 0.0, q.capsule ? caps[p].radius : q.r_tool * (1 + 1e-9), q.half);
      ++sq.counts_.rebuilt;
      fits = nl.valid;
    }
    if (!fits) continue;
    // How far the core gets from where the list was built, at most, in this sweep (the
    // distance to it is 1-Lipschitz in its translation).
    const double reach = (tool.center - nl.c0).norm() + bar_p * len;
    if (!(reach <= 2 * margin)) continue;
    served |= 1u << p;
    near_limit[p] = (nl.rho + reach) * (1 + 1e-9);  // (a rounding's margin, outward)
    ++sq.counts_.reused;
  }
  return served;
}

// One traversal over the union of the boxes of the parts not in `skip`; a leaf is read for
// each part whose own box it overlaps (a tilted stylus's union box holds many leaves no part's
// box reaches).
void SweepQuery::PartsSweep::traverse_bvh(std::uint32_t skip) noexcept {
  const auto n_parts = std::uint32_t(parts.size());
  if (skip == (1u << n_parts) - 1) return;
  if (skip != 0) {
    bool first = true;
    for (std::uint32_t p = 0; p < n_parts; ++p) {
      if ((skip >> p) & 1u) continue;
      for (int k = 0; k < 3; ++k) {
        lo[k] = first ? pd[p].lo[k] : std::min(lo[k], pd[p].lo[k]);
        hi[k] = first ? pd[p].hi[k] : std::max(hi[k], pd[p].hi[k]);
      }
      first = false;
    }
  }
  sq.world_->bvh().for_each_overlapping_leaf_node(lo, hi, [&](const BvhNode& leaf) {
    for (std::uint32_t p = 0; p < n_parts; ++p) {
      if ((skip >> p) & 1u) continue;
      const PartBounds& q = pd[p];
      if (several && (leaf.lo[0] > q.hi[0] || leaf.hi[0] < q.lo[0] || leaf.lo[1] > q.hi[1] || leaf.hi[1] < q.lo[1] ||
                      leaf.lo[2] > q.hi[2] || leaf.hi[2] < q.lo[2]))
        continue;
      if ((q.capsule || q.flat) && !leaf_within_reach(leaf, q, caps[p], flats[p], bar_of(p))) continue;
      if (q.spherical && !leaf_near_sphere_path(leaf, q, motion, bar_of(p))) continue;
      sq.counts_.candidates += leaf.count;
      for (std::uint32_t k = leaf.first; k < leaf.first + leaf.count; ++k) consider(k, p);
    }
    return true;
  });
}

// The served parts' near lists: an entry whose clearance rules it out is passed over; the
// others are the BVH's candidates (the part's own swept box, then the same bounds).
void SweepQuery::PartsSweep::scan_near_lists(std::uint32_t served) noexcept {
  for (std::uint32_t p = 0; p < parts.size(); ++p) {
    if (!((served >> p) & 1u)) continue;
    const PartBounds& q = pd[p];
    const float* clear = sq.near_clear_.data() + std::size_t(p) * kNearCapacity;
    const std::uint32_t* slot = sq.near_slot_.data() + std::size_t(p) * kNearCapacity;
    const double limit_p = near_limit[p];
    // The buckets up to the limit's (bucket j holds clearances up to rho + j x width).
    const NearList& nl = sq.near_[p];
    const std::size_t last = nl.bucket_of(limit_p);
    // The entry's clearance from the core where it is now, against the part's radius plus this
    // sweep's motion (no drift): what the list's clearance leaves through for the drift, this
    // rules out before the candidates' bounds (under a resting stylus, most of them).
    const Eigen::Vector3d& c_now = parts[p].center;
    const double reach_now = nl.rho * (1 + 1e-9) + std::max(0.0, bar_of(p)) * len * (1 + 1e-9);
    for (std::uint32_t i = 0, n_near = nl.bucket_end[last]; i < n_near; ++i) {
      if (double(clear[i]) > limit_p) continue;
      const std::uint32_t k = slot[i];
      const CollisionGaussian& g = gs[k];
      if (!several) {  // (the compound sweep's bounds check the part's own box)
        const float gr = g.bounding_radius();
        bool out = false;
        for (int j = 0; j < 3; ++j) out = out || g.center[j] + gr < q.lo[j] || g.center[j] - gr > q.hi[j];
        if (out) continue;
      }
      const Eigen::Vector3d v = nl.from_core(c_now, g.center);
      if (beyond_reach(v, reach_now, rotation_matrix(g), g.semi_axes)) continue;
      ++sq.counts_.candidates;
      consider(k, p);
    }
  }
}

// The candidates in bound order, each searched exactly while its bound is within its part's bar.
void SweepQuery::PartsSweep::test_sorted() noexcept {
  std::sort(sq.scratch_.begin(), sq.scratch_.begin() + std::ptrdiff_t(n),
            [](const Candidate& a, const Candidate& b) {
              return a.t < b.t || (a.t == b.t && (a.slot < b.slot || (a.slot == b.slot && a.part < b.part)));
            });
  for (std::size_t i = 0; i < n; ++i) {
    const Candidate& c = sq.scratch_[i];
    if (c.t <= bar_of(c.part))
      exact(c.slot, c.part);
    else if (shared)
      break;  // (one bar: the rest come later still)
  }
}

void SweepQuery::sweep_parts(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& motion,
                             std::span<const std::uint32_t> ignore, std::span<const std::uint32_t> hints,
                             BlockFilter filter, double limit, double tolerance, bool shared,
                             std::span<SweepHit> hits) noexcept {
  counts_ = {};
  PartsSweep s(*this, parts, motion, ignore, filter, shared, hits);
  if (!s.set_up(limit, tolerance)) return;
  if (s.several) s.sweep_boxes();  // (the hints' bounds check each part's box; one part's is swept below)
  s.test_hints(hints);
  // A hint that holds the tool (a resting contact: the bar near 0) leaves only the boxes swept
  // up to it to traverse.
  s.sweep_boxes();
  const std::uint32_t settled = s.settled_parts();
  const std::uint32_t served = s.serve_near_lists(hints, settled);
  s.traverse_bvh(served | settled);
  s.scan_near_lists(served);
  s.test_sorted();
}

}  // namespace gshaptics
