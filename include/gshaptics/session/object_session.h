#pragma once
/// @file
/// `gshaptics simulate --scenario push` (issue 72): the simulated hand pushes a box of Gaussians
/// across a floor of Gaussians through the servo step, the box's dynamics on MuJoCo
/// (objects/push_scenario.h). Built when gshaptics::objects is (GSHAPTICS_HAVE_OBJECTS).

#include "gshaptics/objects/push_scenario.h"
#include "gshaptics/session/probe_session.h"

namespace gshaptics::session {

/// scene_objects() of a build with objects: builds each RigidObject of `pw` once (immutable,
/// shared by the runs) and a factory making, per run, its ObjectDynamics (publishing to the
/// returned channel) and ObjectRenderer.
SceneObjects object_scene(const PreparedWorld& pw, const SceneOptions& so, double rate_hz, std::FILE* report);

/// The scenario `o` describes: its rate, force model, execution mode, safety layer and control
/// (the scene, sites, seed and tool are not used: the scenario brings its own), with the box's
/// mass and friction.
[[nodiscard]] PushScenario push_scenario_from(const SimulateOptions& o);

/// Runs the push scenario and writes push_log.csv (one row a tick), summary.json (the box's
/// travel, the friction felt against mu m g, whether the tool ever entered the box, the
/// runtime) and push_run.png (the box's path, the contact force, the friction; unless
/// o.no_plot) to o.out_dir (default runs/push-box), through an OutputStage. Returns the exit
/// code: 0, 1 when the box never slid or the figure failed, kExitOutputsLost.
int run_simulate_push(const SimulateOptions& o);

}  // namespace gshaptics::session
