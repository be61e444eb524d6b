#include "gshaptics/force/proxy_params.h"

#include <array>
#include <cmath>
#include <string>

#include "gshaptics/error.h"

namespace gshaptics {

namespace {

bool finite_at_least(double x, double lo) { return std::isfinite(x) && x >= lo; }
bool finite_positive(double x) { return std::isfinite(x) && x > 0; }

void fail(std::string_view who, const std::string& what) { throw InputError(std::string(who) + ": " + what); }

constexpr ProxyParams kDefaults{};

// The table of tool-specific fields: one row each, with its option and why the other tool has no use for it.
const std::array<ProxyToolField, 10> kToolFields{{
    {"device_shading", "--device-shading", ProxyTool::kOnePart,
     [](const ProxyParams& p) { return p.device_shading == kDefaults.device_shading; },
     [](ProxyParams& p) { p.device_shading = kDefaults.device_shading; },
     "a compound tool's parts read the shaded normal where each touches"},
    {"corner_normal", "--corner-normal", ProxyTool::kOnePart,
     [](const ProxyParams& p) { return p.corner_normal == kDefaults.corner_normal; },
     [](ProxyParams& p) { p.corner_normal = kDefaults.corner_normal; },
     "a compound tool keeps the shaded normal at corners (its parts read clean edges and faces)"},
    {"overhang_falloff", "--overhang-falloff", ProxyTool::kOnePart,
     [](const ProxyParams& p) { return p.overhang_falloff == kDefaults.overhang_falloff; },
     [](ProxyParams& p) { p.overhang_falloff = kDefaults.overhang_falloff; },
     "a compound tool's parts read the shaded normal without the overhang falloff"},
    {"shading_budget", "", ProxyTool::kOnePart,
     [](const ProxyParams& p) { return p.shading_budget == kDefaults.shading_budget; },
     [](ProxyParams& p) { p.shading_budget = kDefaults.shading_budget; },
     "a compound tool's parts read their shaded normals whole"},
    {"rot_stiffness", "", ProxyTool::kCompound,
     [](const ProxyParams& p) { return p.rot_stiffness == kDefaults.rot_stiffness; },
     [](ProxyParams& p) { p.rot_stiffness = kDefaults.rot_stiffness; },
     "a one-part tool at its centre point is not turned by the proxy"},
    {"rot_damping", "", ProxyTool::kCompound,
     [](const ProxyParams& p) { return p.rot_damping == kDefaults.rot_damping; },
     [](ProxyParams& p) { p.rot_damping = kDefaults.rot_damping; },
     "a one-part tool at its centre point is not turned by the proxy"},
    {"rotation_step", "", ProxyTool::kCompound,
     [](const ProxyParams& p) { return p.rotation_step == kDefaults.rotation_step; },
     [](ProxyParams& p) { p.rotation_step = kDefaults.rotation_step; },
     "a one-part tool at its centre point is not turned by the proxy"},
    {"max_rotation_steps", "", ProxyTool::kCompound,
     [](const ProxyParams& p) { return p.max_rotation_steps == kDefaults.max_rotation_steps; },
     [](ProxyParams& p) { p.max_rotation_steps = kDefaults.max_rotation_steps; },
     "a one-part tool at its centre point is not turned by the proxy"},
    {"near_lists", "--near-lists", ProxyTool::kCompound,
     [](const ProxyParams& p) { return p.near_lists == kDefaults.near_lists; },
     [](ProxyParams& p) { p.near_lists = kDefaults.near_lists; },
     "the one-ellipsoid proxy's sweeps read the BVH"},
    {"face_average", "--face-average", ProxyTool::kCompound,
     [](const ProxyParams& p) { return p.face_average == kDefaults.face_average; },
     [](ProxyParams& p) { p.face_average = kDefaults.face_average; },
     "the one-ellipsoid proxy's normal is the shaded field (with its corner normal)"},
}};

}  // namespace

void validate_proxy_params(const ProxyParams& p, std::string_view who) {
  if (!finite_positive(p.stiffness)) fail(who, "stiffness must be > 0 N/m");
  if (!finite_at_least(p.damping, 0)) fail(who, "damping must be >= 0 N s/m");
  if (!(finite_at_least(p.mu_s, 0) && finite_at_least(p.mu_k, 0) && p.mu_k <= p.mu_s))
    fail(who, "friction needs 0 <= mu_k <= mu_s");
  if (p.substeps < 1 || p.substeps > 16) fail(who, "substeps must be in [1, 16]");
  if (!finite_at_least(p.lift, 0)) fail(who, "lift must be >= 0 tool radii");
  if (!finite_at_least(p.isolation_gap, 0)) fail(who, "isolation_gap must be >= 0");
  if (p.floater_cluster < 1 || p.floater_cluster > FloaterRule::kLargestCluster)
    fail(who, "floater_cluster must be in [1, " + std::to_string(FloaterRule::kLargestCluster) + "]");
  if (!finite_at_least(p.shading_turn, 0)) fail(who, "shading_turn must be >= 0 degrees");
  if (!finite_positive(p.shading_tail)) fail(who, "shading_tail must be > 0");
  if (!finite_at_least(p.shading_reuse, 0)) fail(who, "shading_reuse must be >= 0 tool radii");
  if (!finite_at_least(p.device_shading, 0)) fail(who, "device_shading must be >= 0 tool radii");
  if (!finite_positive(p.shading_kernel) || !finite_positive(p.teleport) || !finite_at_least(p.tau_opacity, 0))
    fail(who, "shading_kernel and teleport must be > 0, tau_opacity >= 0");
  if (!finite_at_least(p.rot_stiffness, 0) || !finite_at_least(p.rot_damping, 0))
    fail(who, "rotational stiffness and damping must be >= 0");
  if (!(p.rotation_step > 0 && p.rotation_step <= 1) || p.max_rotation_steps < 1)
    fail(who, "rotation_step must be in (0, 1] and max_rotation_steps >= 1");
}

std::span<const ProxyToolField> tool_specific_proxy_fields() noexcept { return kToolFields; }

ProxyParams proxy_params_for(const ProxyParams& p, ProxyTool tool) {
  ProxyParams out = p;
  for (const ProxyToolField& f : kToolFields)
    if (f.serves != tool) f.reset(out);
  return out;
}

void check_proxy_params_apply(const ProxyParams& p, ProxyTool tool, std::string_view who) {
  std::string refused;
  for (const ProxyToolField& f : kToolFields) {
    if (f.serves == tool || f.at_default(p)) continue;
    refused += std::string(refused.empty() ? "" : "; ") + std::string(f.name);
    if (!f.option.empty()) refused += " (" + std::string(f.option) + ")";
    refused += " serves " + std::string(f.serves == ProxyTool::kCompound ? "compound tools" : "one-part tools") +
               " only: " + std::string(f.why_not);
  }
  if (!refused.empty()) fail(who, refused);
}

}  // namespace gshaptics
