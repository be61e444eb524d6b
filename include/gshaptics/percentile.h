#pragma once
/// @file
/// Percentiles of a sample, for reports and summaries (not for the servo tick: it copies).

#include <algorithm>
#include <cmath>
#include <vector>

namespace gshaptics {

/// Percentile `p` in [0, 100] (clamped) of `values` by nearest rank, on a copy; 0 for an
/// empty sample.
[[nodiscard]] inline double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  const double pos = std::clamp(p, 0.0, 100.0) / 100.0 * double(values.size() - 1);
  const auto k = std::size_t(std::llround(pos));
  std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(k), values.end());
  return values[k];
}

}  // namespace gshaptics
