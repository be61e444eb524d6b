#pragma once
/// @file
/// Continuous collision of a translating tool against the Gaussians (docs/design.md Sec. 8):
/// where along a straight motion the tool ellipsoid first touches a Gaussian
/// ellipsoid, and the contact normal there. The basis of the proxy (god-object) renderer:
/// however thin a shell and however long the step, the first contact along the way is found.
///
/// For one Gaussian: the ellipsoids overlap iff the offset d = c_G - c_T lies in every
/// ellipsoid E_lambda = {d : lambda (1 - lambda) d^T S(lambda)^-1 d <= 1}, S(lambda) =
/// lambda Sigma_G + (1 - lambda) Sigma_T (that is K(lambda) >= 0 for every lambda,
/// Gilitschenski & Hanebeck). Along d(t) = d0 - t u the line enters E_lambda at the smaller root
/// t_e(lambda) of a quadratic; it has entered all of them at t* = max over lambda of t_e. Any
/// lambda gives t_e(lambda) <= t*, so a search that stops short of the maximum reports an
/// earlier, never a later, contact: the tool is never placed past a Gaussian.
///
/// Threading: a SweepQuery belongs to one thread; several may share a world. first_contact()
/// never allocates, locks, logs or throws.

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/tool_ellipsoid.h"

namespace gshaptics {

/// The first contact of a motion.
struct SweepHit {
  bool hit = false;          ///< a Gaussian is touched within the motion
  double t = 1.0;            ///< fraction of the motion at first contact, in [0, 1] (1 when no hit)
  std::uint32_t slot = 0;    ///< the blocking Gaussian's record in CollisionWorld::gaussians()
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< unit contact normal, Gaussian -> tool, world
  int part = 0;              ///< the part of a compound tool that touches (its index in the span)
};

/// Which Gaussians block a sweep: `blocks(context, slot)` is asked for a Gaussian the motion
/// would touch before the best contact found so far; false lets the motion pass it (the proxy's
/// floaters). `known_to_pass(context, slot)` (may be null) is asked before a Gaussian's exact
/// search: true when the filter already knows, at no cost, that it lets the Gaussian pass (a
/// cached answer); the search is then left out (a floater the tool rests in would otherwise be
/// searched at every sweep). It must agree with `blocks`. Empty: every Gaussian blocks. Called on
/// the sweep's thread; must not throw.
struct BlockFilter {
  bool (*blocks)(void* context, std::uint32_t slot) noexcept = nullptr;
  void* context = nullptr;
  bool (*known_to_pass)(void* context, std::uint32_t slot) noexcept = nullptr;
};

/// What the last sweep looked at.
struct SweepCounts {
  std::uint32_t candidates = 0;  ///< in BVH leaves overlapping the swept box
  std::uint32_t prefiltered = 0;  ///< bounding spheres within reach of the path
  std::uint32_t exact = 0;        ///< exact first-contact searches run
  /// Gaussians searched and touched before the contact that the filter let pass (those it knew
  /// beforehand are not searched, nor counted)
  std::uint32_t passed = 0;
  /// Parts whose candidates came from their near list (SweepQuery's `reuse_margin`), and the
  /// near lists built by this sweep
  std::uint32_t reused = 0, rebuilt = 0;
};

/// First-contact time of `tool` translating by `motion` against one Gaussian, as a fraction of
/// the motion: in [0, 1] when it touches within the motion (0 when it already touches at the
/// start and moves further in), +infinity when it does not (a tool that touches at the start
/// and moves away or along the contact plane is not blocked). `normal` (may be null) receives the unit contact normal
/// (Gaussian -> tool). Stops early, returning a value > `stop_above`, once the contact is proven
/// to come later than `stop_above`. `s_io` (may be null): in, a start for the search over the
/// family (s = ln(lambda / (1 - lambda)), e.g. this Gaussian's maximiser at the last sweep; NaN:
/// none); out, the maximiser found when the search ran to the end. A start changes the work,
/// not the answer beyond the search's tolerance (t* to about 1e-12 of the motion), and never
/// gives a later contact.
[[nodiscard]] double sweep_time(const CollisionGaussian& g, const ToolEllipsoid& tool, const Eigen::Vector3d& motion,
                                Eigen::Vector3d* normal = nullptr, double stop_above = 1.0,
                                double* s_io = nullptr) noexcept;

class SweepQuery {
 public:
  /// `max_candidates`: scratch for candidates sorted by their earliest possible contact; more are
  /// still tested, in BVH order.
  ///
  /// `reuse_margin` (world units, >= 0; 0 turns it off): each part keeps a near list, the
  /// Gaussians within its AABB grown by the margin, each with its clearance from the part's core
  /// (the segment of half-length a - b on an elongated part's long axis, the centre of any other)
  /// at the pose it was built: how near any point of the Gaussian comes to that core, bounded
  /// below along the direction between them (its support there). A later sweep of the same part
  /// (same rotation and semi-axes) whose swept box lies in that box and whose centre stays within
  /// a quarter margin of where the list was built takes its candidates from the list instead of
  /// the BVH: it passes over those whose clearance, less how far the part has moved and moves by
  /// the bar, exceeds the part's radius about its core, then those whose clearance from the core
  /// where it is now exceeds that radius plus the bar's motion: they cannot touch it. The others
  /// get the same bounds and exact searches as the BVH's candidates, so the contact is the same
  /// (docs/design.md Sec. 8). For a proxy whose parts rest on the Gaussians for many ticks (a
  /// stylus lying on a surface: each sweep's box holds hundreds of Gaussians near its axis and a
  /// few dozen within reach). A list is built for a sweep with hints that reaches under half the
  /// margin; sweeps reaching farther take the BVH. One SweepQuery per moving tool: parts that
  /// turn every call (a rotation's sub-steps) rebuild every time; give them a query without
  /// reuse. Allocates its lists here (8 x kNearCapacity entries).
  explicit SweepQuery(const CollisionWorld& world, std::size_t max_candidates = 4096, double reuse_margin = 0);
  /// At most this many Gaussians a part's near list (more: that part takes the BVH).
  static constexpr std::size_t kNearCapacity = 2048;

  /// The first Gaussian `tool` touches when its centre moves by `motion` (rotation and axes
  /// fixed; world frame), leaving out the records in `ignore`. `hints` are records tested
  /// first (the last tick's blockers: the likely answer, which then prunes the rest, the BVH
  /// traversal included: it covers only the box swept up to the contact they found). `filter`
  /// decides, in the same pass, whether a Gaussian the motion reaches first blocks it (a
  /// Gaussian it lets pass does not prune the others). A zero or non-finite motion gives no hit.
  /// `limit` in (0, 1]: only contacts at t <= limit count (the earliest contact another part of
  /// a compound tool already found on the same motion: everything later is pruned unseen).
  /// `tolerance` (a fraction of the motion, >= 0; 0: exact): once a contact is found, a Gaussian
  /// touched less than `tolerance` before it is not searched to the end, so the reported t may
  /// lie up to `tolerance` after the first contact (never past the limit, and never when there
  /// is no hit: a motion reported free is free). A caller that stops more than
  /// tolerance x |motion| short of the reported contact overlaps nothing. On a dense shell many
  /// Gaussians are touched within a hair of each other; this spares their searches.
  SweepHit first_contact(const ToolEllipsoid& tool, const Eigen::Vector3d& motion,
                         std::span<const std::uint32_t> ignore = {},
                         std::span<const std::uint32_t> hints = {}, BlockFilter filter = {},
                         double limit = 1.0, double tolerance = 0.0) noexcept;
  /// The first Gaussian any of `parts` (a rigid compound tool: all move by the same `motion`)
  /// touches, in one traversal of the BVH over the union of the parts' swept boxes, with one
  /// sorted list of (Gaussian, part) candidates and one bar: the same contact as the earliest of
  /// the parts' own first_contact() calls (the same t within the tolerance, never later),
  /// SweepHit::part naming the part. A hint is exact-searched against each part its bounds do
  /// not rule out, and the traversal then covers only the boxes swept up to the contact the
  /// hints found. At most kMaxParts parts (more, or an invalid part: no hit).
  SweepHit first_contact(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& motion,
                         std::span<const std::uint32_t> ignore = {},
                         std::span<const std::uint32_t> hints = {}, BlockFilter filter = {},
                         double limit = 1.0, double tolerance = 0.0) noexcept;
  static constexpr std::size_t kMaxParts = 8;
  /// Each part's own first contact along the same `motion`, in one traversal (a bar a part):
  /// hits[j] is what first_contact(parts[j], motion, {}, hints, filter, 1, tolerance) reports,
  /// within the exact search's tolerance. For a compound tool's contact band: how far each part
  /// is from the Gaussians along one direction. `hits` must hold parts.size() entries (fewer:
  /// every hit cleared, none searched).
  void first_contacts(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& motion, std::span<SweepHit> hits,
                      std::span<const std::uint32_t> hints = {}, BlockFilter filter = {},
                      double tolerance = 0.0) noexcept;
  [[nodiscard]] const SweepCounts& counts() const noexcept { return counts_; }
  [[nodiscard]] const CollisionWorld& world() const noexcept { return *world_; }

 private:
  const CollisionWorld* world_;
  struct Candidate {
    double t;  // earliest contact bound
    std::uint32_t slot, part;
  };
  std::vector<Candidate> scratch_;
  // Each Gaussian's last lambda maximiser, direct-mapped by slot (and part): the next search starts there.
  static constexpr std::size_t kStartCache = 1024;
  std::array<std::uint32_t, kStartCache> start_slot_ = filled_slots();
  std::array<float, kStartCache> start_s_{};
  std::array<std::uint8_t, kStartCache> start_part_{};  // the part of a compound tool it was searched against
  std::array<double, kStartCache> start_lambda_{};  // lambda of start_s_
  static constexpr std::array<std::uint32_t, kStartCache> filled_slots() {
    std::array<std::uint32_t, kStartCache> a{};
    for (auto& v : a) v = UINT32_MAX;
    return a;
  }
  SweepCounts counts_;
  // The parts' near lists (reuse_margin): where each was built and what it covers; entries
  // [p * kNearCapacity, + bucket_end[kNearBuckets - 1]) of near_slot_ and near_clear_ (the
  // clearance from the core, rounded down).
  struct NearList {
    bool valid = false;
    // The core: the segment c0 +- half_len axis (a point when half_len is 0)
    Eigen::Vector3d c0 = Eigen::Vector3d::Zero(), axis = Eigen::Vector3d::Zero();
    double half_len = 0;
    Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
    Eigen::Vector3d semi_axes = Eigen::Vector3d::Zero();
    double rho = 0;  // the part lies within rho of its core
    float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    double width = 0;  // the clearance buckets' width
    std::array<std::uint32_t, 8> bucket_end{};  // the list sorted by clearance bucket (kNearBuckets)
    std::uint32_t backoff = 0;    // sweeps to pass before trying again after an overflow
    std::uint32_t overflows = 0;  // builds in a row that overflowed
    // The offset of x (world) from the core's nearest point to it.
    [[nodiscard]] Eigen::Vector3d from_core(const Eigen::Vector3d& center, const double x[3]) const noexcept {
      Eigen::Vector3d v = Eigen::Vector3d(x[0], x[1], x[2]) - center;
      v -= std::clamp(v.dot(axis), -half_len, half_len) * axis;
      return v;
    }
    // The bucket of clearance c: 0 up to rho, j up to rho + j x width, the last beyond.
    [[nodiscard]] std::size_t bucket_of(double c) const noexcept {
      const double over = (c - rho) / width;
      return over <= 0 ? 0 : std::size_t(std::min<double>(double(bucket_end.size() - 1), std::ceil(over)));
    }
  };
  static constexpr std::uint32_t kNearBackoff = 256;
  static constexpr std::size_t kNearBuckets = 8;
  static constexpr double kNearDrift = 0.25;
  std::vector<std::uint32_t> near_tmp_slot_;
  std::vector<float> near_tmp_clear_;
  std::array<std::uint8_t, kNearCapacity> near_tmp_bucket_{};
  double reuse_margin_ = 0;
  // Builds part p's near list at its pose: its core is the segment of half-length `half_len`
  // along `axis` (unit, or zero with half_len 0: its centre) through its centre, `rho` its
  // radius about the core, `half` its AABB's half extent.
  void build_near(std::uint32_t p, const ToolEllipsoid& tool, const Eigen::Vector3d& axis, double half_len,
                  double rho, const Eigen::Vector3d& half) noexcept;
  std::array<NearList, kMaxParts> near_{};
  std::vector<std::uint32_t> near_slot_;
  std::vector<float> near_clear_;
  // One call of sweep_parts, its state and its stages (sweep_query.cpp).
  struct PartsSweep;
  // The sweep of first_contact() and first_contacts(): one bar for all parts (`shared`: the
  // earliest contact, in hits[0]) or one a part (hits[j]).
  void sweep_parts(std::span<const ToolEllipsoid> parts, const Eigen::Vector3d& motion,
                   std::span<const std::uint32_t> ignore, std::span<const std::uint32_t> hints, BlockFilter filter,
                   double limit, double tolerance, bool shared, std::span<SweepHit> hits) noexcept;
};

}  // namespace gshaptics
