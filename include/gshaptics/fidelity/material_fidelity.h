#pragma once
/// @file
/// Materials against their settings (issue 74's ground truth): the plane with two materials side
/// by side, "soft" for x < 0 and "hard" for x >= 0 in the scene's frame (two_material_map()).
/// Each side is pressed (its stiffness against the material's coupling stiffness) and one slide
/// 2 mm deep at 5 cm/s crosses the border at x = 0 (each side's mean -F_x / mean F_z, the
/// friction against the slide's direction over the normal force, away
/// from the border by 3 tool radii, against its mu_k; the largest force step per tick within
/// 3 tool radii of the border against the safety layer's rate limit). Every number is the force
/// the servo step commands (safety layer and execution mode included), as the other fidelity
/// scenarios (interaction.h).

#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/fidelity/interaction.h"
#include "gshaptics/force/material.h"
#include "gshaptics/force/renderer_spec.h"

namespace gshaptics {

/// The two materials of the ground-truth plane.
struct TwoMaterials {
  double soft_stiffness = 600, soft_mu_s = 0.4, soft_mu_k = 0.3;    ///< N/m; coefficients
  double hard_stiffness = 1500, hard_mu_s = 0.8, hard_mu_k = 0.6;
};

/// The map: "soft" claims the box x in [-1e3, 0], "hard" x in [0, 1e3] (scene frame, m; the hard
/// side takes x = 0), both wholly across y and z.
[[nodiscard]] nlohmann::json two_material_json(const TwoMaterials& m = {});
[[nodiscard]] MaterialMap two_material_map(const TwoMaterials& m = {});

/// One side of the plane at one density and tool.
struct MaterialRow {
  std::string side;  ///< "soft" or "hard"
  double spacing = 0, tool_radius = 0;  ///< m
  int presses = 0;
  double stiffness_set = 0, stiffness = 0;  ///< N/mm: the material's, the presses' median
  double mu_k = 0, tangential_over_normal = 0;  ///< the material's; the slide's on this side (mean -F_x / mean F_z)
  double border_step = 0;  ///< N, largest |F(t) - F(t - dt)| within 3 R of the border (same on both rows)
  double rate_limit = 0;   ///< N per tick: the safety layer's max_force_rate x dt
};

/// The two-material plane's rows at one density: `world` is the plane's world, `spec` the proxy
/// (its material map is replaced by two_material_map()), `play` how scripts are played.
/// `presses` sites per side. Throws InputError when `spec` is not the proxy on the ellipsoids.
[[nodiscard]] std::vector<MaterialRow> run_material_cases(const CollisionWorld& world, const RendererSpec& spec,
                                                          double spacing, double tool_radius, double rate_hz,
                                                          const PlayOptions& play, int presses, std::size_t* ticks);

/// The Markdown table of the rows, with a verdict per row (stiffness and F_t / F_n within 5 % of
/// the setting, the border's step under the rate limit).
[[nodiscard]] std::string material_table(const std::vector<MaterialRow>& rows);

}  // namespace gshaptics
