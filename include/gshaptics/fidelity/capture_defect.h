#pragma once
/// @file
/// Capture defects for the ground-truth scenes: what trained real captures do to a surface and
/// the analytic scenes otherwise lack (issue 71, item 5). A defect replaces the synthetic
/// surface's Gaussians in a patch (the surface samples within `radius` of the sample nearest
/// `at`) by what a capture leaves there; outside the patch the scene is the defect-free one,
/// Gaussian for Gaussian. The analytic surface stays the ground truth: a renderer that is right
/// feels it through the defect.
/// - faint patch: every disc becomes `faint_layers` discs of opacity below the 0.2 filter,
///   spread along the normal and in the plane, that composite to an opaque surface (seen-felt's
///   measurements found such layers where the ellipsoid proxy let the tool through);
/// - hole: no Gaussians in the patch (a hole smaller than the tool; neighbours' discs still
///   overhang its rim);
/// - large flat: the patch is covered by a few large, flat, opaque discs (`large_factor` times
///   the spacing) instead of many small ones;
/// - interior clutter: the surface is kept, and as many Gaussians again float behind it, between
///   `clutter_depth_min` and `clutter_depth_max` under the surface (the inside of a trained shell).

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "gshaptics/fidelity/analytic_shape.h"

namespace gshaptics {

enum class DefectKind { kFaintPatch, kHole, kLargeFlat, kInteriorClutter };

/// Every defect, in report order.
[[nodiscard]] const std::vector<DefectKind>& all_defects();
/// "faint-patch", "hole", "large-flat", "interior-clutter".
[[nodiscard]] std::string_view to_string(DefectKind kind);
/// Throws InputError naming `source` for another name.
[[nodiscard]] DefectKind parse_defect(std::string_view name, const std::string& source);

/// One defect patch. Lengths in metres, in the shape's frame.
struct CaptureDefect {
  DefectKind kind = DefectKind::kFaintPatch;
  double radius = 0.015;  ///< the patch: surface samples within this of its centre
  /// The patch's centre is the surface sample nearest this point (default: straight above the
  /// origin, i.e. the top of the plane, sphere, cube and plates).
  Eigen::Vector3d at = Eigen::Vector3d(0, 0, 1);
  int faint_layers = 8;                    ///< faint patch: discs per sample
  double faint_opacity_min = 0.10, faint_opacity_max = 0.19;
  double large_factor = 3.0;               ///< large flat: disc grid and semi-axes, in spacings
  double clutter_depth_min = 0.003, clutter_depth_max = 0.03;  ///< interior clutter, under the surface

  /// The defaults of `kind` (radius 15 mm; a hole 4 mm, smaller than the benchmark's tools).
  [[nodiscard]] static CaptureDefect of(DefectKind kind);
  [[nodiscard]] nlohmann::json describe() const;
  /// Throws InputError naming `source` for a radius <= 0, layers < 1 or an opacity or depth
  /// range out of order.
  void validate(const std::string& source) const;
};

/// The centre of `d`'s patch on `shape` drawn at `spacing`: the surface sample nearest d.at.
[[nodiscard]] Eigen::Vector3d patch_center(const AnalyticShape& shape, const CaptureDefect& d, double spacing);

/// One patch of each kind with its defaults (CaptureDefect::of), in report order, and a second
/// hole of 7 mm (wider than the 4 mm one, which the neighbours' discs nearly close at 4 mm
/// spacing; narrower than a 10 mm tool).
[[nodiscard]] std::vector<CaptureDefect> default_capture_defects();

/// "KIND" or "KIND:RADIUS_MM" (e.g. "hole:4"). Throws InputError naming `source`.
[[nodiscard]] CaptureDefect parse_capture_defect(std::string_view spec, const std::string& source);

}  // namespace gshaptics
