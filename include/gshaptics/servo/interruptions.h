#pragma once
/// @file
/// How often, and for how long, the machine takes the CPU away from a running thread: the gaps
/// between consecutive clock reads of a thread that does nothing else. This is how real-time
/// Linux measures hardware and hypervisor latency (hwlatdetect, sysjitter, jitterdebugger: spin
/// on a clock, record every gap above a threshold). A latency percentile that is rarer than the
/// interruptions are frequent includes them: a query of t us is hit with probability about
/// 1 - exp(-rate * t), so once that passes 1 % the p99 is the query plus one interruption.

#include <cstdint>
#include <span>

#include "gshaptics/device/clock.h"

namespace gshaptics {

/// The gaps a spinning thread saw.
struct InterruptionProfile {
  double seconds = 0;         ///< how long the thread spun, s
  double threshold_us = 0;    ///< gaps longer than this were counted, us
  std::uint64_t count = 0;    ///< gaps counted
  double per_second = 0;      ///< count / seconds, 1/s
  double median_us = 0;       ///< of the counted gaps, us (0 when none)
  double p99_us = 0;          ///< of the counted gaps, us
  double max_us = 0;          ///< of the counted gaps, us
  double lost_fraction = 0;   ///< summed gaps / seconds: the share of the core taken away

  /// Probability that a computation of `us` microseconds is hit by at least one interruption,
  /// taking arrivals as Poisson at per_second: 1 - exp(-per_second * us * 1e-6).
  [[nodiscard]] double hit_probability(double us) const noexcept;
};

/// The profile of a list of gaps (us, each already above `threshold_us`) seen while spinning for
/// `seconds`. Pure; `seconds` <= 0 gives rates of 0.
[[nodiscard]] InterruptionProfile interruption_profile(std::span<const double> gaps_us, double seconds,
                                                       double threshold_us);

/// Spins on `clock` for `seconds`, recording every gap between consecutive reads longer than
/// `threshold_us`, and returns their profile. Run it on the core (and with the scheduling
/// class) the measured work will use. Allocates (the gap list); not for a servo tick.
[[nodiscard]] InterruptionProfile measure_interruptions(const Clock& clock, double seconds = 0.5,
                                                        double threshold_us = 5.0);

}  // namespace gshaptics
