#pragma once
/// @file
/// The simulated probe run (the main job): a simulated user drives a simulated admittance
/// device along a probe trajectory, on simulated time through SimulatedRuntime: the same servo
/// step, safety layer and execution mode as a real-time run (servo/simulated_runtime.h), so the
/// forces it reports are the ones the hand would get.

#include <Eigen/Core>
#include <functional>

#include "gshaptics/collision/compound_tool.h"
#include <memory>
#include <string>
#include <vector>

#include "gshaptics/collision/contact_query.h"
#include "gshaptics/force/force_model.h"
#include "gshaptics/force/proxy_renderer.h"
#include "gshaptics/servo/admittance.h"
#include "gshaptics/servo/haptic_runtime.h"
#include "gshaptics/servo/safety.h"
#include "gshaptics/servo/tick_log.h"
#include "gshaptics/device/device_model.h"
#include "gshaptics/sim/probe_trajectory.h"

namespace gshaptics {

/// A contiguous stretch of ticks with contacts (gaps shorter than the merge gap are bridged).
struct ContactEpisode {
  double t_start = 0, t_end = 0;  ///< s
  std::uint32_t peak_contacts = 0;
  double peak_force = 0;  ///< N
  Eigen::Vector3d peak_direction = Eigen::Vector3d::Zero();  ///< unit force direction at the peak
  /// W, J: the energy the hand put into the scene over the episode, -sum F_k . (x_k+1 - x_k) over
  /// its ticks with contacts (the force sent, held over each tick, as the passivity observer
  /// counts it, servo/passivity.h). < 0: the scene gave back more than it took.
  double energy_j = 0;
};

/// Query-time statistics over a run.
struct QueryTimeStats {
  double p50_us = 0, p99_us = 0, max_us = 0;
  std::size_t over_1ms = 0;  ///< ticks whose query exceeded the 1 ms servo period
};

struct ProbeRunParams {
  double rate_hz = kDefaultServoRateHz;  ///< servo rate of the simulation (paper: 1 kHz)
  RendererSpec renderer;              ///< the force renderer and its parameters (default: the proxy)
  RendererFactory make_renderer;      ///< RuntimeConfig::make_renderer (a scene with objects)
  AdmittanceParams device;
  UserHandParams user;
  QueryOptions query;
  SafetyParams safety;        ///< the servo's safety layer, as in a real-time run
  bool inline_query = kDefaultInlineQuery;  ///< query inside the tick; false: the decoupled worker
  int latency_ticks = 1;      ///< decoupled mode: ticks from a pose to its result (>= 1)
  /// A tool with a shape (count 0: a sphere of the trajectory's radius). The simulated hand holds
  /// it at a fixed orientation (the tool frame is the world's; a stylus, along +z, probes tip
  /// first); the simulated device renders force only, so the safety layer drops the torque
  /// (TickRecord::flags has kFlagTorqueDropped on those ticks).
  CompoundTool tool;
  /// Impedance: the ideal mass-damper device, commanded force. Admittance (issue 73): the
  /// simulated robot under a position servo with a force sensor (SimulatedDeviceParams), driven
  /// through the virtual tool (servo/admittance.h); TickRecord::user_force is the sensor's
  /// reading and TickRecord::setpoint the virtual tool.
  ControlParams control;
};

struct ProbeRunResult {
  std::vector<TickRecord> ticks;
  std::vector<ContactEpisode> episodes;
  QueryTimeStats query_time;
};

/// Progress callback: fraction of simulated time done, in [0, 1]. May be empty.
using RunProgressFn = std::function<void(double)>;

/// Runs the whole trajectory (plus 0.5 s) with a spherical tool of the trajectory's radius, or
/// with `params.tool`.
/// `ticks` are the servo's records: `force` is what was commanded (after the safety layer),
/// `desired` what the renderer asked for, `query_us` the wall time of the render.
[[nodiscard]] ProbeRunResult run_probe(const CollisionWorld& world,
                                       const ProbeTrajectory& trajectory,
                                       const ProbeRunParams& params,
                                       const RunProgressFn& progress = {});

/// Groups ticks with contacts into episodes, bridging gaps shorter than `merge_gap_s`; `ticks`
/// in time order (each tick's displacement to the next one counts toward its episode's energy:
/// the device's, or under admittance control (`admittance`) the virtual tool's, TickRecord::setpoint,
/// the body the rendered force acts on).
[[nodiscard]] std::vector<ContactEpisode> find_episodes(const std::vector<TickRecord>& ticks,
                                                        double merge_gap_s = 0.1, bool admittance = false);

/// What an episode's energy W may fall below zero by and still count as passive, J: what the
/// passivity observer's one-tick prediction can miss (a microjoule is 20 N over 50 nm).
inline constexpr double kEnergyTolerance = 1e-6;

/// "" when no episode gave energy back (W < -kEnergyTolerance); else "; N gave energy back, the worst W = X mJ" (for
/// the commands' printed summaries).
[[nodiscard]] std::string active_episodes_note(const std::vector<ContactEpisode>& episodes);

/// What became of one planned probe site (ProbeTrajectory::sites()) in a run. A site's window
/// runs from halfway after the previous site's planned touch to halfway before the next one's
/// (the run's start and end for the first and last).
struct SiteAccount {
  int site = 0;                      ///< 0-based, in the trajectory's order
  double t_planned = 0;              ///< when the target reaches the touch point, s
  double t_window_start = 0, t_window_end = 0;  ///< s
  bool touched = false;              ///< a tick in the window had contacts
  double t_first_contact = 0;        ///< first tick with contacts in the window, s (when touched)
  double peak_force = 0;             ///< largest commanded force in the window, N
  int episodes = 0;                  ///< contact episodes that start in the window (> 1: bounces)
  /// Closest approach of the tool centre to the planned touch point in the window, world units
  /// (a missed site the tool reached says: nothing there to touch; one it never reached says:
  /// the run or the hand did not get there).
  double closest_approach = 0;
};

/// Accounts for every planned site of `trajectory` in `ticks` (sorted by time) and `episodes`
/// (from find_episodes on the same ticks).
[[nodiscard]] std::vector<SiteAccount> account_sites(const ProbeTrajectory& trajectory,
                                                     const std::vector<TickRecord>& ticks,
                                                     const std::vector<ContactEpisode>& episodes);

/// The note a command prints beside a site's row: "" for a site touched once, "N bounces" for
/// more episodes, and for a missed site what it means and what to try with `renderer`'s own
/// options: a tool that came within `tool_radius` (world units) of the planned touch point met
/// nothing the renderer holds there (the ellipsoids: no Gaussian kept by the opacity filter and
/// the floater rule; the seen solid: no layer that composites to half transmittance along the
/// approach; the paper's model: no Gaussian kept); one that never came so close was not brought
/// there by the run or the hand.
[[nodiscard]] std::string site_note(const SiteAccount& a, double tool_radius, const RendererSpec& renderer);

/// p50/p99/max of the ticks' query times.
[[nodiscard]] QueryTimeStats query_time_stats(const std::vector<TickRecord>& ticks);

}  // namespace gshaptics
