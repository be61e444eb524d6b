#pragma once
/// @file
/// Ground-truth 3DGS scenes: Gaussians placed on an AnalyticShape the way 3DGS optimisation
/// leaves them (flat discs tangent to the surface, log-normal sizes around the spacing, jittered
/// along the normal and in orientation, a share of low-opacity Gaussians below the filter, a few
/// floaters off the surface). Seeded and byte-reproducible; written as ordinary INRIA PLY with
/// every parameter in the header comments and a JSON sidecar describing the exact surface.

#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "gshaptics/fidelity/analytic_shape.h"
#include "gshaptics/fidelity/capture_defect.h"
#include "gshaptics/io/gaussian_scene.h"

namespace gshaptics {

/// How the Gaussians are drawn. Lengths in metres, angles in degrees.
struct SynthParams {
  double spacing = 0.004;            ///< distance between neighbouring Gaussians on the surface
  std::uint64_t seed = 1;
  double scale_log_sigma = 0.25;     ///< in-plane scales: spacing * exp(N(0, this))
  double thin_min = 0.02, thin_max = 0.10;  ///< thin axis as a fraction of the in-plane scale
  double normal_jitter = 0.0005;     ///< position along the normal: N(0, this)
  double tilt_deg = 3.0;             ///< orientation jitter: tilt of the disc normal, N(0, this)
  double low_opacity_share = 0.15;   ///< share with opacity in [0.01, 0.2) (dropped by the filter)
  double floater_share = 0.003;      ///< extra Gaussians floating off the surface (share of surface count)
  double floater_min = 0.005, floater_max = 0.03;  ///< their centre's distance from the surface
  /// A floater's whole ellipsoid stays this far off the surface (its centre's distance less its
  /// largest semi-axis) and, grown by this much, touches none of the surface's Gaussians that the
  /// default world keeps (the discs overhanging an edge): a floater is a Gaussian in free space.
  /// One that reached the surface's discs would be a bump the analytic answer does not know (on
  /// the 8 mm plane of seed 36 a 7.2 mm one 7.7 mm up held the side-on stylus 7.5 mm above it).
  double floater_clearance = 0.002;
  /// > 0: discs near a convex edge (the cube's, the plates' rims) narrowed across it, their
  /// standard deviation toward the edge at most the distance to it over this many (a trained
  /// capture's crisp edges; AnalyticShape::convex_borders). 0: every disc sized alike, edges
  /// included, so a face's discs overhang its edge: at 8 mm spacing the cube's top face is seen
  /// (median depth) up to 8 mm past the edge and its side faces 6 mm above the top. 1.17 (a disc
  /// of opacity 0.99 alone is seen no farther out than the edge) leaves 1-3 mm of that at 8 mm
  /// and sees the corners within 0.5 mm; 2 leaves no lip but opens the corners (seen through at 4
  /// and 8 mm: bench/RESULTS.md, hundred-and-fifth session). In [0, 10].
  double edge_sigmas = 0;
  static constexpr double kMaxEdgeSigmas = 10;  ///< edge_sigmas' upper bound
  /// The suggested edge_sigmas (crisp edges: a disc of opacity 0.99 alone is seen no farther out
  /// than the edge; bench/FIDELITY-crisp-edges.md).
  static constexpr double kCrispEdgeSigmas = 1.17;
  /// Patches where the surface has what real captures leave (fidelity/capture_defect.h); none by
  /// default. Outside its patches a scene is the defect-free one, Gaussian for Gaussian.
  std::vector<CaptureDefect> defects;
};

/// A generated scene and what made it.
struct SyntheticScene {
  GaussianScene scene;           ///< RDF frame as any PLY; coordinates are the shape's (metres)
  std::size_t surface_count = 0;  ///< Gaussians on the surface (the first ones)
  std::size_t floater_count = 0;  ///< then the floaters
  nlohmann::json description() const;  ///< shape, exact surface, every parameter, counts
  AnalyticShape shape{ShapeKind::kPlane};
  SynthParams params;
};

/// Draws the Gaussians of `shape` with `params`. Throws InputError for a spacing outside
/// [0.5 mm, 5 cm] or shares outside [0, 1].
[[nodiscard]] SyntheticScene make_synthetic_scene(const AnalyticShape& shape, const SynthParams& params);

/// Writes `s` as INRIA PLY at `path` (parameters as header comments) and its description as
/// JSON at `path` + ".json" (both atomically). Throws InputError naming the file.
void write_synthetic_scene(const std::string& path, const SyntheticScene& s);

}  // namespace gshaptics
