// `gshaptics synth SHAPE OUT.ply`: a ground-truth 3DGS scene (a thin CLI over
// fidelity/synthetic_scene.h).

#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "options.h"
#include "gshaptics/fidelity/material_fidelity.h"
#include "gshaptics/fidelity/synthetic_scene.h"
#include "gshaptics/fidelity/texture_fidelity.h"
#include "gshaptics/io/scene_writer.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/scene/scene_cut.h"

namespace gshaptics::cli {

namespace {

// `synth grating OUT.ply --grating LAMBDA_MM,A_MM`.
template <typename Options>
void write_grating(const Options& o) {
  if (std::filesystem::path(o.out).extension() != ".ply")
    throw InputError("synth: " + o.out + ": the output must be a .ply file");
  const Eigen::Vector2d la = parse_vec2(o.grating, "--grating");
  GratingParams g;
  g.wavelength = la[0] * 1e-3;
  g.amplitude = la[1] * 1e-3;
  const GaussianScene s = make_grating_scene(g);
  write_scene(o.out, s);
  fmt::print("wrote      {} ({} Gaussians: a grating of wavelength {:g} mm, amplitude {:g} mm, ridges along y)\n", o.out,
             s.size(), la[0], la[1]);
}

// `synth box-on-floor OUT.ply`: a box to push (--object) on a floor, both of Gaussians.
template <typename Options>
void write_box_on_floor(const Options& o) {
  if (std::filesystem::path(o.out).extension() != ".ply")
    throw InputError("synth: " + o.out + ": the output must be a .ply file");
  const BoxOnFloor b = box_on_floor(Eigen::Vector3d(0.05, 0.04, 0.03), Eigen::Vector2d(0.25, 0.18), o.params.spacing);
  write_scene(o.out, b.scene);
  fmt::print("wrote      {} ({} Gaussians: a 10 x 8 x 6 cm box on a 50 x 36 cm floor, z up, spacing {:g} mm)\n"
             "try        gshaptics serve {} --up z-up --object {}\n",
             o.out, b.scene.size(), o.params.spacing * 1e3, o.out, b.object_spec);
}

}  // namespace

void register_synth(CLI::App& app) {
  struct Options {
    std::string shape, out;
    SynthParams params;
    std::vector<std::string> defects;
    std::string two_materials;
    std::string grating = "2,0.1";
  };
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "synth",
      "Write a ground-truth 3DGS scene: Gaussians on an analytic surface (metres) the way 3DGS "
      "optimisation leaves them (flat discs tangent to the surface, log-normal sizes around the "
      "spacing, jittered along the normal and in tilt, a share below the 0.2 opacity filter, a few "
      "floaters). INRIA PLY with every parameter in its header comments, plus OUT.json with the "
      "exact surface. Shapes: plane, sphere, cube, plate-2mm, plate-5mm, cylinder, corner-90, "
      "v-groove-60, grating (--grating), and box-on-floor (a box to push with --object, and the command to). --defect adds what real captures leave: faint layers, a hole, large flat discs, "
      "clutter behind the surface.");
  cmd->add_option("shape", o->shape, "Shape name")->required();
  cmd->add_option("out", o->out, "Output .ply (and OUT.ply.json)")->required();
  SynthParams& p = o->params;
  cmd->add_option("--spacing", p.spacing, "Gaussian spacing on the surface, m")->capture_default_str()
      ->check(check::range(5e-4, 0.05));
  cmd->add_option("--seed", p.seed, "Random seed")->capture_default_str();
  cmd->add_option("--normal-jitter", p.normal_jitter, "Std of the position along the normal, m")
      ->capture_default_str()->check(check::range(0.0, 0.05));
  cmd->add_option("--tilt", p.tilt_deg, "Std of the disc tilt, degrees")->capture_default_str()->check(check::range(0.0, 45.0));
  cmd->add_option("--low-opacity-share", p.low_opacity_share, "Share with opacity below 0.2")
      ->capture_default_str()->check(check::range(0.0, 1.0));
  cmd->add_option("--floater-share", p.floater_share, "Floaters per surface Gaussian")
      ->capture_default_str()->check(check::range(0.0, 1.0));
  cmd->add_option("--edge-sigmas", p.edge_sigmas,
                  fmt::format("Crisp convex edges (cube, plates): discs near an edge narrowed so their standard "
                              "deviation toward it is at most the distance over this ({}: a disc alone is seen no farther "
                              "than the edge); 0: sized alike, overhanging the edge",
                              SynthParams::kCrispEdgeSigmas))
      ->capture_default_str()->check(check::range(0.0, SynthParams::kMaxEdgeSigmas));
  cmd->add_option("--defect", o->defects,
                  "A capture defect patch, KIND[:RADIUS_MM] (faint-patch, hole, large-flat, interior-clutter; "
                  "radius 15 mm, a hole 4 mm), centred at the surface point nearest (0, 0, 1) m; repeatable");
  cmd->add_option("--two-materials", o->two_materials,
                  "Also write a material map (JSON, for --materials) with two materials side by side: soft for x < 0, "
                  "hard for x >= 0 (the fidelity's two-material plane)")
      ->type_name("FILE");
  cmd->add_option("--grating", o->grating,
                  "For the shape 'grating': the relief's wavelength and amplitude in mm, LAMBDA_MM,A_MM (a plane with "
                  "A sin(2 pi x / lambda), Gaussians every lambda / 8 across the ridges; A = 0: the plane without relief)")
      ->capture_default_str();
  cmd->callback([o] {
    // (An option that does not apply is refused: only the cube's and the plates' faces end at
    // convex edges.)
    if (o->params.edge_sigmas > 0 &&
        (o->shape == "grating" || o->shape == "box-on-floor" ||
         !AnalyticShape(parse_shape(o->shape, "synth")).has_convex_edges()))
      throw InputError("synth: --edge-sigmas applies to the shapes with convex edges (cube, plate-2mm, plate-5mm), not '" +
                       o->shape + "'");
    if (o->shape == "grating") {
      write_grating(*o);
      return;
    }
    if (o->shape == "box-on-floor") {
      write_box_on_floor(*o);
      return;
    }
    for (const std::string& spec : o->defects) o->params.defects.push_back(parse_capture_defect(spec, "synth --defect"));
    const ShapeKind kind = parse_shape(o->shape, "synth");
    if (std::filesystem::path(o->out).extension() != ".ply")
      throw InputError("synth: " + o->out + ": the output must be a .ply file");
    const SyntheticScene s = make_synthetic_scene(AnalyticShape(kind), o->params);
    write_synthetic_scene(o->out, s);
    for (const CaptureDefect& d : o->params.defects)
      fmt::print("defect     {} within {:g} mm of the surface point nearest ({:g}, {:g}, {:g}) m\n", to_string(d.kind),
                 d.radius * 1e3, d.at.x(), d.at.y(), d.at.z());
    fmt::print("wrote      {} ({} Gaussians on the surface, {} floaters, spacing {:g} mm, seed {})\n"
               "surface    {}.json\n",
               o->out, s.surface_count, s.floater_count, o->params.spacing * 1e3, o->params.seed, o->out);
    if (!o->two_materials.empty()) {
      write_file_atomically(o->two_materials, two_material_json().dump(2) + "\n");
      fmt::print("materials  {} (soft for x < 0, hard for x >= 0)\n", o->two_materials);
    }
  });
}

}  // namespace gshaptics::cli
