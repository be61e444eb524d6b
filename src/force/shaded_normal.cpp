#include "gshaptics/force/shaded_normal.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <Eigen/Cholesky>
#include <memory>
#include <vector>

#include "gshaptics/broadphase/bvh.h"
#include "gshaptics/force/lane_exp.h"
#include "gshaptics/narrowphase/k_min_batch.h"

// The sum is computed in lanes: the Gaussians a reading visits are gathered kLanes at a time
// into a structure of arrays and their terms computed by one vectorised loop (term_lanes); the
// terms kept are stored in order, and the two passes over them run kLanes terms at a time,
// each lane keeping its own partial sums, added up in lane order at the end. Term i always goes
// to lane i % kLanes, so the plain call, the call with working memory and a reading spread over
// calls add the same numbers in the same order: their results are bit-identical. (Built with
// -fopenmp-simd, -fno-math-errno and -fno-trapping-math, as the narrow phase's kernel.)

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

constexpr int kLanes = 16;

// min and max by value in the lane loops (std::min/max return references, which turn a select
// into a load through a chosen pointer and keep GCC from vectorising the loop).
inline double lane_min(double a, double b) noexcept { return b < a ? b : a; }
inline double lane_max(double a, double b) noexcept { return a < b ? b : a; }
inline double flag(bool c) noexcept { return c ? 1.0 : 0.0; }

// A term's fields (the parts that do not depend on the outward estimate), one array each.
enum Field : int {
  kAx, kAy, kAz,  // shortest axis turned toward c
  kRx, kRy, kRz,  // unit direction from the nearest rim point to c (the axis when c is not beyond the rim)
  kGx, kGy, kGz,  // R A^-1 d / |A^-1 d|: the density gradient's direction
  kPx, kPy, kPz,  // the Gaussian's centre relative to c (-d)
  kW,             // alpha exp(-q / 2) (times the concave-crease falloff, FreeBall::surface)
  kFlat,          // 1 - a_min / a_mid
  kPast,          // distance past the rim, in kRimFalloff kernel widths (0 when not beyond it)
  kFields
  // (Whether c is beyond a disc's rim needs no field of its own: where it is not, the rim
  // direction is the axis itself and the distance past the rim is 0, so both passes' rim terms
  // vanish exactly: exp(0) = 1, and a rim direction equal to the axis gains nothing.)
};

// kLanes visited Gaussians, gathered.
struct alignas(64) GaussianLanes {
  double dx[kLanes], dy[kLanes], dz[kLanes];  // c - centre
  double qw[kLanes], qx[kLanes], qy[kLanes], qz[kLanes];
  double a0[kLanes], a1[kLanes], a2[kLanes], amax[kLanes], alpha[kLanes];
};

// Their terms, and which are kept.
struct alignas(64) TermLanes {
  double f[kFields][kLanes];
  double keep[kLanes];  // 1: kept, 0: not
};

// What a reading's terms depend on besides the Gaussians.
struct Support {
  double s2 = 0, q_cut = 0, rim = 0;  // kernel width squared, q's cut-off, rim falloff scale
  FreeBall ball;
  std::size_t max_visits = kMaxKernelVisits;  // (sampling_stride)
};

// The terms of kLanes gathered Gaussians at c (which `in` holds as offsets); a padding lane
// must be far (it is then not kept). Branch-free: every lane runs the same vector code. One
// loop an instruction set, picked by the first call (GCC 12 fails on this loop's SSE2
// vectorisation, an internal compiler error, so the baseline loop runs lane by lane).
template <bool kSimd>
[[gnu::always_inline]] inline void term_lanes_loop(const GaussianLanes& in, const Support& sp, TermLanes& out) noexcept {
  const double s2 = sp.s2, q_cut = sp.q_cut, pre = q_cut + 1e-3 * q_cut;
  const double ball_r = sp.ball.radius, ux = sp.ball.up.x(), uy = sp.ball.up.y(), uz = sp.ball.up.z();
  const double ball_lim = ball_r * (1.0 - 1e-3), surface = sp.ball.surface, half_rim = 0.5 * sp.rim;
  const double inv_falloff = 1.0 / (kRimFalloff * sp.rim);
  // (FreeBall::face off: a zero direction and margin, so that every depth term is 0.)
  const bool overhang = surface > 0 && !sp.ball.face.isZero(0);
  const double fx = overhang ? sp.ball.face.x() : 0.0, fy = overhang ? sp.ball.face.y() : 0.0,
               fz = overhang ? sp.ball.face.z() : 0.0;
  const double fin_m = overhang ? kOverhangMargin * surface : 0.0, inv_fin_m = overhang ? 1.0 / fin_m : 0.0;
  const double face_h = overhang ? sp.ball.face_height : 0.0, face_s = overhang ? sp.ball.face_strength : 0.0;
  const auto lane = [&](int l) __attribute__((always_inline)) {
    const double dx = in.dx[l], dy = in.dy[l], dz = in.dz[l];
    const double a0 = in.a0[l], a1 = in.a1[l], a2 = in.a2[l];
    const double d2 = dx * dx + dy * dy + dz * dz;
    const double amin = lane_min(a0, lane_min(a1, a2));
    // FreeBall: a floater beside the resting tool, whose inscribed ball reaches into the tool's.
    const double lim = ball_lim + amin;
    // (Conditions are 0/1 doubles, combined by products: a bool combined with another is a
    // byte, and a byte lane sets the vectorisation factor past the loop's 16 lanes.)
    const double beside =
        flag(ball_r > 0) * flag(dx * ux + dy * uy + dz * uz < kFloaterDepth * ball_r) * flag(d2 < lim * lim);
    // q >= |d|^2 / (a_max^2 + s^2): the pre-filter (its 1e-3 margin keeps rounding from
    // dismissing one the exact q keeps).
    const double am = in.amax[l];
    const double near = flag(d2 <= pre * (am * am + s2));
    double r0, r1, r2, r3, r4, r5, r6, r7, r8;
    rotation_from_quaternion<double>(in.qw[l], in.qx[l], in.qy[l], in.qz[l], r0, r1, r2, r3, r4, r5, r6, r7, r8);
    // In the Gaussian's frame A = diag(a^2 + s^2): q = sum dl^2 / A, A^-1 d = R (dl / A).
    const double l0 = r0 * dx + r3 * dy + r6 * dz, l1 = r1 * dx + r4 * dy + r7 * dz, l2 = r2 * dx + r5 * dy + r8 * dz;
    const double ad0 = l0 / (a0 * a0 + s2), ad1 = l1 / (a1 * a1 + s2), ad2 = l2 / (a2 * a2 + s2);
    const double q = l0 * ad0 + l1 * ad1 + l2 * ad2;
    const double an2 = ad0 * ad0 + ad1 * ad1 + ad2 * ad2;
    out.keep[l] = (1.0 - beside) * near * flag(q <= q_cut) * flag(an2 > 0);
    // The thinnest axis j (the first of equal ones), the middle semi-axis and the flatness.
    const double jd = a2 < (a1 < a0 ? a1 : a0) ? 2.0 : (a1 < a0 ? 1.0 : 0.0);
    const bool j0 = jd == 0.0, j1 = jd == 1.0, j2 = jd == 2.0;
    const double mid = lane_max(lane_min(a0, a1), lane_max(lane_min(a1, a2), lane_min(a0, a2)));
    const double flat = (mid - amin) / lane_max(mid, 1e-300);  // (0 when mid is: a rod or a point states no normal)
    const double ln = j0 ? l0 : (j1 ? l1 : l2);  // offset along the thinnest axis
    const double sgn = ln >= 0 ? 1.0 : -1.0;
    const double ax = sgn * (j0 ? r0 : (j1 ? r1 : r2));
    const double ay = sgn * (j0 ? r3 : (j1 ? r4 : r5));
    const double az = sgn * (j0 ? r6 : (j1 ? r7 : r8));
    // A disc whose plane lies farther from c than the surface under the tool is not under it
    // (FreeBall::surface): the far face of a concave crease.
    const double excess = surface > 0 ? lane_max(0.0, (std::fabs(ln) - surface - half_rim) / half_rim) : 0.0;
    // A disc across the face under the tool whose centre lies behind that face's plane
    // (FreeBall::face): the other face of a convex edge, overhanging it.
    const double across = lane_min(1.0, lane_max(0.0, (kAgree - std::fabs(ax * fx + ay * fy + az * fz)) / kAgree));
    const double deep = lane_max(0.0, (dx * fx + dy * fy + dz * fz - face_h - fin_m) * inv_fin_m);
    const double w = in.alpha[l] * lane_exp(-0.5 * q) *
                     lane_exp(-0.5 * flat * (excess * excess + face_s * across * deep * deep));  // (flat 0: no falloff)
    const double inv_an = 1.0 / std::sqrt(an2 > 0 ? an2 : 1.0);
    // Beyond the rim: the in-plane offset in semi-axes, rho^2 > 1.
    const double e0 = l0 / a0, e1 = l1 / a1, e2 = l2 / a2;
    const double rho2 = (j0 ? 0.0 : e0 * e0) + (j1 ? 0.0 : e1 * e1) + (j2 ? 0.0 : e2 * e2);
    const bool beyond = flag(flat > 0) * flag(rho2 > 1.0) > 0;
    // From the rim point on the ray toward c's projection, to c: the in-plane offset shrunk.
    const double shrink = 1.0 - 1.0 / std::sqrt(rho2 > 1.0 ? rho2 : 1.0);
    const double o0 = j0 ? l0 : l0 * shrink, o1 = j1 ? l1 : l1 * shrink, o2 = j2 ? l2 : l2 * shrink;
    const double wx = r0 * o0 + r1 * o1 + r2 * o2, wy = r3 * o0 + r4 * o1 + r5 * o2, wz = r6 * o0 + r7 * o1 + r8 * o2;
    const double wn = std::sqrt(wx * wx + wy * wy + wz * wz);
    const double inv_wn = 1.0 / (wn > 0 ? wn : 1.0);
    const double past2 = (j0 ? 0.0 : o0 * o0) + (j1 ? 0.0 : o1 * o1) + (j2 ? 0.0 : o2 * o2);
    out.f[kAx][l] = ax, out.f[kAy][l] = ay, out.f[kAz][l] = az;
    out.f[kRx][l] = beyond ? wx * inv_wn : ax;
    out.f[kRy][l] = beyond ? wy * inv_wn : ay;
    out.f[kRz][l] = beyond ? wz * inv_wn : az;
    out.f[kGx][l] = (r0 * ad0 + r1 * ad1 + r2 * ad2) * inv_an;
    out.f[kGy][l] = (r3 * ad0 + r4 * ad1 + r5 * ad2) * inv_an;
    out.f[kGz][l] = (r6 * ad0 + r7 * ad1 + r8 * ad2) * inv_an;
    out.f[kPx][l] = -dx, out.f[kPy][l] = -dy, out.f[kPz][l] = -dz;
    out.f[kW][l] = w;
    out.f[kFlat][l] = flat;
    out.f[kPast][l] = beyond ? std::sqrt(past2) * inv_falloff : 0.0;
  };
  if constexpr (kSimd) {
#pragma omp simd
    for (int l = 0; l < kLanes; ++l) lane(l);
  } else {
    for (int l = 0; l < kLanes; ++l) lane(l);
  }
}
__attribute__((target("avx512f"))) void term_lanes_avx512(const GaussianLanes& in, const Support& sp,
                                                           TermLanes& out) noexcept {
  term_lanes_loop<true>(in, sp, out);
}
__attribute__((target("avx2,fma"))) void term_lanes_avx2(const GaussianLanes& in, const Support& sp,
                                                         TermLanes& out) noexcept {
  term_lanes_loop<true>(in, sp, out);
}
__attribute__((optimize("no-tree-vectorize"))) void term_lanes_base(const GaussianLanes& in, const Support& sp,
                                                                     TermLanes& out) noexcept {
  term_lanes_loop<false>(in, sp, out);
}
using TermLanesFn = void (*)(const GaussianLanes&, const Support&, TermLanes&) noexcept;
void term_lanes_first(const GaussianLanes& in, const Support& sp, TermLanes& out) noexcept;
// The loop for this CPU: picked by the first call (a relaxed atomic, constant-initialised, so no
// static initialiser runs before it and no call after the first waits on anything).
constinit std::atomic<TermLanesFn> term_lanes_fn{term_lanes_first};
void term_lanes_first(const GaussianLanes& in, const Support& sp, TermLanes& out) noexcept {
  __builtin_cpu_init();
  const bool avx512 = __builtin_cpu_supports("avx512f");
  const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  TermLanesFn f = avx512 ? term_lanes_avx512 : avx2 ? term_lanes_avx2 : term_lanes_base;
  // GSHAPTICS_SHADING_ISA=avx2|base asks for a narrower loop than the CPU has (the tests run each
  // against the scalar reference); never a wider one.
  if (const char* isa = std::getenv("GSHAPTICS_SHADING_ISA"); isa != nullptr) {
    if (std::strcmp(isa, "base") == 0) f = term_lanes_base;
    else if (std::strcmp(isa, "avx2") == 0 && avx2) f = term_lanes_avx2;
  }
  term_lanes_fn.store(f, std::memory_order_relaxed);
  f(in, sp, out);
}
inline void term_lanes(const GaussianLanes& in, const Support& sp, TermLanes& out) noexcept {
  term_lanes_fn.load(std::memory_order_relaxed)(in, sp, out);
}

// Where terms are stored, kLanes at a time: term i's field k at
// base[(i / kLanes) kFields kLanes + k kLanes + i % kLanes] (a block of kLanes terms is 1.9 KiB
// in one piece; arrays a field apart, a capacity apart, would all map to the same cache sets).
struct TermStore {
  double* base;
  // Field k of the block that starts at term i (a multiple of kLanes).
  [[nodiscard]] const double* field(int k, std::size_t i) const noexcept {
    return base + i * kFields + std::size_t(k) * kLanes;
  }
};

// The first pass's partial sums, a lane each: every disc seen from beyond its rim takes the rim
// direction, with its weight falling by exp(-past^2 / 2).
struct FirstLanes {
  double v[3][kLanes] = {};
  [[nodiscard]] Eigen::Vector3d total() const noexcept {
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    for (int l = 0; l < kLanes; ++l) s += Eigen::Vector3d(v[0][l], v[1][l], v[2][l]);
    return s;
  }
};

// Adds terms [i, i + count) (count <= kLanes) of `st` to the first pass's lanes.
__attribute__((target_clones("avx512f", "avx2", "default")))
void first_lanes(const TermStore& st, std::size_t i, int count, FirstLanes& acc) noexcept {
  const double *rx = st.field(kRx, i), *ry = st.field(kRy, i), *rz = st.field(kRz, i);
  const double *gx = st.field(kGx, i), *gy = st.field(kGy, i), *gz = st.field(kGz, i);
  const double *w = st.field(kW, i), *fl = st.field(kFlat, i), *pa = st.field(kPast, i);
  alignas(64) double live[kLanes];
  for (int l = 0; l < kLanes; ++l) live[l] = l < count ? 1.0 : 0.0;
#pragma omp simd
  for (int l = 0; l < kLanes; ++l) {
    // (The rim direction is unit, and the axis itself where c is not beyond the rim.)
    const double wt = w[l] * lane_exp(-0.5 * pa[l] * pa[l]);
    const double f = fl[l];
    const double x = f * rx[l] + (1.0 - f) * gx[l], y = f * ry[l] + (1.0 - f) * gy[l], z = f * rz[l] + (1.0 - f) * gz[l];
    const bool in = live[l] > 0;
    acc.v[0][l] += in ? wt * x : 0.0;
    acc.v[1][l] += in ? wt * y : 0.0;
    acc.v[2][l] += in ? wt * z : 0.0;
  }
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

// The second pass's partial sums, a lane each: the plain sum and its weight, and the fitted
// samples' weight, moments and cross moments (LocalLinearSum's fields, fxx by its 6 entries).
enum FitField : int { kSx, kSy, kSz, kSw, kFw, kFx0, kFx1, kFx2, kFn0, kFn1, kFn2,
                      kXX, kYY, kZZ, kXY, kXZ, kYZ,
                      kN00, kN01, kN02, kN10, kN11, kN12, kN20, kN21, kN22, kFitFields };
struct FitLanes {
  double v[kFitFields][kLanes] = {};
};

// Adds terms [i, i + count) of `st` to the second pass's lanes for the outward estimate `o`.
// A disc whose own normal disagrees with `o` and that c sees from beyond its rim turns toward
// the rim direction (see kAgree) and loses weight with its distance past the rim.
__attribute__((target_clones("avx512f", "avx2", "default")))
void fit_lanes(const TermStore& st, std::size_t i, int count, const Eigen::Vector3d& o, FitLanes& acc) noexcept {
  const double ox = o.x(), oy = o.y(), oz = o.z();
  const double *ax = st.field(kAx, i), *ay = st.field(kAy, i), *az = st.field(kAz, i);
  const double *rx = st.field(kRx, i), *ry = st.field(kRy, i), *rz = st.field(kRz, i);
  const double *gx = st.field(kGx, i), *gy = st.field(kGy, i), *gz = st.field(kGz, i);
  const double *px = st.field(kPx, i), *py = st.field(kPy, i), *pz = st.field(kPz, i);
  const double *w = st.field(kW, i), *fl = st.field(kFlat, i), *pa = st.field(kPast, i);
  constexpr double kInvFitSpan = 1.0 / (kFitFull - kFitNone);
  alignas(64) double live[kLanes];
  for (int l = 0; l < kLanes; ++l) live[l] = l < count ? 1.0 : 0.0;
#pragma omp simd
  for (int l = 0; l < kLanes; ++l) {
    const double agree = ax[l] * ox + ay[l] * oy + az[l] * oz;
    const double rim_agree = rx[l] * ox + ry[l] * oy + rz[l] * oz;
    const double turn = lane_min(1.0, (kAgree - agree) / kAgree);
    const double gain = lane_min(1.0, lane_max(0.0, (rim_agree - agree) / kGain));
    const double t = flag(agree < kAgree) * turn * gain;  // (0 where c is not beyond a rim: no gain)
    const double bx = (1.0 - t) * ax[l] + t * rx[l], by_ = (1.0 - t) * ay[l] + t * ry[l], bz = (1.0 - t) * az[l] + t * rz[l];
    const double bn = std::sqrt(bx * bx + by_ * by_ + bz * bz);
    // (At t = 0 the blend is the unit axis itself, normalised again.)
    const bool blended = bn > 1e-9;
    const double inv_bn = 1.0 / (blended ? bn : 1.0);
    const double nx = blended ? bx * inv_bn : ax[l], ny = blended ? by_ * inv_bn : ay[l], nz = blended ? bz * inv_bn : az[l];
    const double wt = w[l] * lane_exp(-0.5 * t * pa[l] * pa[l]);  // (exp(0) is 1 exactly)
    const double f = fl[l];
    const double dx = f * nx + (1.0 - f) * gx[l], dy = f * ny + (1.0 - f) * gy[l], dz = f * nz + (1.0 - f) * gz[l];
    const double dn = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double cosine = (dx * ox + dy * oy + dz * oz) / (dn > 0 ? dn : 1.0);
    const double fit = dn > 0 ? lane_min(1.0, lane_max(0.0, (cosine - kFitNone) * kInvFitSpan)) : 0.0;
    const bool in = live[l] > 0;
    const double ws = in ? wt : 0.0;      // (a lane past `count` adds nothing: selected, not multiplied)
    const double wf = in ? fit * wt : 0.0;
    const double x = in ? px[l] : 0.0, y = in ? py[l] : 0.0, z = in ? pz[l] : 0.0;
    const double ex = in ? dx : 0.0, ey = in ? dy : 0.0, ez = in ? dz : 0.0;
    acc.v[kSx][l] += ws * ex, acc.v[kSy][l] += ws * ey, acc.v[kSz][l] += ws * ez;
    acc.v[kSw][l] += ws;
    acc.v[kFw][l] += wf;
    const double wx = wf * x, wy = wf * y, wz = wf * z;
    acc.v[kFx0][l] += wx, acc.v[kFx1][l] += wy, acc.v[kFx2][l] += wz;
    acc.v[kFn0][l] += wf * ex, acc.v[kFn1][l] += wf * ey, acc.v[kFn2][l] += wf * ez;
    acc.v[kXX][l] += wx * x, acc.v[kYY][l] += wy * y, acc.v[kZZ][l] += wz * z;
    acc.v[kXY][l] += wx * y, acc.v[kXZ][l] += wx * z, acc.v[kYZ][l] += wy * z;
    acc.v[kN00][l] += wx * ex, acc.v[kN01][l] += wx * ey, acc.v[kN02][l] += wx * ez;
    acc.v[kN10][l] += wy * ex, acc.v[kN11][l] += wy * ey, acc.v[kN12][l] += wy * ez;
    acc.v[kN20][l] += wz * ex, acc.v[kN21][l] += wz * ey, acc.v[kN22][l] += wz * ez;
  }
}

// The corrected sum (see kFitFull) from the lanes, for the outward estimate o and kernel width s.
Eigen::Vector3d fit_result(const FitLanes& acc, const Eigen::Vector3d& o, double s) noexcept {
  double t[kFitFields];
  for (int k = 0; k < kFitFields; ++k) {
    t[k] = 0;
    for (int l = 0; l < kLanes; ++l) t[k] += acc.v[k][l];
  }
  const Eigen::Vector3d sum(t[kSx], t[kSy], t[kSz]);
  const double weight = t[kSw], fw = t[kFw];
  if (!(fw > 0) || !(weight > 0)) return sum;
  const Eigen::Vector3d m = Eigen::Vector3d(t[kFx0], t[kFx1], t[kFx2]) / fw;
  const Eigen::Vector3d nbar = Eigen::Vector3d(t[kFn0], t[kFn1], t[kFn2]) / fw;
  Eigen::Matrix3d fxx, fxn;
  fxx << t[kXX], t[kXY], t[kXZ], t[kXY], t[kYY], t[kYZ], t[kXZ], t[kYZ], t[kZZ];
  fxn << t[kN00], t[kN01], t[kN02], t[kN10], t[kN11], t[kN12], t[kN20], t[kN21], t[kN22];
  const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - o * o.transpose();
  const double ridge = kFitRidge * s;
  const Eigen::Matrix3d C = P * (fxx / fw - m * m.transpose()) * P + ridge * ridge * Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d B = fxn / fw - m * nbar.transpose();
  const Eigen::Vector3d y = C.ldlt().solve(P * m);
  const double share = fw / weight;
  const Eigen::Vector3d out = sum - fw * share * share * (B.transpose() * y);
  return out.allFinite() ? out : sum;
}

// The support of the sum at c for a tool of bounding radius `radius` and kernel width s (the
// header's shaded_normal): q <= q_cut.
inline double q_cutoff(double radius, double s, double tail = kShadingTail) noexcept {
  return (1 + radius / s) * (1 + radius / s) + tail;
}

// Calls f(first, count) for the slots of the BVH leaves that may hold such Gaussians: those whose
// box comes within s sqrt(q_cut) of c (a ball: the box around it alone would take about twice as
// many Gaussians off a volumetric scene), in slot order; a subtree wholly inside the ball comes
// as one range (Bvh::for_each_overlapping_range), so a wide kernel is not walked leaf by leaf.
template <typename F>
void for_each_kernel_leaf(const CollisionWorld& world, const Eigen::Vector3d& c, double s, double q_cut, F&& f) noexcept {
  const double half = s * std::sqrt(q_cut);
  float lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = round_down_to_float(c[k] - half);
    hi[k] = round_up_to_float(c[k] + half);
  }
  const double reach = half * half * (1 + 1e-6);
  // (A node wholly within the ball, its farthest corner within reach, is reported as one range.)
  const auto within = [&](const BvhNode& node) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double e = std::max(c[k] - double(node.lo[k]), double(node.hi[k]) - c[k]);
      d2 += e * e;
    }
    return d2 <= reach;
  };
  const auto near = [&](const BvhNode& leaf) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double e = std::max({double(leaf.lo[k]) - c[k], c[k] - double(leaf.hi[k]), 0.0});
      d2 += e * e;
    }
    return d2 <= reach;
  };
  world.bvh().for_each_overlapping_range(lo, hi, within, near, f);
}

// The stride of a reading whose kernel's leaves hold `held` Gaussians: 1 up to `max_visits`
// (kMaxKernelVisits; 0: no limit), else the smallest power of two that brings the Gaussians
// visited under it.
std::uint32_t sampling_stride(std::size_t held, std::size_t max_visits) noexcept {
  std::uint32_t stride = 1;
  while (max_visits > 0 && held > max_visits * std::size_t(stride)) stride *= 2;
  return stride;
}

// The stride of a reading at c (sampling_stride of the Gaussians its kernel's leaves hold).
std::uint32_t kernel_stride(const CollisionWorld& world, const Eigen::Vector3d& c, double s, const Support& sp) noexcept {
  if (sp.max_visits == 0) return 1;
  std::size_t held = 0;
  for_each_kernel_leaf(world, c, s, sp.q_cut, [&](std::uint32_t, std::uint32_t count) { held += count; });
  return sampling_stride(held, sp.max_visits);
}

// The sampled slots of a leaf's range [first, first + count): the multiples of `stride`, as the
// first of them and how many. The world keeps its Gaussians in the BVH's leaf order, so the
// multiples of a stride are spread evenly over the space a kernel covers, and a coarser
// stride's slots are a subset of a finer one's.
struct SampledRange {
  std::uint32_t first, count;
};
SampledRange sampled(std::uint32_t first, std::uint32_t count, std::uint32_t stride) noexcept {
  const std::uint32_t start = (first + stride - 1) / stride * stride, end = first + count;
  return {start, start < end ? (end - start + stride - 1) / stride : 0};
}

// Calls f(g) for the Gaussians in the sampled slots of a leaf's range, in slot order; returns how
// many it visited.
template <typename F>
std::uint32_t for_each_sampled(const CollisionGaussian* gs, std::uint32_t first, std::uint32_t count,
                               std::uint32_t stride, F&& f) noexcept {
  const SampledRange r = sampled(first, count, stride);
  for (std::uint32_t i = 0; i < r.count; ++i) f(gs[r.first + i * stride]);
  return r.count;
}

// Gathers visited Gaussians kLanes at a time and passes each kept term, in visiting order, to a
// sink: sink(lanes, l) for lane l of `lanes`.
class Gatherer {
 public:
  void start(const Eigen::Vector3d& c, const Support& sp) noexcept {
    c_ = c;
    sp_ = sp;
    n_ = 0;
  }
  template <typename Sink>
  void add(const CollisionGaussian& g, Sink&& sink) noexcept {
    in_.dx[n_] = c_.x() - g.center[0];
    in_.dy[n_] = c_.y() - g.center[1];
    in_.dz[n_] = c_.z() - g.center[2];
    in_.qw[n_] = g.quaternion[0], in_.qx[n_] = g.quaternion[1], in_.qy[n_] = g.quaternion[2], in_.qz[n_] = g.quaternion[3];
    in_.a0[n_] = g.semi_axes[0], in_.a1[n_] = g.semi_axes[1], in_.a2[n_] = g.semi_axes[2];
    in_.amax[n_] = g.radius;
    in_.alpha[n_] = g.opacity;
    if (++n_ == kLanes) flush(sink);
  }
  template <typename Sink>
  void flush(Sink&& sink) noexcept {
    if (n_ == 0) return;
    for (int l = n_; l < kLanes; ++l) {  // padding: far, unit and round (not kept)
      in_.dx[l] = in_.dy[l] = in_.dz[l] = 1e30;
      in_.qw[l] = 1, in_.qx[l] = in_.qy[l] = in_.qz[l] = 0;
      in_.a0[l] = in_.a1[l] = in_.a2[l] = in_.amax[l] = in_.alpha[l] = 1;
    }
    term_lanes(in_, sp_, out_);
    for (int l = 0; l < n_; ++l)
      if (out_.keep[l] > 0) sink(out_, l);
    n_ = 0;
  }

 private:
  Eigen::Vector3d c_ = Eigen::Vector3d::Zero();
  Support sp_;
  int n_ = 0;
  GaussianLanes in_;
  TermLanes out_;
};

inline void copy_term(const TermLanes& from, int l, const TermStore& to, std::size_t i) noexcept {
  double* block = to.base + (i / kLanes) * kFields * kLanes + i % kLanes;
  for (int k = 0; k < kFields; ++k) block[k * kLanes] = from.f[k][l];
}

Eigen::Vector3d finish(const Eigen::Vector3d& sum) noexcept {
  const double n = sum.norm();
  return n > 0 && std::isfinite(n) ? Eigen::Vector3d(sum / n) : Eigen::Vector3d::Zero();
}

Support support_of(double radius, double kernel, const FreeBall& ball, double min_width, double tail,
                   std::size_t max_visits) noexcept {
  Support sp;
  sp.rim = kernel * radius;
  const double s = std::max(sp.rim, min_width);
  sp.s2 = s * s;
  sp.q_cut = q_cutoff(radius, s, tail);
  sp.max_visits = max_visits;
  sp.ball = ball;
  return sp;
}

// The plain reading: two traversals, the terms staged kLanes at a time (no working memory).
Eigen::Vector3d plain_reading(const CollisionWorld& world, const Eigen::Vector3d& c, double radius, double kernel,
                              const FreeBall& ball, double min_width, double tail, std::size_t max_visits) noexcept {
  const Support sp = support_of(radius, kernel, ball, min_width, tail, max_visits);
  const double s = std::sqrt(sp.s2);
  const CollisionGaussian* gs = world.gaussians().data();
  const std::uint32_t stride = kernel_stride(world, c, s, sp);
  alignas(64) double staged[kFields * kLanes] = {};
  const TermStore st{staged};
  int m = 0;
  Gatherer gather;
  // One traversal, each kept term staged; a full stage goes to `lanes`.
  const auto traverse = [&](auto&& lanes) {
    m = 0;
    gather.start(c, sp);
    const auto sink = [&](const TermLanes& t, int l) {
      copy_term(t, l, st, std::size_t(m));
      if (++m == kLanes) lanes(kLanes), m = 0;
    };
    for_each_kernel_leaf(world, c, s, sp.q_cut, [&](std::uint32_t first, std::uint32_t count) {
      for_each_sampled(gs, first, count, stride, [&](const CollisionGaussian& g) { gather.add(g, sink); });
    });
    gather.flush(sink);
    if (m > 0) lanes(m);
  };
  FirstLanes first;
  traverse([&](int count) { first_lanes(st, 0, count, first); });
  const Eigen::Vector3d f = first.total();
  const double n1 = f.norm();
  if (!(n1 > 0) || !std::isfinite(n1)) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d outward = f / n1;
  FitLanes fit;
  traverse([&](int count) { fit_lanes(st, 0, count, outward, fit); });
  return finish(fit_result(fit, outward, s));
}

}  // namespace

struct ShadingScratch::Terms {
  // The kept terms (TermStore), room for `stride` (a multiple of kLanes).
  std::vector<double> store;
  std::size_t stride = 0;
  [[nodiscard]] TermStore terms() noexcept { return {store.data()}; }
  // A reading spread over calls (ShadedNormalCache::read_ahead): the sampled slot ranges of its support,
  // then its terms in visiting order (each full kLanes of them added to the first pass as they
  // come), then the second pass over them kLanes at a time.
  std::vector<SampledRange> ranges;
  std::uint32_t sample_stride = 1;  // (sampling_stride)
  std::size_t n_ranges = 0, range_i = 0, offset = 0, n = 0, fit_i = 0, steps = 0;
  int phase = 0;  // 1: terms, 2: the second pass
  bool overflow = false;
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), outward = Eigen::Vector3d::Zero();
  Support sp;
  double s = 0;
  Gatherer gather;
  FirstLanes first;
  FitLanes fit;

  // Stores lane l of `t` as the next term (or marks the overflow), adding each full kLanes of
  // terms to the first pass.
  void keep(const TermLanes& t, int l) noexcept {
    if (n == stride) {
      overflow = true;
      return;
    }
    copy_term(t, l, terms(), n);
    if (++n % kLanes == 0) first_lanes(terms(), n - kLanes, kLanes, first);
  }
  // The terms gathered: the last partial kLanes to the first pass; false when it found none.
  bool close_first() noexcept {
    gather.flush([this](const TermLanes& t, int l) { keep(t, l); });
    if (n % kLanes != 0) first_lanes(terms(), n - n % kLanes, int(n % kLanes), first);
    const Eigen::Vector3d f = first.total();
    const double n1 = f.norm();
    if (!(n1 > 0) || !std::isfinite(n1)) return false;
    outward = f / n1;
    return true;
  }
  void start(const Eigen::Vector3d& at, double radius, double kernel, const FreeBall& ball, double min_width,
             double tail, std::size_t max_visits) noexcept {
    c = at;
    sp = support_of(radius, kernel, ball, min_width, tail, max_visits);
    s = std::sqrt(sp.s2);
    gather.start(c, sp);
    first = FirstLanes{};
    fit = FitLanes{};
    range_i = offset = n = fit_i = steps = 0;
    overflow = false;
    outward = Eigen::Vector3d::Zero();
  }

  // The support's slot ranges (started at c) kept in `ranges` while they are counted: false when
  // they outgrow it. Sets sample_stride from the count.
  bool collect_ranges(const CollisionWorld& world) noexcept {
    n_ranges = 0;
    bool fits = true;
    std::size_t held = 0;
    for_each_kernel_leaf(world, c, s, sp.q_cut, [&](std::uint32_t f, std::uint32_t count) {
      held += count;
      if (n_ranges < ranges.size())
        ranges[n_ranges++] = {f, count};
      else
        fits = false;
    });
    sample_stride = sampling_stride(held, sp.max_visits);
    return fits;
  }

  // Starts reading at `at`: false when the support comes in more ranges than `ranges` holds (read it at once).
  bool begin(const CollisionWorld& world, const Eigen::Vector3d& at, double radius, double kernel,
             const FreeBall& ball, double min_width, double tail, std::size_t max_visits) noexcept {
    start(at, radius, kernel, ball, min_width, tail, max_visits);
    const bool fits = collect_ranges(world);
    // The leaves' ranges to their sampled slots (one past the last has none).
    std::size_t kept = 0;
    for (std::size_t i = 0; fits && i < n_ranges; ++i)
      if (const SampledRange r = sampled(ranges[i].first, ranges[i].count, sample_stride); r.count > 0)
        ranges[kept++] = r;
    n_ranges = kept;
    phase = 1;
    return fits;
  }
  // Advances the reading by about `budget` steps (a Gaussian visited, or a term of the second
  // pass; that pass goes kLanes terms at a time): 1 when it is done (the normal in `out`), 0
  // while it is not, -1 when its terms outgrow the scratch.
  int advance(const CollisionWorld& world, std::size_t budget, Eigen::Vector3d& out) noexcept {
    const CollisionGaussian* gs = world.gaussians().data();
    const auto sink = [this](const TermLanes& t, int l) { keep(t, l); };
    while (phase == 1 && budget > 0) {
      if (range_i == n_ranges) {
        if (!close_first()) {
          out = Eigen::Vector3d::Zero();
          phase = 0;
          return overflow ? -1 : 1;
        }
        phase = 2;
        break;
      }
      const SampledRange& rg = ranges[range_i];
      gather.add(gs[rg.first + std::uint32_t(offset) * sample_stride], sink);
      ++steps;
      if (++offset == rg.count) offset = 0, ++range_i;
      --budget;
    }
    if (overflow) return phase = 0, -1;
    while (phase == 2 && budget > 0 && fit_i < n) {
      const int count = int(std::min<std::size_t>(kLanes, n - fit_i));
      fit_lanes(terms(), fit_i, count, outward, fit);
      fit_i += std::size_t(count);
      steps += std::size_t(count);
      budget -= std::min(budget, std::size_t(count));
    }
    if (phase == 2 && fit_i == n) {
      out = finish(fit_result(fit, outward, s));
      phase = 0;
      return 1;
    }
    return 0;
  }
};

ShadingScratch::ShadingScratch(std::size_t capacity) : terms_(std::make_unique<Terms>()) {
  const std::size_t stride = (capacity + kLanes - 1) / kLanes * kLanes;
  terms_->stride = stride;
  terms_->store.assign(stride * kFields, 0.0);
  terms_->ranges.resize(std::max<std::size_t>(64, capacity / 4));
}
ShadingScratch::~ShadingScratch() = default;
ShadingScratch::ShadingScratch(const ShadingScratch& o) : ShadingScratch(o.capacity()) {}
ShadingScratch& ShadingScratch::operator=(const ShadingScratch& o) {
  if (this != &o) {
    terms_->stride = o.terms_->stride;
    terms_->store.assign(o.terms_->store.size(), 0.0);
    terms_->ranges.resize(o.terms_->ranges.size());
    terms_->phase = 0;
  }
  return *this;
}
std::size_t ShadingScratch::capacity() const noexcept { return terms_->stride; }

Eigen::Vector3d shaded_normal(const CollisionWorld& world, const Eigen::Vector3d& c, double radius, double kernel,
                              const FreeBall& ball, double min_width, double tail, std::size_t max_visits) noexcept {
  return plain_reading(world, c, radius, kernel, ball, min_width, tail, max_visits);
}

Eigen::Vector3d shaded_normal(const CollisionWorld& world, const Eigen::Vector3d& c, double radius, double kernel,
                              ShadingScratch& scratch, const FreeBall& ball, double min_width, double tail,
                              std::size_t max_visits) noexcept {
  ShadingScratch::Terms& t = *scratch.terms_;
  t.phase = 0;  // (a reading spread over calls in this scratch is given up)
  t.start(c, radius, kernel, ball, min_width, tail, max_visits);
  const CollisionGaussian* gs = world.gaussians().data();
  // One traversal: the support's slot ranges kept while they are counted (the sample's stride
  // needs the count before the first Gaussian is gathered); a second only where they outgrow
  // the scratch's room for ranges.
  const bool fits = t.collect_ranges(world);
  const std::uint32_t stride = t.sample_stride;
  std::size_t visited = 0;
  const auto sink = [&t](const TermLanes& tl, int l) { t.keep(tl, l); };
  const auto gather = [&](std::uint32_t first, std::uint32_t count) {
    visited += for_each_sampled(gs, first, count, stride, [&](const CollisionGaussian& g) { t.gather.add(g, sink); });
  };
  if (fits)
    for (std::size_t i = 0; i < t.n_ranges; ++i) gather(t.ranges[i].first, t.ranges[i].count);
  else
    for_each_kernel_leaf(world, c, t.s, t.sp.q_cut, gather);
  const bool found = t.close_first();
  scratch.last_terms_ = t.n;
  scratch.last_overflow_ = t.overflow;
  scratch.last_steps_ = visited + t.n;
  if (t.overflow) return plain_reading(world, c, radius, kernel, ball, min_width, tail, max_visits);  // more than it holds
  if (!found) return Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < t.n; i += kLanes) fit_lanes(t.terms(), i, int(std::min<std::size_t>(kLanes, t.n - i)), t.outward, t.fit);
  return finish(fit_result(t.fit, t.outward, t.s));
}

const Eigen::Vector3d& ShadedNormalCache::read_ahead(const CollisionWorld& world, const Eigen::Vector3d& at,
                                                     double scale, double kernel, double reuse, ShadingScratch& scratch,
                                                     std::size_t budget, const FreeBall& ball,
                                                     double min_width, double tail, std::size_t max_visits) noexcept {
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
    return read(world, at, scale, kernel, largest_reuse, scratch, ball, min_width, tail, max_visits);
  }
  if (budget == 0) return normal_;
  // A reading ahead is started only where one costs more than a tick's budget, and only on a
  // steady motion: it took `calls_` calls to move half of `reuse` on a nearly straight path, so
  // about as many remain, and the reading, made for where the proxy will then be, is spread
  // evenly over them, even where its share of a call is over the budget (a fast slide: half a
  // reading a tick is still half the spike). A reading due on the first call, or on a wandering
  // motion, is made whole when due; so is one on a motion so slow that readings are rare (more
  // than kAheadCalls calls to half of `reuse`). Up to 8 calls and within the budget only, the
  // fidelity gratings' drags read tick p99 of 60-90 us with the 10 mm sphere at 20 mm/s (a whole
  // reading every 10-30 ticks), 27-37 us with this; the real scenes' probe runs rise by 0.2-1.1 us
  // at p99 (bench/RESULTS.md).
  constexpr std::size_t kAheadCalls = 64;
  constexpr double kStraight = 0.8;  // displacement over path length
  ++calls_;
  const double moved = (at - at_).norm();
  const std::size_t share = (scratch.last_steps_ + calls_ - 1) / calls_;
  if (!pending_ && !ready_ && !ahead_blocked_ && scratch.last_steps_ > budget && moved > 0.5 * reuse &&
      moved >= kStraight * path_ && calls_ >= 2 && calls_ <= kAheadCalls) {
    ahead_share_ = share;
    pending_at_ = at + (at - at_);  // as far on again as it came
    pending_ = pending.begin(world, pending_at_, scale, kernel, ball, min_width, tail, max_visits);
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

FrontFace front_face(const CollisionWorld& world, std::span<const Contact> blockers, const Eigen::Vector3d& at,
                     double margin) noexcept {
  constexpr std::size_t kMax = 8;
  if (!(margin > 0)) return {};
  std::array<Eigen::Vector3d, kMax> axis, center;
  std::size_t n = 0;
  for (const Contact& b : blockers) {
    if (n == kMax) break;
    const CollisionGaussian& g = world.gaussians()[b.slot];
    if (!(flatness(g) >= 0.5)) continue;  // (a rod or a ball states no plane)
    const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
    const Eigen::Vector3d a = rotation_matrix(g).col(thinnest_axis(g));
    axis[n] = (at - c).dot(a) >= 0 ? a : Eigen::Vector3d(-a);
    center[n++] = c;
  }
  // How far j lies behind i's plane (on the side away from `at`) past `margin`, in margins, up
  // to 1; and how far across i it lies (1 at 90 degrees, 0 from acos(kAgree) ~ 73 degrees on:
  // discs of one face lie behind each other by their tilt over their distance, not across).
  const auto behind = [&](std::size_t j, std::size_t i) {
    return std::clamp(((center[i] - center[j]).dot(axis[i]) - margin) / margin, 0.0, 1.0);
  };
  const auto across = [&](std::size_t j, std::size_t i) {
    return std::clamp((kAgree - std::fabs(axis[j].dot(axis[i]))) / kAgree, 0.0, 1.0);
  };
  // j overhangs i when it lies across i and behind it while i does not lie behind j; the
  // product of the three ramps is how clearly (continuous in the blockers' poses).
  std::array<bool, kMax> overhang{};
  double strength = 0;
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t i = 0; i < n; ++i) {
      if (i == j) continue;
      const double clear = across(j, i) * behind(j, i) * (1.0 - behind(i, j));
      if (clear > 0) overhang[j] = true, strength = std::max(strength, clear);
    }
  FrontFace face;
  if (!(strength > 0)) return face;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double height = 0;
  int front = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (!overhang[i]) sum += axis[i], height += (at - center[i]).dot(axis[i]), ++front;
  const double norm = sum.norm();
  if (!(norm > 0)) return face;
  face.normal = sum / norm;
  face.height = height / front;
  face.strength = strength;
  return face;
}

}  // namespace gshaptics
