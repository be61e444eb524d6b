// `gshaptics poses SCENE`: seeded tool poses in the format `query --poses` reads.

#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "options.h"
#include "gshaptics/sim/pose_sampler.h"

namespace gshaptics::cli {

void register_poses(CLI::App& app) {
  auto o = std::make_shared<SceneOptions>();
  auto p = std::make_shared<PoseSamplerParams>();
  auto uniform = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "poses",
      "Print seeded tool poses, one per line (cx cy cz ax ay az qw qx qy qz, world frame), for "
      "`gshaptics query --poses`. Near-surface by default: centred within one tool radius of a "
      "kept Gaussian. Tool radii are fractions of the scene's 1-99 percentile extent.");
  cmd->add_option("scene", o->scene, "Scene file (any format gshaptics reads: INRIA PLY, compressed PLY, .splat, SPZ)")->required();
  cmd->add_option("--count", p->count, "Number of poses")->capture_default_str()->check(CLI::Range(1, 100000000));
  cmd->add_option("--seed", p->seed, "Random seed")->capture_default_str();
  cmd->add_option("--radius-min", p->radius_min, "Smallest tool radius (fraction of extent)")
      ->capture_default_str()->check(check::positive());
  cmd->add_option("--radius-max", p->radius_max, "Largest tool radius (fraction of extent)")
      ->capture_default_str()->check(check::positive());
  cmd->add_flag("--uniform", *uniform, "Centres uniform in the 1-99 percentile box instead");
  cmd->add_flag("--anisotropic", p->anisotropic, "Random ellipsoids (axis ratios down to 1/3)");
  add_world_options(*cmd, *o);
  cmd->callback([o, p, uniform] {
    if (p->radius_min > p->radius_max)
      throw InputError(fmt::format("--radius-min {:g} is above --radius-max {:g}", p->radius_min, p->radius_max));
    const LoadedScene s = load_with_progress(o->scene);
    const WorldConfig cfg = world_config_from(*o);
    const CollisionWorld world = CollisionWorld::build(s.scene, cfg);
    PoseSamplerParams params = *p;
    params.near_surface = !*uniform;
    fmt::print("# {} poses on {} (seed {}, tool radius {}..{} of extent {:.6g}, {})\n",
               params.count, o->scene, params.seed, params.radius_min, params.radius_max,
               robust_extent(world), params.near_surface ? "near surface" : "uniform");
    fmt::print("{}\n", frame_comment(*o));
    for (const ToolEllipsoid& t : sample_poses(world, params))
      fmt::print("{:.9g} {:.9g} {:.9g} {:.9g} {:.9g} {:.9g} {:.9g} {:.9g} {:.9g} {:.9g}\n",
                 t.center.x(), t.center.y(), t.center.z(), t.semi_axes.x(), t.semi_axes.y(),
                 t.semi_axes.z(), t.rotation.w(), t.rotation.x(), t.rotation.y(), t.rotation.z());
  });
}

}  // namespace gshaptics::cli
