#include "gshaptics/fidelity/stability.h"

#include <algorithm>
#include <cmath>

#include "gshaptics/servo/simulated_runtime.h"

namespace gshaptics {

void judge_wall_trace(const std::vector<double>& time, const std::vector<double>& height,
                      const WallTrialOptions& options, WallTrialResult& result) {
  // Half peak-to-peak of the height in each window after the settling time.
  std::vector<double> amplitudes;
  double lo = INFINITY, hi = -INFINITY, window_end = options.settle + options.window;
  double sum = 0;
  std::size_t count = 0;
  double last_mean = 0;
  for (std::size_t i = 0; i < time.size() && i < height.size(); ++i) {
    if (time[i] < options.settle) continue;
    if (time[i] >= window_end) {
      if (lo <= hi) amplitudes.push_back(0.5 * (hi - lo));
      if (count > 0) last_mean = sum / double(count);
      lo = INFINITY;
      hi = -INFINITY;
      sum = 0;
      count = 0;
      while (time[i] >= window_end) window_end += options.window;
    }
    lo = std::min(lo, height[i]);
    hi = std::max(hi, height[i]);
    sum += height[i];
    ++count;
  }
  // A last window at least half full counts.
  if (lo <= hi && count > 0) {
    const double covered = time.empty() ? 0 : time.back() - (window_end - options.window);
    if (covered >= 0.5 * options.window || amplitudes.empty()) {
      amplitudes.push_back(0.5 * (hi - lo));
      last_mean = sum / double(count);
    }
  }
  result.mean_depth = -last_mean;
  if (amplitudes.empty()) {
    result.stable = false;
    result.first_amplitude = result.last_amplitude = result.growth = 0;
    return;
  }
  result.first_amplitude = amplitudes.front();
  result.last_amplitude = amplitudes.back();
  result.growth = result.first_amplitude > 0 ? result.last_amplitude / result.first_amplitude : 0;
  result.stable = result.last_amplitude < options.rest_amplitude ||
                  (amplitudes.size() > 1 && result.last_amplitude < options.decay * result.first_amplitude);
}

WallTrialResult run_wall_trial(HapticDevice& device, std::unique_ptr<ForceRenderer> renderer,
                               RuntimeConfig config, const WallTrialOptions& options) {
  config.duration = options.duration;
  SimulatedRuntime runtime(device, config, std::move(renderer));
  runtime.run();
  WallTrialResult r;
  const auto& records = runtime.log().records();
  r.time.reserve(records.size());
  r.height.reserve(records.size());
  r.force.reserve(records.size());
  double min_energy = 0;
  for (const TickRecord& rec : records) {
    r.time.push_back(rec.time);
    r.height.push_back(rec.position.z());
    r.force.push_back(rec.force.z());
    min_energy = std::min(min_energy, rec.energy);
  }
  judge_wall_trace(r.time, r.height, options, r);
  const RuntimeSummary s = runtime.summary();
  r.min_energy = min_energy;
  r.peak_force = s.peak_force;
  r.passivity_ticks = s.passivity_ticks;
  r.peak_damping = s.passivity_peak_damping;
  return r;
}

}  // namespace gshaptics
