#pragma once
/// @file
/// The session layer (gshaptics::session): what a command does around the haptic loop, as library
/// calls, so the CLI and an embedder (or the Python module) do it one way. This part: a world as
/// the commands open it (scene options, registration from a file and overrides, the bundled
/// scene, the world cache folder, the prepared world with the lines a run prints about it), output folders that lose nothing (OutputStage: a failed run
/// keeps the previous results), the frame comment pose files carry, vector parsing and the
/// console progress bar.
///
/// Console: the session prints the CLI's report (stdout) and warnings and progress (stderr);
/// quiet flags silence progress. Errors are InputError naming the file or option.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/servo/object_poses.h"
#include "gshaptics/scene/scene_cut.h"
#include "gshaptics/force/material.h"
#include "gshaptics/error.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/io/scene_loader.h"
#include "gshaptics/servo/haptic_runtime.h"

namespace gshaptics::session {

/// Exit status of a run that completed but could not write its outputs (disk full, read-only).
inline constexpr int kExitOutputsLost = 4;

/// SceneOptions::min_opacity when the user gave none: the force model decides.
inline constexpr float kModelMinOpacity = -1.0f;

/// How a session opens a scene: the options every scene-consuming command shares (the CLI binds
/// them to --min-opacity, --sigma, --registration, --reg-*, --up and --world-cache).
struct SceneOptions {
  std::string scene;
  /// Keep alpha > this; kModelMinOpacity (negative): the force model's own default
  /// (default_min_opacity(): 0.2, or 1/255 for the proxy on the seen solid).
  float min_opacity = kModelMinOpacity;
  double sigma = 1.0;
  std::string registration_file;
  std::string reg_scale, reg_rotation, reg_translation;  // empty: not given
  std::string up = "none";  // scene up axis turned to world +z before the registration
  std::string world_cache;  // folder of world caches, "auto", or "" (none)
  /// --object (run, simulate): rigid objects cut from the scene (scene/scene_cut.h); their
  /// Gaussians leave the static world, and MuJoCo moves them (gshaptics::objects).
  std::vector<ObjectSpec> objects;
  /// --support: static parts of the scene the objects stand on (a table top): they stay in the
  /// static world, and MuJoCo gets each one's convex hull (select_supports).
  std::vector<ObjectSpec> supports;
  /// --objects-mjcf: where to write the objects' MuJoCo model (object_model_xml; "" none).
  std::string objects_mjcf;
};

/// The world-cache folder of --world-cache ("auto": $XDG_CACHE_HOME/gshaptics/worlds, else
/// ~/.cache/gshaptics/worlds); "" when off.
std::string world_cache_dir(const SceneOptions& o);

/// Path of the bundled scene (data/truck.splat) and its registration, or "" when not found.
std::string bundled_scene();
std::string bundled_registration();
std::string data_file(const std::string& name);

/// Registration from the file and flags (flags override the file's keys).
SimilarityTransform registration_from(const SceneOptions& o);

/// World configuration from the shared options (opacity filter, sigma, --up, registration). An
/// opacity filter left to the model (kModelMinOpacity) is kDefaultMinOpacity here; a run resolves
/// it first (with_bundled_defaults with its renderer).
WorldConfig world_config_from(const SceneOptions& o);

/// The default output folder of a run on `scene`: runs/<name>-<extension> ("runs/biker-spz"), so
/// that biker.spz and biker.ply never share one.
/// `v` rounded to `decimals` places with negative zeros made positive, for printing
/// ("[0.00, -0.00, 1.00]" reads as a sign that is not there).
Eigen::Vector3d for_print(const Eigen::Vector3d& v, int decimals = 2);

std::string default_out_dir(const std::string& scene);

/// Checks an output folder before any work starts, and changes nothing: InputError naming
/// `option` when the path is a file, when one of `owned` (the names a run writes there) is a
/// folder, or when the folder (or the nearest existing folder above it) is not writable. Returns
/// the folder (the default one for `scene` when `dir` is empty). Outputs go through an
/// OutputStage, so a run that fails leaves the previous run's results as they were and creates
/// no folder.
std::string prepare_out_dir(const std::string& dir, const std::string& scene,
                            const std::vector<std::string>& owned, const std::string& option = "--out");

/// A run's outputs, written into a private folder first (under the system's temporary folder)
/// and moved into the output folder only by commit(): each of `owned` that was written replaces
/// the old one (rename; a copy then rename across file systems), each that was not is removed
/// (a stale figure after a --no-plot re-run), so the folder holds one run's outputs. Destroyed
/// without commit(), it removes its private folder and the output folder is untouched.
class OutputStage {
 public:
  OutputStage(std::string final_dir, std::vector<std::string> owned);
  ~OutputStage();
  OutputStage(const OutputStage&) = delete;
  OutputStage& operator=(const OutputStage&) = delete;
  /// Where to write now: stage_dir() + "/" + name.
  [[nodiscard]] const std::string& stage_dir() const noexcept { return stage_; }
  [[nodiscard]] std::string path(const std::string& name) const { return stage_ + "/" + name; }
  /// Where a file ends up.
  [[nodiscard]] std::string final_path(const std::string& name) const { return final_ + "/" + name; }
  /// Creates the output folder and moves the outputs in. Throws InputError naming the folder.
  void commit();

 private:
  std::string final_, stage_;
  std::vector<std::string> owned_;
};

/// The frame options as one comment line that pose files carry ("# frame: up=auto
/// registration=... reg-scale=... reg-rotation=... reg-translation=..."), so that `query --poses`
/// can tell when it reads poses made in another world frame.
std::string frame_comment(const SceneOptions& o);
/// The options of a frame comment line that differ from `o` ("up: file auto, here none"); empty
/// when they agree or `line` is not a frame comment.
std::vector<std::string> frame_mismatches(const std::string& line, const SceneOptions& o);

/// Loads a scene with a progress bar on stderr for files over a few MB.
LoadedScene load_with_progress(const std::string& path, bool quiet = false, bool keep_color = false);

/// `gshaptics info`: loads `so.scene` and prints its format, counts, load report, bounds,
/// opacity and scale percentiles and the filter's reduction, then the world that --up and the
/// registration make of it and the suggested --up, --reg-scale and tool radius. Throws InputError.
void run_info_command(const SceneOptions& so, bool quiet);

/// "A,B" -> vector; throws InputError naming the option.
Eigen::Vector2d parse_vec2(const std::string& text, const std::string& option);
/// "X,Y,Z" -> vector; throws InputError naming the option.
Eigen::Vector3d parse_vec3(const std::string& text, const std::string& option);
Eigen::Vector4d parse_vec4(const std::string& text, const std::string& option);

/// A one-line progress bar on stderr: "label [#####     ] 45%".
class Progress {
 public:
  explicit Progress(std::string label, bool enabled = true);
  void operator()(double fraction);
  void done();

 private:
  std::string label_;
  bool enabled_;
  int last_ = -1;
};

/// Without SCENE: the bundled Truck and its registration. Throws InputError naming `command`
/// when the bundled scene is missing.
/// The opacity filter left to the model (kModelMinOpacity) becomes `renderer`'s default_min_opacity()
/// (the seen solid keeps the faint Gaussians a viewer draws): every command passes the renderer
/// it will hold the world against (`run` once did not, and its seen solid lost the faint ones).
SceneOptions with_bundled_defaults(SceneOptions so, const std::string& command, const RendererSpec& renderer);

/// True when a registration file, rotation, translation or --reg-scale was given: the world is
/// then meant to be in metres (--up alone turns the scene, it does not change its units).
bool is_scaled(const SceneOptions& so);

/// A loaded scene turned into a world, with the lines `simulate` and `run` print about it.
struct PreparedWorld {
  LoadedScene scene;
  WorldConfig config;
  WorldBuildReport report;
  CollisionWorld world;  ///< the static part when objects were cut out
  /// The objects' Gaussians in the world frame, in the order of SceneOptions::objects.
  std::vector<GaussianScene> objects;
  /// The static supports' Gaussians in the world frame (copies: they are in `world` too).
  std::vector<GaussianScene> supports;
};
/// Loads and builds the world (or maps it from the world cache, --world-cache), printing what it
/// did to `report` (stdout; a command whose stdout is data passes stderr). With objects, the scene
/// is cut first (cut_objects) and the world holds the static part (never cached).
PreparedWorld prepare_world(const SceneOptions& so, bool quiet, std::FILE* report = stdout);

/// A world's rigid objects as a run and its readers see them.
struct SceneObjects {
  /// RuntimeConfig::make_renderer: for each run, the objects' MuJoCo dynamics and an
  /// ObjectRenderer (objects/object_renderer.h). Empty without objects.
  RendererFactory make_renderer;
  /// Every run's dynamics publish their poses and applied wrenches here (the viewer, ROS and the
  /// logs subscribe). Null without objects.
  std::shared_ptr<ObjectPoseChannel> poses;
  /// Each object's body-frame origin in the world at rest, m (RigidObject::rest_origin): a body
  /// pose p, R places a rest-frame point x at R (x - rest_origin) + p.
  std::vector<Eigen::Vector3d> rest_origins;
  /// Each object's Gaussians in its body frame (RigidObject::body), to draw its contacts.
  std::vector<std::shared_ptr<const CollisionWorld>> bodies;
  /// Each object's box: the extents of its hull points (m), centred on its body origin.
  std::vector<Eigen::Vector3d> sizes;
  /// How far each object goes in 1 s untouched (untouched_drift), m and rad.
  std::vector<double> untouched_moved, untouched_turned;
  [[nodiscard]] bool empty() const noexcept { return rest_origins.empty(); }
};

/// The objects of a run for its summary: each one's --object text, mass (kg), friction and the
/// Gaussians cut for it, and with `objects` how far it goes in 1 s untouched
/// (untouched_moved_m, untouched_turned_rad) ([] without objects).
nlohmann::json objects_json(const SceneOptions& so, const PreparedWorld& pw, const SceneObjects* objects = nullptr);

/// The objects of `pw` (specs in so.objects), their MuJoCo dynamics at `rate_hz` on the ground
/// fitted to the scene around them (fit_support_plane). Empty when there are none. Prints a line
/// per object to `report` (nullptr: nowhere). Throws InputError when objects are given to a build without
/// gshaptics::objects.
SceneObjects scene_objects(const PreparedWorld& pw, const SceneOptions& so, double rate_hz,
                           std::FILE* report = stdout);

/// `map` with its colour regions resolved on the colours of the scene file `scene_path` (loaded
/// once more, with its colour: a world and its cache keep none), printing what each selected to
/// `report`; `map` itself when it has no colour region (or is null). Throws InputError naming the
/// map when the scene has no colour.
std::shared_ptr<const MaterialMap> with_scene_colours(std::shared_ptr<const MaterialMap> map,
                                                      const std::string& scene_path, std::FILE* report = stdout);

}  // namespace gshaptics::session
