#include "gshaptics/session/object_session.h"

#include <fmt/core.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "gshaptics/io/atomic_file.h"
#include "gshaptics/objects/object_renderer.h"
#include "gshaptics/session/report_session.h"

namespace gshaptics::session {
namespace {

constexpr const char* kLog = "push_log.csv";
constexpr const char* kSummary = "summary.json";
constexpr const char* kFigure = "push_run.png";

std::string push_log_csv(const PushRun& run) {
  std::ostringstream csv;
  csv.precision(9);
  csv << "t_s,hand_x,hand_y,hand_z,device_x,device_y,device_z,box_x,box_y,box_z,box_vx,box_vy,box_vz,box_turn_rad,"
         "push_x,push_y,push_z,k_min\n";
  for (const PushSample& s : run.samples) {
    csv << s.t;
    for (const Eigen::Vector3d* v : {&s.hand, &s.device, &s.box, &s.box_velocity})
      csv << ',' << v->x() << ',' << v->y() << ',' << v->z();
    csv << ',' << s.box_turn << ',' << s.push.x() << ',' << s.push.y() << ',' << s.push.z() << ',' << s.k_min << '\n';
  }
  return csv.str();
}

nlohmann::json push_summary(const PushRun& run, const SimulateOptions& o) {
  const PushScenario& sc = run.scenario;
  nlohmann::json j;
  j["scenario"] = "push";
  j["box"] = {{"half_extents_m", {sc.box_half.x(), sc.box_half.y(), sc.box_half.z()}},
              {"mass_kg", sc.mass},
              {"friction", sc.friction},
              {"spacing_m", sc.spacing}};
  j["tool_radius_m"] = sc.tool_radius;
  j["force_model"] = renderer_name(o.force.spec());
  j["travelled_m"] = run.travelled;
  j["sliding_ticks"] = run.sliding_ticks;
  j["friction_felt_N"] = run.friction_estimate;
  j["friction_expected_N"] = run.friction_expected;
  j["friction_felt_over_expected"] = run.friction_expected > 0 ? run.friction_estimate / run.friction_expected : 0.0;
  j["deepest_k_min"] = run.deepest_k_min;
  j["deepest_box_depth_m"] = run.deepest_box_depth;
  j["energy_peak_J"] = run.peak_energy;
  j["energy_lowest_J"] = run.lowest_energy;
  j["passivity"] = o.safety.passivity.enabled ? "on" : "off (observed only)";
  j["ticks"] = run.runtime.ticks;
  j["rate_hz"] = run.runtime.rate_hz;
  return j;
}

// A warning for each object that falls, slides or tips by itself in its first second; returns
// how far each goes.
UntouchedDrift warn_untouched_drift(std::span<const RigidObject> objects, const SupportPlane& support,
                                    const DynamicsParams& dp, const SupportFit& fit) {
  const UntouchedDrift drift = untouched_drift(objects, support, dp);
  std::fflush(stdout);  // (the report so far comes first)
  for (std::size_t i = 0; i < objects.size(); ++i)
    if (drift.moved[i] > kUntouchedDriftWarn || drift.turned[i] > kUntouchedTurnWarn)
      fmt::print(stderr,
                 "warning: object {} ({}) moves {:.3f} m and turns {:.0f} deg in its first second untouched: it does "
                 "not stand on its support as cut{}; the viewer shows it where it goes. Check the cut, or name what "
                 "it stands on with --support\n",
                 i, objects[i].spec.text, drift.moved[i], drift.turned[i] * 180 / M_PI,
                 fit.fitted ? fmt::format(" (the ground fitted around it has an RMS of {:.0f} mm)", 1e3 * fit.rms) : "");
  return drift;
}

}  // namespace

SceneObjects object_scene(const PreparedWorld& pw, const SceneOptions& so, double rate_hz, std::FILE* report) {
  auto objects = std::make_shared<std::vector<RigidObject>>();
  for (std::size_t i = 0; i < pw.objects.size(); ++i) {
    objects->push_back(make_rigid_object(pw.objects[i], so.objects[i], pw.config));
    const RigidObject& o = objects->back();
    if (report != nullptr)
      fmt::print(report, "object     {}: {} Gaussians kept, {:.3g} kg, mu {:.3g}, {} convex piece{}, at [{:.3f}, {:.3f}, {:.3f}]\n", i,
                 o.body->size(), o.spec.mass, o.spec.friction, o.piece_ends.size(), o.piece_ends.size() == 1 ? "" : "s",
                 o.rest_origin.x(), o.rest_origin.y(), o.rest_origin.z());
  }
  // With static supports (a table top), the ground is the floor around them, and their hulls
  // are static bodies the objects stand on.
  std::vector<RigidObject> supports;
  for (std::size_t i = 0; i < pw.supports.size(); ++i)
    supports.push_back(make_rigid_object(pw.supports[i], so.supports[i], pw.config));
  const ObjectSupport held = object_support(pw.world, *objects, supports);
  const SupportFit& fit = held.fit;
  const SupportPlane& support = held.plane;
  if (report != nullptr) {
    if (fit.fitted)
      fmt::print(report, "support    a plane fitted to {} Gaussians of the scene around the {} (RMS {:.1f} mm, "
                 "{:.1f} deg from up) through [{:.3f}, {:.3f}, {:.3f}]; MuJoCo at {:.0f} Hz\n",
                 fit.points, supports.empty() ? "objects" : "supports", 1e3 * fit.rms, fit.tilt * 180 / M_PI, support.point.x(), support.point.y(),
                 support.point.z(), rate_hz);
    else
      fmt::print(report, "support    no ground around the {} in the scene: a plane under their lowest point, "
                 "normal the world's up, through [{:.3f}, {:.3f}, {:.3f}]; MuJoCo at {:.0f} Hz\n",
                 supports.empty() ? "objects" : "supports", support.point.x(), support.point.y(), support.point.z(), rate_hz);
    for (std::size_t i = 0; i < held.base.size(); ++i)
      if (held.base[i] != 0)
        fmt::print(report, "object     {}: seated on the ground: as cut its hull's lowest point stood {:.3f} m {} it ({}; the "
                   "hand feels its Gaussians as captured)\n", i, std::abs(held.base[i]), held.base[i] > 0 ? "above" : "under",
                   held.base[i] > 0 ? "its bottom pieces now reach down to it" : "the points under it are raised onto it");
  }
  DynamicsParams dp;
  dp.timestep = 1.0 / rate_hz;
  const UntouchedDrift drift = warn_untouched_drift(*objects, support, dp, fit);
  if (!so.objects_mjcf.empty()) {
    write_file_atomically(so.objects_mjcf, object_model_xml(*objects, support, dp));
    if (report != nullptr) fmt::print(report, "mjcf       {} (the objects' MuJoCo model)\n", so.objects_mjcf);
  }
  SceneObjects out;
  out.poses = std::make_shared<ObjectPoseChannel>();
  out.untouched_moved.assign(drift.moved.begin(), drift.moved.begin() + std::ptrdiff_t(objects->size()));
  out.untouched_turned.assign(drift.turned.begin(), drift.turned.begin() + std::ptrdiff_t(objects->size()));
  for (const RigidObject& o : *objects) {
    out.rest_origins.push_back(o.rest_origin);
    out.bodies.push_back(o.body);
    Eigen::AlignedBox3d box;
    for (const Eigen::Vector3d& p : o.hull_points) box.extend(p);
    out.sizes.push_back(box.sizes());
  }
  // The whole scene (the static part joined with the objects where they stand untouched), built
  // once for every run's renderer on this static world.
  std::shared_ptr<const WholeSceneWorld> whole = whole_scene_world(pw.world, *objects, drift);
  out.make_renderer = [objects, support, dp, channel = out.poses, whole, base = pw.world.gaussians().data()](
                          const CollisionWorld& world, const RendererSpec& spec,
                          const QueryOptions& query) -> std::unique_ptr<ForceRenderer> {
    auto dynamics = std::make_shared<ObjectDynamics>(*objects, support, dp, channel);
    WholeSceneOptions captured;
    if (world.gaussians().data() == base) captured.world = whole;
    return make_object_renderer(spec, world, *objects, std::move(dynamics), query, std::move(captured));
  };
  return out;
}

PushScenario push_scenario_from(const SimulateOptions& o) {
  PushScenario sc;
  if (o.object_mass) sc.mass = *o.object_mass;
  if (o.object_friction) sc.friction = *o.object_friction;
  sc.runtime.rate_hz = o.rate;
  sc.runtime.renderer = o.force.spec();
  sc.runtime.inline_query = o.exec.inline_query;
  sc.runtime.latency_ticks = o.exec.latency_ticks;
  sc.runtime.safety = o.safety;
  sc.runtime.safety.f_max = o.force.f_max;
  sc.runtime.control = o.control;
  return sc;
}

int run_simulate_push(const SimulateOptions& o) {
  const std::string out_dir = prepare_out_dir(o.out_dir, "push.box", {kLog, kSummary, kFigure});
  const PushScenario sc = push_scenario_from(o);
  fmt::print("scenario   push: a {:.0f} x {:.0f} x {:.0f} cm box of Gaussians, {:.3g} kg, mu {:.3g}, on a floor of "
             "Gaussians; a sphere of {:.0f} mm radius pushes it along +x\n",
             200 * sc.box_half.x(), 200 * sc.box_half.y(), 200 * sc.box_half.z(), sc.mass, sc.friction,
             1e3 * sc.tool_radius);
  fmt::print("rate       {:.0f} Hz of simulated time, {}; dynamics: MuJoCo at the servo rate\n", o.rate,
             describe_execution(o.exec, true));
  std::fflush(stdout);
  Progress bar("simulating", !o.quiet);
  const PushRun run = run_push_scenario(sc, [&](double f) { bar(f); });
  bar.done();

  OutputStage stage(out_dir, {kLog, kSummary, kFigure});
  try {
    write_file_atomically(stage.path(kLog), push_log_csv(run));
    write_file_atomically(stage.path(kSummary), push_summary(run, o).dump(2) + "\n");
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: the run completed, but {}\nnote: {} is left as it was\n", e.what(), out_dir);
    return kExitOutputsLost;
  }
  fmt::print("box        travelled {:.1f} cm; slid on {} ticks; friction felt {:.3f} N against mu m g = {:.3f} N "
             "({:+.1f} %)\n", 100 * run.travelled, run.sliding_ticks, run.friction_estimate, run.friction_expected,
             run.friction_expected > 0 ? 100 * (run.friction_estimate / run.friction_expected - 1) : 0.0);
  fmt::print("contact    the tool at its proxy at most {:.2f} mm into the box's faces; deepest K_min of its "
             "Gaussians there {:.2g}{}\n", 1e3 * run.deepest_box_depth, run.deepest_k_min,
             run.deepest_k_min < 1e-3 ? " (never inside their ellipsoids)" : "");
  fmt::print("passivity  {}: energy into the scene and the box at most {:.3g} mJ, lowest {:.3g} mJ (below 0: "
             "energy given to the hand)\n", o.safety.passivity.enabled ? "on" : "off (observed only)",
             1e3 * run.peak_energy, 1e3 * run.lowest_energy);
  int rc = 0;
  if (run.sliding_ticks == 0) {
    fmt::print(stderr, "error: the box never slid (the push stayed below mu m g)\n");
    rc = 1;
  }
  const bool plotted = !o.no_plot && run_python(find_tool_script("plot_push_object.py"),
                                                 {stage.path(kLog), stage.path(kSummary), stage.path(kFigure)},
                                                 "simulate --scenario push");
  if (!o.no_plot && !plotted) rc = 1;
  stage.commit();
  fmt::print("log        {}\nsummary    {}\n", stage.final_path(kLog), stage.final_path(kSummary));
  if (plotted) fmt::print("figure     {}\n", stage.final_path(kFigure));
  return rc;
}

}  // namespace gshaptics::session
