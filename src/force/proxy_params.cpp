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

// Whether `p` holds the field `Member` at its default (kDefaults), for both tables' rows.
template <auto Member>
bool at_default(const ProxyParams& p) {
  return p.*Member == kDefaults.*Member;
}

// A row of the table for the field `Member`: its default is read from kDefaults.
template <auto Member>
constexpr ProxyToolField field(std::string_view name, std::string_view option, ProxyTool serves, std::string_view why_not) {
  return {name, option, serves, &at_default<Member>, [](ProxyParams& p) { p.*Member = kDefaults.*Member; }, why_not};
}

// The table of tool-specific fields: one row each, with its option and why the other tool has no use for it.
const std::array<ProxyToolField, 12> kToolFields{{
    field<&ProxyParams::device_shading>("device_shading", "--device-shading", ProxyTool::kOnePart,
                                 "a compound tool's parts read the shaded normal where each touches"),
    field<&ProxyParams::corner_normal>("corner_normal", "--corner-normal", ProxyTool::kOnePart,
                                 "a compound tool keeps the shaded normal at corners (its parts read clean edges and faces)"),
    field<&ProxyParams::crest_hold>("crest_hold", "--crest-hold", ProxyTool::kOnePart,
                                 "a compound tool's parts slide on a crest as on a face"),
    field<&ProxyParams::overhang_falloff>("overhang_falloff", "--overhang-falloff", ProxyTool::kOnePart,
                                 "a compound tool's parts read the shaded normal without the overhang falloff"),
    field<&ProxyParams::shading_budget>("shading_budget", "", ProxyTool::kOnePart,
                                 "a compound tool's parts read their shaded normals whole"),
    field<&ProxyParams::seen_footprint>("seen_footprint", "--seen-footprint", ProxyTool::kOnePart,
                                 "a compound tool's parts meet the seen solid at their leading points (the footprint is the sphere's)"),
    field<&ProxyParams::rot_stiffness>("rot_stiffness", "", ProxyTool::kCompound,
                                 "a one-part tool at its centre point is not turned by the proxy"),
    field<&ProxyParams::rot_damping>("rot_damping", "", ProxyTool::kCompound,
                                 "a one-part tool at its centre point is not turned by the proxy"),
    field<&ProxyParams::rotation_step>("rotation_step", "", ProxyTool::kCompound,
                                 "a one-part tool at its centre point is not turned by the proxy"),
    field<&ProxyParams::max_rotation_steps>("max_rotation_steps", "", ProxyTool::kCompound,
                                 "a one-part tool at its centre point is not turned by the proxy"),
    field<&ProxyParams::near_lists>("near_lists", "--near-lists", ProxyTool::kCompound,
                                 "the one-ellipsoid proxy's sweeps read the BVH"),
    field<&ProxyParams::face_average>("face_average", "--face-average", ProxyTool::kCompound,
                                 "the one-ellipsoid proxy's normal is the shaded field (with its corner normal)"),
}};

// A row of the surface table for the field `Member`.
template <auto Member>
constexpr ProxySurfaceField surface_field(std::string_view name, std::string_view option, ProxySurface serves,
                                          std::string_view why_not) {
  return {name, option, serves, &at_default<Member>, why_not};
}

constexpr std::string_view kNoEllipsoids = "the seen solid has no ellipsoids to sweep, shade or pass as floaters";

// The table of surface-specific fields.
const std::array<ProxySurfaceField, 13> kSurfaceFields{{
    surface_field<&ProxyParams::opacity_stiffness>("opacity_stiffness", "--opacity-stiffness", ProxySurface::kEllipsoids,
                                                   "the seen solid's surface is already where the opacity composites to 1/2"),
    surface_field<&ProxyParams::substeps>("substeps", "--substeps", ProxySurface::kEllipsoids,
                                          "the seen solid searches each motion's whole segment"),
    surface_field<&ProxyParams::energy_bound>("energy_bound", "--energy-bound", ProxySurface::kEllipsoids,
                                              "it bounds the ellipsoid proxy's shaded normal's turns"),
    surface_field<&ProxyParams::device_shading>("device_shading", "--device-shading", ProxySurface::kEllipsoids, kNoEllipsoids),
    surface_field<&ProxyParams::corner_normal>("corner_normal", "--corner-normal", ProxySurface::kEllipsoids, kNoEllipsoids),
    surface_field<&ProxyParams::crest_hold>("crest_hold", "--crest-hold", ProxySurface::kEllipsoids,
                                            "the seen normal on a convex crease is already the rigid sphere's"),
    surface_field<&ProxyParams::overhang_falloff>("overhang_falloff", "--overhang-falloff", ProxySurface::kEllipsoids,
                                                  kNoEllipsoids),
    surface_field<&ProxyParams::near_lists>("near_lists", "--near-lists", ProxySurface::kEllipsoids, kNoEllipsoids),
    surface_field<&ProxyParams::face_average>("face_average", "--face-average", ProxySurface::kEllipsoids, kNoEllipsoids),
    surface_field<&ProxyParams::isolation_gap>("isolation_gap", "--isolation-gap", ProxySurface::kEllipsoids,
                                               "the seen solid keeps every Gaussian a viewer draws"),
    surface_field<&ProxyParams::floater_cluster>("floater_cluster", "--floater-cluster", ProxySurface::kEllipsoids,
                                                 "the seen solid keeps every Gaussian a viewer draws"),
    surface_field<&ProxyParams::seen_window>("seen_window", "--seen-window", ProxySurface::kSeen,
                                             "the ellipsoid proxy's solid does not depend on where it is seen from"),
    surface_field<&ProxyParams::seen_footprint>("seen_footprint", "--seen-footprint", ProxySurface::kSeen,
                                                "the ellipsoid proxy's sweep holds the whole sphere already"),
}};

}  // namespace

std::string_view proxy_surface_name(ProxySurface s) noexcept { return s == ProxySurface::kSeen ? "seen" : "ellipsoids"; }

ProxySurface proxy_surface_from(std::string_view name, std::string_view who) {
  for (ProxySurface s : {ProxySurface::kEllipsoids, ProxySurface::kSeen})
    if (name == proxy_surface_name(s)) return s;
  fail(who, "--surface must be ellipsoids or seen, not '" + std::string(name) + "'");
  return ProxySurface::kSeen;  // (not reached)
}

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
  if (!finite_positive(p.seen_window)) fail(who, "seen_window must be > 0 tool radii");
  if (!(p.rotation_step > 0 && p.rotation_step <= 1) || p.max_rotation_steps < 1)
    fail(who, "rotation_step must be in (0, 1] and max_rotation_steps >= 1");
  std::string refused;
  for (const ProxySurfaceField& f : kSurfaceFields) {
    if (f.serves == p.surface || f.at_default(p)) continue;
    refused += std::string(refused.empty() ? "" : "; ") + std::string(f.name) + " (" + std::string(f.option) +
               ") serves the surface " + std::string(proxy_surface_name(f.serves)) + " only (--surface " +
               std::string(proxy_surface_name(f.serves)) + "): " + std::string(f.why_not);
  }
  if (!refused.empty()) fail(who, refused);
}

std::span<const ProxyToolField> tool_specific_proxy_fields() noexcept { return kToolFields; }

std::span<const ProxySurfaceField> surface_specific_proxy_fields() noexcept { return kSurfaceFields; }

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
