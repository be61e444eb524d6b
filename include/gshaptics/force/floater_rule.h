#pragma once
/// @file
/// The floater rule of the proxies (ProxyParams::pass_isolated): a Gaussian that no other kept
/// Gaussian supports is a floater (an optimisation artefact hanging in free space) and does not
/// block the god-object. Shared by the one-ellipsoid proxy (ProxySolver) and the compound proxy.
///
/// Threading: one thread; isolated() and the filter never allocate, lock, log or throw.

#include <array>
#include <cstdint>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/collision/sweep_query.h"

namespace gshaptics {

class FloaterRule {
 public:
  /// `max_cluster`: the largest clump the rule passes (1: single Gaussians only; at most
  /// kLargestCluster).
  explicit FloaterRule(const CollisionWorld& world, std::size_t max_cluster = kMaxCluster);
  /// Whether the Gaussian in `slot` is a floater: no other kept Gaussian overlaps its ellipsoid
  /// grown on every semi-axis by `gap` (m) or its middle semi-axis, whichever is smaller; or it
  /// belongs to a small clump in free space: its overlap cluster (the Gaussians so grown that
  /// overlap it, theirs, and so on) has at most `max_cluster` members, and no Gaussian outside the
  /// cluster overlaps a member grown by its own largest semi-axis. (3DGS floaters come in
  /// small clumps; a clump of a surface's discs has neighbours about one disc size away.)
  /// Cached per slot (the last kCacheSize answers) while `gap` stays the same; a clump's
  /// members are cached together. At most 2 max_cluster early-exit queries, on small
  /// ellipsoids; a Gaussian of a dense surface costs one.
  bool isolated(std::uint32_t slot, double gap) noexcept;
  /// The largest overlap cluster the floater rule passes by default (ProxyParams::floater_cluster).
  static constexpr std::size_t kMaxCluster = 3;
  /// The largest one it can be asked to pass.
  static constexpr std::size_t kLargestCluster = 4;
  /// Forgets the cached answers.
  void reset() noexcept { state_.fill(0); }
  /// Uncached isolation tests one tick may run through a Filter; past them a Gaussian blocks.
  static constexpr int kQueriesPerTick = 16;

  /// A SweepQuery BlockFilter for one tick: a Gaussian blocks unless it is a floater; once
  /// `budget` uncached tests ran, every Gaussian not known to be a floater blocks (the safe side).
  /// With `pass_floaters` false (ProxyParams::pass_isolated off) every Gaussian blocks.
  class Filter {
   public:
    Filter(FloaterRule& test, double gap, bool pass_floaters = true, int budget = kQueriesPerTick) noexcept
        : test_(&test), gap_(gap), left_(budget), on_(pass_floaters) {}
    /// The BlockFilter to hand to SweepQuery (valid while this Filter lives); it knows the
    /// cached floaters beforehand (BlockFilter::known_to_pass). Empty (everything blocks) when off.
    [[nodiscard]] BlockFilter block_filter() noexcept {
      return on_ ? BlockFilter{&Filter::blocks, this, &Filter::known_to_pass} : BlockFilter{};
    }

   private:
    FloaterRule* test_;
    double gap_;
    int left_;
    bool on_;
    static bool blocks(void* context, std::uint32_t slot) noexcept;
    static bool known_to_pass(void* context, std::uint32_t slot) noexcept;
  };

 private:
  static constexpr std::size_t kCacheSize = 64;
  const CollisionWorld* world_;
  ContactQuery query_;  // early-exit queries only
  std::array<std::uint32_t, kCacheSize> slot_{};
  std::array<std::uint8_t, kCacheSize> state_{};  // 0: empty, 1: supported, 2: isolated
  std::size_t next_ = 0;
  std::size_t max_cluster_;
  double gap_ = -1;  // the gap the cache was filled with
  // 0: not cached, 1: supported, 2: isolated.
  int cached(std::uint32_t slot, double gap) noexcept;
  void remember(std::uint32_t slot, bool alone) noexcept;
  // The cluster of members[0] (n = 1 on entry) is a small clump in free space; `members` and
  // `n` end as the cluster found so far.
  bool isolated_cluster(double gap, std::array<std::uint32_t, kLargestCluster>& members, std::size_t& n) noexcept;
};

}  // namespace gshaptics
