#pragma once
/// @file
/// The surface a 3DGS scene shows along a ray: the 3DGS median depth (../shared/DESIGN.md
/// Sec. 2d; the compositing of Kerbl, Kopanas, Leimkuehler and Drettakis 2023, "3D Gaussian
/// Splatting for Real-Time Radiance Field Rendering"). The ground truth the real-scene
/// seen-against-felt benchmark (fidelity/seen_felt.h) holds the force renderers to.
///
/// Every Gaussian of the scene counts (no opacity filter, no floater rule): that is what a
/// viewer draws. Along a ray o + t u (|u| = 1) Gaussian i has its peak at depth
/// t_i = (mu_i - o)^T P_i u / (u^T P_i u) (P_i = Sigma_i^-1) and there the value
/// G_i = exp(-r_i^2 / 2), r_i the ray's Mahalanobis distance to mu_i; its alpha is
/// min(0.99, o_i G_i), and a Gaussian with alpha below 1/255 is skipped, as the 3DGS rasterizer
/// does. Taken in the order of t_i (only t_i > 0: in front of the eye), the optical depth
/// tau(t) = -sum_{t_i <= t} log1p(-alpha_i) grows; the seen depth is the first t_i at which it
/// reaches ln 2 (the transmittance falls to 1/2).
///
/// The frame is the scene's (whatever frame `scene` is given in); lengths in its units.
/// An exact reference: each ray composites every Gaussian whose alpha-1/255 ellipsoid reaches
/// the ray (a bounding-sphere test first), found through a four-wide BVH over the bounding
/// spheres' boxes (broadphase/wide_bvh.h) and taken in the file's order, so the answer is the
/// exhaustive loop's bit for bit (median_depth_exhaustive(), the tests' reference). Not for the
/// servo tick (it allocates).

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "gshaptics/broadphase/wide_bvh.h"

#include "gshaptics/io/gaussian_scene.h"

namespace gshaptics {

/// The seen depth along one ray.
struct SeenDepth {
  bool hit = false;              ///< the transmittance fell to 1/2
  double depth = 0;              ///< t of the seen surface (valid when hit), scene units
  double optical_depth = 0;      ///< tau accumulated over the whole ray (t in (0, t_max])
  std::size_t composited = 0;    ///< Gaussians with alpha >= 1/255 on the ray
  /// The renderer's normal sum up to the seen depth (valid when hit): sum_k T_k alpha_k n_k over
  /// the Gaussians in depth order up to and including the one that makes it, T_k the
  /// transmittance in front of Gaussian k and n_k = -P_k u / |P_k u| the normal of its depth
  /// plane (the plane of its peaks along rays parallel to u). Unnormalised; SeenSolid::normal.
  Eigen::Vector3d shade = Eigen::Vector3d::Zero();
};

/// A seen point with the normal of the seen surface there.
struct SeenPoint {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   ///< o + depth u
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< unit, facing the eye (n . u < 0)
  double depth = 0;
  /// Scene units: the centre's depth minus the mean of the four neighbours' (surface_point()).
  /// About 0 on a face (h^2 / (2 rho) on a surface of curvature radius rho); large where the
  /// centre line threads a gap narrower than 2 h (> 0) or meets a spike narrower than it (< 0).
  double kink = 0;
};

class SeenSurface {
 public:
  /// Keeps every Gaussian of `scene` whose opacity can reach 1/255 (their precision matrices
  /// from scale and rotation; scales below 1e-9 are raised to it).
  explicit SeenSurface(const GaussianScene& scene);

  /// Gaussians held (opacity >= 1/255).
  [[nodiscard]] std::size_t size() const noexcept { return gaussians_.size(); }

  /// The 3DGS median depth along origin + t dir for t in (0, t_max]. `dir` need not be unit
  /// (it is normalised; the depth is in scene units along the unit direction).
  [[nodiscard]] SeenDepth median_depth(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                       double t_max = 1e300) const;
  /// median_depth()'s hit, depth and shade bit for bit, composited front to back in chunks of the
  /// ray and stopped at the seen surface: optical_depth and composited then count the layers up
  /// to it only. The cheap call where only the seen surface matters (surface_point(), the
  /// seen-felt measure's lines).
  [[nodiscard]] SeenDepth first_seen(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                     double t_max = 1e300) const;
  /// first_seen() along many parallel rays origins[i] + t dir (t in (0, inf)) at once, into
  /// out[i]: the Gaussians are binned once on a grid across dir over the rays' spread, so each
  /// ray composites only those whose reach its cell meets (a part's shadow read by thousands of
  /// lines). Throws std::invalid_argument when out and origins differ in size.
  void first_seen_parallel(std::span<const Eigen::Vector3d> origins, const Eigen::Vector3d& dir,
                           std::span<SeenDepth> out) const;
  /// median_depth() by visiting every Gaussian (no BVH): the slow reference the tests hold the
  /// BVH's candidates to.
  [[nodiscard]] SeenDepth median_depth_exhaustive(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                                  double t_max = 1e300) const;

  /// The seen point along the ray and the seen surface's normal there, from the seen depth of
  /// four parallel rays offset by +-`h` (scene units, > 0) across the ray: the normal of the
  /// plane through their four seen points, and the centre's kink against them (SeenPoint::kink).
  /// Empty when any of the five rays sees nothing.
  [[nodiscard]] std::optional<SeenPoint> surface_point(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                                       double h, double t_max = 1e300) const;

 private:
  void build_bvh();  // bvh_, order_, centre_ and radius_ over gaussians_
  struct Entry {
    Eigen::Vector3d mean;
    double m[9];       // whitening diag(1/s) R^T, row-major: |W (x - mean)| is the Mahalanobis distance
    double opacity;
    double reach;      // Euclidean radius beyond which alpha < 1/255
    double r2_far;     // a squared Mahalanobis distance past which alpha < 1/255 for sure (exp not needed)
    Eigen::Matrix3d precision;  // Sigma^-1 = R diag(s^-2) R^T
  };
  struct Layer {
    double t, alpha;
    const Entry* g;
  };
  // The Gaussians whose reach the line origin + t u (|u| = 1) meets, of the BVH's leaves on
  // t in [ta, tb], into `candidates` in ascending order (the file's: ties in depth composite as
  // the exhaustive loop's).
  void gather(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double ta, double tb,
              std::vector<std::uint32_t>& candidates) const;
  // Gaussian i's layer on the ray when its peak lies at t in (after, upto] with alpha >= 1/255.
  bool layer_of(std::uint32_t i, const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double after, double upto,
                Layer& layer) const;
  // Their layers peaking at t in (after, upto] with alpha >= 1/255, appended and stably sorted by t.
  void add_layers(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double after, double upto,
                  std::span<const std::uint32_t> candidates, std::vector<Layer>& layers) const;
  // The whole ray's layers from `candidates` (as gather() gives them), composited.
  [[nodiscard]] SeenDepth composite_whole(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, double t_max,
                                          std::span<const std::uint32_t> candidates) const;
  // first_seen_parallel()'s steps: a bundle's frame, grid and near Gaussians (false when a
  // foot is not finite); the near Gaussians binned into the cells; one ray's first_seen() in it.
  struct Bundle;
  bool frame_bundle(std::span<const Eigen::Vector3d> origins, const Eigen::Vector3d& u, Bundle& bundle) const;
  static void bin_bundle(Bundle& bundle);
  [[nodiscard]] SeenDepth first_seen_in_bundle(const Bundle& bundle, const Eigen::Vector3d& o,
                                               std::vector<Layer>& heap) const;
  // Composites `layers` (in depth order) onto `out`; `stop`: return at the seen surface.
  void accumulate(const Eigen::Vector3d& u, std::span<const Layer> layers, SeenDepth& out, double& transmittance,
                  bool stop) const;
  std::vector<Entry> gaussians_;
  WideBvh bvh_;                       // over the bounding spheres' boxes
  std::vector<std::uint32_t> order_;  // the BVH's slot -> index into gaussians_
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();  // of every box
  double radius_ = 0;                                 // every box lies within it of centre_
};

}  // namespace gshaptics
