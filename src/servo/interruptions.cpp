#include "gshaptics/servo/interruptions.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "gshaptics/percentile.h"

namespace gshaptics {

double InterruptionProfile::hit_probability(double us) const noexcept {
  if (!(us > 0) || !(per_second > 0)) return 0;
  return 1.0 - std::exp(-per_second * us * 1e-6);
}

InterruptionProfile interruption_profile(std::span<const double> gaps_us, double seconds, double threshold_us) {
  InterruptionProfile p;
  p.seconds = seconds;
  p.threshold_us = threshold_us;
  p.count = gaps_us.size();
  if (gaps_us.empty()) return p;
  std::vector<double> g(gaps_us.begin(), gaps_us.end());
  p.median_us = percentile(g, 50);
  p.p99_us = percentile(g, 99);
  p.max_us = *std::max_element(g.begin(), g.end());
  if (seconds > 0) {
    double lost = 0;
    for (double x : g) lost += x;
    p.per_second = double(p.count) / seconds;
    p.lost_fraction = lost * 1e-6 / seconds;
  }
  return p;
}

InterruptionProfile measure_interruptions(const Clock& clock, double seconds, double threshold_us) {
  std::vector<double> gaps;
  gaps.reserve(1 << 16);
  const Nanos start = clock.now();
  const Nanos end = start + to_nanos(seconds);
  const Nanos threshold = to_nanos(threshold_us * 1e-6);
  Nanos last = start;
  for (;;) {
    const Nanos now = clock.now();
    if (now - last > threshold) gaps.push_back(double(now - last) * 1e-3);
    last = now;
    if (now >= end) break;
  }
  return interruption_profile(gaps, to_seconds(last - start), threshold_us);
}

}  // namespace gshaptics
