#pragma once
/// @file
/// Force shading on Gaussians, the proxy's contact normal (one of the proxy renderer's four
/// parts; docs/design.md Sec. 7). Force shading after Morgenbesser & Srinivasan (1996): the force
/// acts along a normal that varies smoothly across the surface instead of jumping between
/// primitives.
///
/// The normal at p is the opacity-weighted sum over the Gaussians near p of
///   w_i = alpha_i exp(-q_i / 2),  q_i = (p - c_i)^T A_i^-1 (p - c_i),  A_i = Sigma_i + s^2 I,
/// times a unit direction that blends, by the Gaussian's flatness f = 1 - a_min / a_mid, the
/// Gaussian's shortest axis turned toward p (a disc states its own normal) and the direction of
/// A_i^-1 (p - c_i) (a round Gaussian only says where it is: the density gradient). The kernel
/// width s widens every Gaussian so the field is smooth at the scale of the tool. Near convex
/// edges and corners, a disc whose turned axis disagrees with a first outward estimate and that
/// p sees from beyond its rim gives the direction from its rim to p instead, with less weight
/// (two passes; docs/design.md Sec. 7), so the other face's discs do not pull the normal into
/// the solid. The second pass reads the directions' local linear fit over the Gaussians' centres
/// at p, not their plain weighted mean, which is the field at the Gaussians' centroid (local
/// linear kernel regression: Cleveland 1979, Fan 1992; on the directions within about 18-32
/// degrees of the first pass's estimate, so not across edges and corners).
///
/// Threading: pure functions of an immutable world; no allocation, lock, log or throw.

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <utility>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/contact_query.h"

namespace gshaptics {

/// How far below a free ball's centre, in ball radii, a passed Gaussian's centre lies before it
/// counts as under the tool rather than beside it (FreeBall).
inline constexpr double kFloaterDepth = 0.75;

/// The tool's free ball at the reading point, for leaving out the floaters beside a resting tool.
/// A Gaussian whose inscribed ball (radius a_min,i) reaches into the free ball,
/// |center - c_i| < radius (1 - 1e-3) + a_min,i, overlaps the tool, so the proxy passed it (it
/// rests free of every blocker, whose inscribed ball lies inside it); one whose centre is also
/// less than kFloaterDepth x radius below the ball's centre along `up` (or above it), that is
/// more than a quarter radius above a resting ball's lowest point, is beside the tool, not under
/// it: a floater, and it is left out. Passed Gaussians under the tool stay: on sparse real scenes
/// the floater rule passes many that belong to the surface (the Truck's roof, which a depth of
/// one radius loses). Without this a round floater level with a resting tool (0.3 % of the
/// fidelity scenes' Gaussians, 5-30 mm off the surface) tilts the normal by its density
/// gradient: 11 degrees on a cube face at 8 mm spacing; and a depth of r / 2 missed one 5.9 mm up
/// beside a 10 mm tool resting 1.2 mm high on a proud disc (4.1 degrees on the fidelity sphere).
///
/// `surface`, when set, is how far the surface the tool rests on lies from the reading point
/// (a sphere's radius). A disc whose plane lies farther than that, past half a narrow kernel
/// (0.5 kernel x radius) more for the Gaussians' jitter, is not under the tool: its weight falls
/// as exp(-e^2 / 2) with e the excess in half narrow kernels, scaled by its flatness. That is
/// the far face of a concave crease, which the kernel widened to the Gaussian spacing reaches:
/// 9.6 degrees on a 60-degree groove's face at 8 mm spacing, 33 mm from the crease, with a
/// 10 mm tool on 13 mm discs.
///
/// `face`, when set (front_face), is the plane of the face under the tool where a disc of the
/// other face, overhanging a convex edge, blocks it too. A disc across that face (its axis more
/// than acos(0.3) ~ 73 degrees from `face`, fully at 90) whose centre lies behind the plane by
/// more than a margin (kOverhangMargin x `surface`) belongs to the other face: its weight falls
/// as exp(-s e^2 / 2), e the excess in margins and s the face's strength, scaled by its
/// flatness. Without it the overhang's flat side turned the normal by 23 degrees out of the face
/// on the 8 mm fidelity cube (a -y face disc 16 mm across reaching 12 mm below the -z face, the
/// tool resting on the -z face against it).
struct FreeBall {
  double radius = 0;  ///< m; 0: off (every Gaussian near counts)
  Eigen::Vector3d up = Eigen::Vector3d::Zero();  ///< unit, away from the surface the tool rests on (its constraint normals)
  double surface = 0;  ///< m, from the reading point to the surface under the tool along `up`; 0: no height falloff
  Eigen::Vector3d face = Eigen::Vector3d::Zero();  ///< unit normal of the face under an overhang (front_face); zero: off
  double face_height = 0;  ///< m, the reading point's height above that face's plane along `face`
  double face_strength = 1;  ///< in [0, 1], scales the overhang falloff's exponent (FrontFace::strength)
};

/// How far, in units of FreeBall::surface, a disc's centre must lie behind another blocker's
/// plane (front_face), or behind the plane of the face under the tool (FreeBall::face), before
/// it counts as the other face of a convex edge rather than the jitter and tilt of this one.
inline constexpr double kOverhangMargin = 0.25;

/// The face under a resting tool where a disc of the other face of a convex edge overhangs the
/// edge and blocks the tool beside it (a "fin": the synthetic scenes' discs near an edge reach
/// past it by up to half their width; trained scenes have them where a surface ends).
struct FrontFace {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< unit, toward the reading point; zero: no overhang
  double height = 0;  ///< m, the reading point's mean height above the front blockers' planes
  /// In (0, 1] with a normal: how clearly a blocker overhangs, the largest over the pairs of the
  /// product of three ramps (across: 0 at acos(0.3), 1 at 90 degrees; behind the other's plane:
  /// 0 at `margin`, 1 at twice it; the other not behind its plane: the same ramp, reversed), so
  /// that the face comes and goes continuously as the tool moves.
  double strength = 0;
};

/// Among the flat `blockers` (flatness >= 0.5; each disc's axis turned toward `at`), blocker j
/// overhangs blocker i when the two lie across each other (axes more than acos(0.3) ~ 73 degrees
/// apart: two faces, not two discs of one face) and j's centre lies more than `margin` m behind
/// i's plane while i's centre does not lie as far behind j's (FrontFace::strength grades each).
/// The normal is the normalised sum of the axes of the flat blockers that overhang none, the
/// height `at`'s mean height above their planes. Zero when no blocker overhangs another: at a
/// clean convex edge each face's discs lie behind the other's plane, in a concave crease neither
/// does; and for `margin` <= 0. World frame. No allocation; the first 8 flat blockers are compared.
[[nodiscard]] FrontFace front_face(const CollisionWorld& world, std::span<const Contact> blockers,
                                   const Eigen::Vector3d& at, double margin) noexcept;

/// How far the shaded normal's support reaches, in q past the Gaussians that touch the tool
/// (see shaded_normal): exp(-kShadingTail / 2) = 1.2e-4 of such a Gaussian's weight.
inline constexpr double kShadingTail = 18;

/// How many Gaussians a shaded normal reading visits at most. Where its kernel's BVH leaves hold
/// more (a large tool on a dense capture: a 2 % tool on firepit.ply, 12.7 cm, holds 10,000-17,000,
/// 0.6-1.4 ms a reading), the reading takes every k-th slot of the world's BVH order, k the
/// smallest power of two that brings the visits under this: a sample spread evenly over the
/// kernel's space, the same for every reading made at that point (the plain call, the call with
/// working memory, a reading spread over calls), a coarser one a subset of a finer one. The normal
/// is a ratio of weighted sums over the terms, so a thinned sum estimates the whole one: 4 and 6 cm
/// tools on 2 mm spacing read it within 2.5 deg of the whole sum, 0.4 deg on average
/// (tests/proxy_parts_test.cpp); the fidelity's 5 and 10 mm spheres never need a sample. Where
/// the count crosses a power of two times this, the normal steps by about that much.
inline constexpr std::size_t kMaxKernelVisits = 2048;

/// The shaded normal at `center` (world frame, m) for a tool of bounding radius `radius` (m)
/// with a kernel of `kernel` radii (s = kernel x radius). The Gaussians with
/// q <= q_cut = (1 + radius / s)^2 + `tail` contribute, except the floaters beside the `ball`
/// (FreeBall); they are found by the BVH leaves within s sqrt(q_cut) of the centre. A Gaussian
/// that touches a resting tool has q <= (1 + radius / s)^2 (in the norm of A^-1 the tool's centre
/// is at most 1 from the Gaussian's surface point and radius / s beyond it), so a term left out
/// weighs under exp(-tail / 2) of it at equal opacity. On the fidelity shapes (faces, edges,
/// corners, floaters included) the default tail reads the sum over all Gaussians within 0.5 deg
/// (mean 0.002 deg; tests/proxy_parts_test.cpp), where the box radius + 3 s with q <= 40 that it
/// replaced read it within 0.25 deg (mean 0.0035) with 1.4 times the terms (the burger's readings).
/// `min_width` (m): the kernel width is max(s, min_width), so that on a sparse
/// surface it spans the Gaussian spacing (shading_spacing()) and averages neighbouring Gaussians
/// instead of reading the one under the tool; the falloff of discs seen beyond their rim stays
/// on s (docs/design.md Sec. 7). Returns a unit vector pointing from the Gaussians toward
/// `center`, or zero when no Gaussian is near.
[[nodiscard]] Eigen::Vector3d shaded_normal(const CollisionWorld& world, const Eigen::Vector3d& center, double radius,
                                            double kernel, const FreeBall& ball = {},
                                            double min_width = 0, double tail = kShadingTail,
                                            std::size_t max_visits = kMaxKernelVisits) noexcept;

/// The length scale of the shading kernel for a tool of bounding radius `radius`: the radius,
/// or the largest middle semi-axis of the `blockers` when that is larger. On sparse scenes a
/// kernel smaller than the Gaussian spacing would see single Gaussians, not the surface.
[[nodiscard]] double shading_scale(const CollisionWorld& world, std::span<const Contact> blockers,
                                   double radius) noexcept;

/// The Gaussian spacing of the surface under a resting tool, as its `blockers` show it: their
/// largest middle semi-axis (m; 0 without blockers). 3DGS and the synthetic scenes size their
/// discs about as far apart as they are wide.
[[nodiscard]] double shading_spacing(const CollisionWorld& world, std::span<const Contact> blockers) noexcept;

/// Working memory of shaded_normal(): the terms of the Gaussians near the reading point, kept
/// from the first pass for the second (no second traversal, rotation or exponential per
/// Gaussian). Allocated once, at construction; copies allocate their own.
class ShadingScratch {
 public:
  /// Room for `capacity` terms, rounded up to a multiple of 16 (120 bytes each; the default,
  /// 480 KiB, holds a 7.6 cm tool's kernel on the Truck and most of one on the largest real
  /// scenes). A reading with more falls back to the plain call, with the same result.
  explicit ShadingScratch(std::size_t capacity = 4096);
  ~ShadingScratch();
  ShadingScratch(const ShadingScratch& other);
  ShadingScratch& operator=(const ShadingScratch& other);
  [[nodiscard]] std::size_t capacity() const noexcept;
  /// Gaussians the last reading kept, and whether it had more than the capacity.
  [[nodiscard]] std::size_t last_terms() const noexcept { return last_terms_; }
  [[nodiscard]] bool last_overflow() const noexcept { return last_overflow_; }
  /// What the last finished reading cost: Gaussians visited plus terms fitted.
  [[nodiscard]] std::size_t last_steps() const noexcept { return last_steps_; }

 private:
  friend Eigen::Vector3d shaded_normal(const CollisionWorld&, const Eigen::Vector3d&, double, double,
                                       ShadingScratch&, const FreeBall&, double, double, std::size_t) noexcept;
  friend class ShadedNormalCache;  // (its reading ahead keeps the pending reading here)
  struct Terms;
  std::unique_ptr<Terms> terms_;
  std::size_t last_terms_ = 0, last_steps_ = 0;
  bool last_overflow_ = false;
};

/// shaded_normal() with working memory: bit-identical to the plain call (the same terms, summed
/// in the same order, by the same vectorised kernels), one traversal instead of two. Allocates
/// nothing.
[[nodiscard]] Eigen::Vector3d shaded_normal(const CollisionWorld& world, const Eigen::Vector3d& center, double radius,
                                            double kernel, ShadingScratch& scratch,
                                            const FreeBall& ball = {}, double min_width = 0,
                                            double tail = kShadingTail,
                                            std::size_t max_visits = kMaxKernelVisits) noexcept;

/// The last shaded normal and where it was read. The field is smooth at the kernel's scale, so
/// a proxy re-reads it only once its reading point moved more than `reuse` m
/// (ProxyParams::shading_reuse, in tool radii, times the radius), or sooner where the field
/// turns fast, with a turn tolerance (set_turn_tolerance; ProxyParams::shading_turn).
class ShadedNormalCache {
 public:
  /// shaded_normal(world, at, scale, kernel, scratch, ball, min_width, tail), or a cached one while
  /// `at` is within `reuse` m (less where the field turns fast: reuse_within) of where that was
  /// read: the last reading, or one of the
  /// kEarlierReadings before it (then it becomes the last). A compound tool's part whose probe
  /// cycles among two or three Gaussians tick by tick (a resting tool's limit cycle) moves its
  /// reading point back and forth by more than `reuse` (a long part's support point moves by
  /// a^2 / b per radian of the contact normal: 1.4 mm on the fidelity stylus's tip, pressed at 30
  /// degrees); the earlier readings keep it from re-reading each time.
  const Eigen::Vector3d& read(const CollisionWorld& world, const Eigen::Vector3d& at, double scale, double kernel,
                              double reuse, ShadingScratch& scratch, const FreeBall& ball = {},
                              double min_width = 0, double tail = kShadingTail,
                              std::size_t max_visits = kMaxKernelVisits) noexcept {
    reuse = reuse_within(reuse);
    if (valid_ && (at - at_).norm() <= reuse) return normal_;
    for (std::size_t i = 0; valid_ && i < n_earlier_; ++i)
      if ((at - earlier_at_[i]).norm() <= reuse) {
        std::swap(at_, earlier_at_[i]);
        std::swap(normal_, earlier_normal_[i]);
        return normal_;
      }
    if (valid_) {  // the last reading joins the earlier ones (the oldest leaves)
      const std::size_t keep = n_earlier_ < kEarlierReadings ? n_earlier_++ : kEarlierReadings - 1;
      for (std::size_t i = keep; i > 0; --i) {
        earlier_at_[i] = earlier_at_[i - 1];
        earlier_normal_[i] = earlier_normal_[i - 1];
      }
      earlier_at_[0] = at_, earlier_normal_[0] = normal_;
    }
    take(shaded_normal(world, at, scale, kernel, scratch, ball, min_width, tail, max_visits), at);
    ++reads_;
    ++whole_reads_;
    return normal_;
  }
  static constexpr std::size_t kEarlierReadings = 3;
  /// read() that prepares the next reading ahead, so that the tick it is due does not pay for a
  /// whole one. Where the last reading cost more than `budget` steps (a Gaussian visited, or a
  /// term fitted: ShadingScratch::last_steps) and the proxy moved half of `reuse` from the cached
  /// reading steadily (in 2 to 64 calls, on a path at most 1.25 times the displacement), a
  /// reading starts for the point as far on again, and each later call advances it by an even
  /// share over as many calls (the last reading's steps over the calls it took to get here; on
  /// a fast slide over `budget`). When the cached normal is due (`at`
  /// more than `reuse` from where it was read), that reading replaces it if it was made for a
  /// point within `reuse` of `at` (what is left of it is done then); otherwise `at` is read
  /// whole, as read() does. So the normal returned was read within `reuse` of `at`, is
  /// bit-identical to shaded_normal() at the point where it was read, and there are no more
  /// readings than read() makes; only which point of that range differs. A reading within the
  /// budget, or one due on the first call or on a slow or wandering motion, is made whole when
  /// due (budget 0: read() exactly).
  /// The pending reading lives in `scratch`: one cache a scratch, and no other reading with it
  /// in between (one cancels the pending reading).
  const Eigen::Vector3d& read_ahead(const CollisionWorld& world, const Eigen::Vector3d& at, double scale,
                                    double kernel, double reuse, ShadingScratch& scratch, std::size_t budget,
                                    const FreeBall& ball = {}, double min_width = 0,
                                    double tail = kShadingTail,
                                    std::size_t max_visits = kMaxKernelVisits) noexcept;
  /// Bounds the normal's turn between readings (radians; 0: off, `reuse` as given). The field
  /// is smooth on a face but turns fast round a convex edge (40 degrees per mm beside the 8 mm
  /// fidelity cube's edge with a 10 mm tool), and a normal held over `reuse` there makes the
  /// force depend on the path: a press read on the way in and again on the way out pushed
  /// harder out than in (W down to -3 mJ a cycle). With a tolerance, the radius a reading is
  /// kept over is `tolerance` / (the turn per metre between the last two readings), at most
  /// `reuse` and at least kMinReuseShare of it.
  void set_turn_tolerance(double radians) noexcept { turn_tolerance_ = radians > 0 ? radians : 0.0; }
  [[nodiscard]] double turn_tolerance() const noexcept { return turn_tolerance_; }
  /// The field's turn between the last two readings, radians per metre (negative before two:
  /// unknown, and the first reading is kept over the smallest radius only).
  [[nodiscard]] double turn_rate() const noexcept { return turn_rate_; }
  /// The radius a reading is now kept over, for a largest radius `reuse` (m).
  [[nodiscard]] double reuse_within(double reuse) const noexcept {
    if (!(turn_tolerance_ > 0) || !(turn_rate_ * reuse > turn_tolerance_ || turn_rate_ < 0)) return reuse;
    return turn_rate_ < 0 ? kMinReuseShare * reuse : std::max(kMinReuseShare * reuse, turn_tolerance_ / turn_rate_);
  }
  static constexpr double kMinReuseShare = 0.04;
  /// Drops the cached readings and any reading under way, keeping the field's measured turn
  /// rate: the next call reads anew. For a change in what a reading depends on besides the point
  /// (the proxy's FreeBall::face).
  void forget() noexcept {
    valid_ = pending_ = ahead_blocked_ = ready_ = false;
    n_earlier_ = 0;
    calls_ = 0;
    path_ = 0;
  }
  void reset() noexcept {
    turn_rate_ = -1;
    valid_ = pending_ = ahead_blocked_ = ready_ = false;
    n_earlier_ = 0;
    calls_ = 0;
    path_ = 0;
  }
  /// Readings of the field so far (cache misses), for profiling.
  [[nodiscard]] std::uint64_t reads() const noexcept { return reads_; }
  /// Of those, the ones made whole within one call (read(), or read_ahead() when a reading was
  /// due and none was prepared).
  [[nodiscard]] std::uint64_t whole_reads() const noexcept { return whole_reads_; }
  /// Where the cached normal was read (world, m).
  [[nodiscard]] const Eigen::Vector3d& read_point() const noexcept { return at_; }

 private:
  // A new reading `n` at `at` replaces the cached one; the turn between them is measured.
  void take(const Eigen::Vector3d& n, const Eigen::Vector3d& at) noexcept {
    if (valid_) {
      const double d = (at - at_).norm();
      const double c = n.dot(normal_);
      if (d > 0 && n.allFinite() && !n.isZero(0) && !normal_.isZero(0))
        turn_rate_ = std::acos(std::min(1.0, std::max(-1.0, c))) / d;
    }
    normal_ = n, at_ = at, valid_ = true;
  }
  double turn_tolerance_ = 0;   // radians; 0: off
  double turn_rate_ = -1;       // radians per metre between the last two readings (< 0: unknown)
  std::uint64_t reads_ = 0, whole_reads_ = 0;
  Eigen::Vector3d at_ = Eigen::Vector3d::Zero(), normal_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d pending_at_ = Eigen::Vector3d::Zero();  // where the reading ahead started
  bool valid_ = false;
  // read()'s readings before the last, most recent first (read_ahead() keeps only the last).
  std::array<Eigen::Vector3d, kEarlierReadings> earlier_at_{}, earlier_normal_{};
  std::size_t n_earlier_ = 0;
  bool pending_ = false;        // a reading ahead is under way in the scratch
  bool ahead_blocked_ = false;  // it did not fit the scratch: read at once until the next reading
  std::size_t calls_ = 0;       // read_ahead() calls since the last reading
  std::size_t ahead_share_ = 0; // steps a call gives the reading ahead
  bool ready_ = false;          // the reading ahead is done (ready_normal_), taken when due
  Eigen::Vector3d ready_normal_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_at_ = Eigen::Vector3d::Zero();  // the last call's point
  double path_ = 0;             // path length since the last reading, m
};

}  // namespace gshaptics
