#pragma once
/// @file
/// Writing the runtime's per-tick log.

#include <string>
#include <vector>

#include "gshaptics/servo/servo_controller.h"
#include "gshaptics/sim/probe_run.h"

namespace gshaptics {

/// Writes the per-tick log as CSV to a temporary name, then renames. The first 17 columns are
/// those of the probe run's log (time_s, x, y, z, vx, vy, vz, candidates, prefiltered, contacts,
/// fx, fy, fz, user_fx, user_fy, user_fz, query_us), so the same plot and replay read both; then
/// desired_fx/fy/fz (force model before safety), jitter_us, tick_us, result_age_us, held
/// (0/1: a stale result was held), fading (0/1: faded or fading) and flags (SafetyFlag bits).
/// Throws InputError naming the file when it cannot be written.
void write_servo_log_csv(const std::string& path, const std::vector<ServoTickRecord>& records);

/// The probe-run view of the log (time, pose, counts, force sent, user force, query time), for
/// find_episodes() and the like.
[[nodiscard]] std::vector<TickRecord> to_tick_records(const std::vector<ServoTickRecord>& records);

}  // namespace gshaptics
