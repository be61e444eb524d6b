#pragma once
/// @file
/// Stability trials: a simulated device held against a wall through the full servo step
/// (SimulatedRuntime: the same safety layer, passivity controller and execution mode as a live
/// run), and whether the contact settles or oscillates. `gshaptics stability` sweeps them; the
/// device-model validation (tests/stability_test.cpp) bisects them for the limit stiffness.
///
/// A trial: the device starts `start_gap` above the wall (the plane z = 0 of the world, normal +z)
/// with the hand pushing it down (HandImpedance::push), and runs for `duration`. The tool's
/// height along the normal, as the runtime read it, is cut into windows of `window` seconds after
/// `settle`; the amplitude of a window is half its peak-to-peak. The contact is stable when the
/// last window's amplitude is below `decay` times the first's (the oscillation dies out), or below
/// `rest_amplitude` (it is at rest). A growing oscillation and a limit cycle (bouncing) are
/// unstable.

#include <memory>
#include <string>
#include <vector>

#include "gshaptics/force/force_renderer.h"
#include "gshaptics/servo/haptic_runtime.h"

namespace gshaptics {

/// How a trial is judged. Seconds and metres.
struct WallTrialOptions {
  double duration = 3.0;        ///< simulated time, s
  double settle = 0.5;          ///< the first windows start this late, s
  double window = 0.25;         ///< s
  double decay = 0.9;           ///< stable: last amplitude < decay * first amplitude
  double rest_amplitude = 2e-6; ///< or the last amplitude below this, m (at rest)
};

/// What a trial measured. Forces in N, lengths in m, energies in J.
struct WallTrialResult {
  bool stable = false;
  double first_amplitude = 0, last_amplitude = 0;  ///< m (half peak-to-peak of the height)
  double growth = 0;          ///< last / first amplitude (0 when both are 0)
  double mean_depth = 0;      ///< mean height below the wall over the last window, m (> 0: inside)
  double min_energy = 0;      ///< the passivity observer's lowest energy, J (< 0: active)
  double peak_force = 0;      ///< N, sent
  std::uint64_t passivity_ticks = 0;
  double peak_damping = 0;    ///< N s/m
  std::vector<double> time, height, force;  ///< per tick: s, m (along +z), N (z component sent)
};

/// Runs one trial: `device` (started and stopped by the runtime) driven by `renderer` with
/// `config` (its duration is replaced by options.duration). Throws what SimulatedRuntime throws.
[[nodiscard]] WallTrialResult run_wall_trial(HapticDevice& device, std::unique_ptr<ForceRenderer> renderer,
                                             RuntimeConfig config, const WallTrialOptions& options = {});

/// Judges a height trace (s, m) as run_wall_trial does; fills stable, amplitudes and growth.
void judge_wall_trace(const std::vector<double>& time, const std::vector<double>& height,
                      const WallTrialOptions& options, WallTrialResult& result);

}  // namespace gshaptics
