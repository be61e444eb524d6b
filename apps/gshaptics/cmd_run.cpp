// `gshaptics run [SCENE]`: the real-time runtime. A servo thread at --rate drives a device
// (simulated admittance device + simulated hand, a replayed pose log, or a vendor device) and
// computes each force inside its tick (--inline, the default) or takes it from the collision
// worker thread (--decoupled, the paper's split, Sec. IV-V); prints a live status line, then the
// summary; writes servo_log.csv, run_summary.json and run.png (Fig. 5 plus a jitter row).

#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/error.h"

namespace gshaptics::cli {

void register_run(CLI::App& app) {
  auto o = std::make_shared<RuntimeOptions>();
  CLI::App* cmd = app.add_subcommand(
      "run",
      "Real-time haptic runtime: a servo thread at --rate (absolute deadlines, real-time priority "
      "when granted) drives the device; the query and force renderer run inside the tick (or "
      "--decoupled, on a collision worker thread); the safety layer holds, fades, ramps and limits "
      "the force (min of --f-max and the device's own limit). Live status on stderr; Ctrl-C stops "
      "cleanly with the device at zero force. --simulated-time runs sim and replay devices through "
      "the same step on simulated time. Writes servo_log.csv, run_summary.json and run.png (paper "
      "Fig. 5 + jitter row).");
  add_runtime_options(*cmd, *o,
                      "one of" + registry_device_help(false).substr(1) + " (`gshaptics devices` says which this machine has)");
  add_object_option(*cmd, o->scene);
  cmd->callback([o] {
    const SceneOptions so = with_bundled_defaults(o->scene, "run", o->force.spec());
    std::unique_ptr<HapticDevice> opened = validate_runtime_options(*o, /*allow_mouse=*/false);  // before the scene load
    if (o->simulated_time && o->device != "sim" && o->device.rfind("replay:", 0) != 0)
      throw InputError("--simulated-time: only the sim and replay:FILE devices run on simulated time, not '" +
                       o->device + "'");
    prepare_run_out_dir(*o, so);
    const PreparedWorld pw = prepare_world(so, o->quiet);
    o->force.materials = with_scene_colours(o->force.materials, so.scene);
    warn_if_outside_profile(pw, o->force);
    RuntimeSetup setup = make_runtime_setup(*o, so, pw, false, std::move(opened));
    if (o->simulated_time) {
      SimulatedRuntime sim(pw.world, *setup.device, setup.config);
      Progress bar("simulating", !o->quiet);
      sim.run([&](double f) { bar(f); });
      bar.done();
      if (const int rc = write_run_outputs(sim, *o, so, pw, setup, "run")) set_exit_code(rc);
      return;
    }
    HapticRuntime rt(pw.world, *setup.device, setup.config);
    const bool interrupted = run_live(rt, setup.planned, o->quiet);
    if (const int rc = write_run_outputs(rt, *o, so, pw, setup, interrupted, "run")) set_exit_code(rc);
  });
}

}  // namespace gshaptics::cli
