#include "gshaptics/fidelity/synthetic_scene.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/collision/contact_query.h"
#include "gshaptics/error.h"
#include "gshaptics/io/atomic_file.h"
#include "gshaptics/io/scene_writer.h"
#include "defect_painter.h"

namespace gshaptics {

namespace {

using synth_detail::kPi;
using synth_detail::Rng;

Eigen::Vector4f to_wxyz(const Eigen::Quaterniond& q) {
  return {float(q.w()), float(q.x()), float(q.y()), float(q.z())};
}

// A disc narrowed across the convex edges near its sample, its standard deviation toward an edge
// at most the distance to it over `sigmas` (SynthParams::edge_sigmas): a trained capture keeps a
// solid's edges crisp, since a disc overhanging an edge is seen from the side in the training
// views and optimised away. A disc the edges do not reach is returned as drawn, bit for bit; a
// narrowed one keeps its axes' order (in-plane, in-plane, thin).
void narrow_at_edges(const AnalyticShape& shape, const SurfaceSample& sample, double sigmas, Eigen::Quaterniond& q,
                     Eigen::Vector3d& scales) {
  std::array<FaceBorder, 2> borders;
  const int n = sigmas > 0 ? shape.convex_borders(sample, borders) : 0;
  const Eigen::Matrix3d r = q.toRotationMatrix();
  Eigen::Matrix3d cov = r * scales.cwiseAbs2().asDiagonal() * r.transpose();
  bool narrowed = false;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d& v = borders[std::size_t(k)].outward;
    const double sd = std::sqrt(v.dot(cov * v)), most = borders[std::size_t(k)].distance / sigmas;
    if (!(sd > most)) continue;
    // Scaled by f along v alone: S Sigma S with S = I + (f - 1) v v^T.
    const Eigen::Matrix3d squeeze = Eigen::Matrix3d::Identity() + (most / sd - 1) * v * v.transpose();
    cov = squeeze * cov * squeeze;
    narrowed = true;
  }
  if (!narrowed) return;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  // Ascending: the thin axis first. Stored in-plane, in-plane, thin, right-handed.
  Eigen::Matrix3d axes;
  axes << eig.eigenvectors().col(1), eig.eigenvectors().col(2), eig.eigenvectors().col(0);
  if (axes.determinant() < 0) axes.col(2) = -axes.col(2);
  const Eigen::Vector3d var = eig.eigenvalues().cwiseMax(1e-24);
  scales = Eigen::Vector3d(std::sqrt(var[1]), std::sqrt(var[2]), std::sqrt(var[0]));
  q = Eigen::Quaterniond(axes).normalized();
}

}  // namespace

nlohmann::json SyntheticScene::description() const {
  nlohmann::json j = shape.describe();
  j["generator"] = "gshaptics synth";
  j["parameters"] = {{"spacing_m", params.spacing},
                     {"seed", params.seed},
                     {"scale_log_sigma", params.scale_log_sigma},
                     {"thin_fraction", {params.thin_min, params.thin_max}},
                     {"normal_jitter_sigma_m", params.normal_jitter},
                     {"tilt_sigma_deg", params.tilt_deg},
                     {"low_opacity_share", params.low_opacity_share},
                     {"floater_share", params.floater_share},
                     {"floater_distance_m", {params.floater_min, params.floater_max}},
                     {"floater_clearance_m", params.floater_clearance}};
  if (params.edge_sigmas > 0) j["parameters"]["edge_sigmas"] = params.edge_sigmas;
  j["counts"] = {{"surface", surface_count}, {"floaters", floater_count}, {"total", scene.size()}};
  j["layout"] = "Gaussians 0 .. surface-1 lie on the surface, the rest are floaters";
  if (!params.defects.empty()) {
    j["defects"] = nlohmann::json::array();
    for (const CaptureDefect& d : params.defects) j["defects"].push_back(d.describe());
  }
  return j;
}

SyntheticScene make_synthetic_scene(const AnalyticShape& shape, const SynthParams& p) {
  if (!(p.spacing >= 5e-4 && p.spacing <= 0.05))
    throw InputError("synth: spacing must be in [0.0005, 0.05] m, got " + std::to_string(p.spacing));
  for (double share : {p.low_opacity_share, p.floater_share})
    if (!(share >= 0 && share <= 1)) throw InputError("synth: shares must be in [0, 1]");
  if (!(p.thin_min > 0 && p.thin_max >= p.thin_min && p.thin_max <= 1))
    throw InputError("synth: thin fractions must satisfy 0 < thin_min <= thin_max <= 1");
  if (!(p.normal_jitter >= 0 && p.tilt_deg >= 0 && p.scale_log_sigma >= 0 && p.floater_min >= 0 &&
        p.floater_max >= p.floater_min && p.floater_clearance >= 0))
    throw InputError("synth: jitters, sigmas and floater distances must be >= 0 (floater_max >= floater_min)");
  if (!(p.edge_sigmas >= 0 && p.edge_sigmas <= SynthParams::kMaxEdgeSigmas))
    throw InputError(fmt::format("synth: edge sigmas must be in [0, {:g}], got {:g}", SynthParams::kMaxEdgeSigmas, p.edge_sigmas));
  if (p.floater_share > 0 && !(p.floater_max - 0.3 * p.spacing >= p.floater_clearance))
    throw InputError("synth: floaters cannot clear the surface: floater_max less the smallest floater (0.3 spacing) "
                     "must be >= floater_clearance");

  SyntheticScene out;
  out.shape = shape;
  out.params = p;
  Rng rng(p.seed);
  const std::vector<SurfaceSample> samples = shape.sample_surface(p.spacing);
  const auto floaters = std::size_t(std::lround(p.floater_share * double(samples.size())));
  GaussianScene& g = out.scene;
  g.frame = SceneFrame::kRdf;
  g.reserve(samples.size() + floaters);
  const auto opacity = [&] {
    if (rng.uniform() < p.low_opacity_share) return rng.uniform(0.01, 0.2);
    return rng.uniform() < 0.7 ? rng.uniform(0.8, 1.0) : rng.uniform(0.2, 0.8);
  };
  synth_detail::DefectPainter painter(shape, p.defects, samples, p.spacing, p.seed);
  for (const SurfaceSample& s : samples) {
    // Disc frame: tangent, bitangent, normal; tilted a few degrees, spun at random in the plane.
    const Eigen::Vector3d axis = Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()).normalized();
    const double tilt = p.tilt_deg * kPi / 180 * rng.normal();
    const double spin = rng.uniform(0, 2 * kPi);
    const Eigen::Vector3d b = s.normal.cross(s.tangent);
    Eigen::Matrix3d frame;
    frame << s.tangent, b, s.normal;
    Eigen::Quaterniond q =
        (Eigen::AngleAxisd(tilt, (axis - axis.dot(s.normal) * s.normal).normalized()) * Eigen::Quaterniond(frame) *
         Eigen::AngleAxisd(spin, Eigen::Vector3d::UnitZ()))
            .normalized();
    const double s1 = p.spacing * std::exp(p.scale_log_sigma * rng.normal());
    const double s2 = p.spacing * std::exp(p.scale_log_sigma * rng.normal());
    const double thin = rng.uniform(p.thin_min, p.thin_max) * std::min(s1, s2);
    const Eigen::Vector3d mean = s.position + s.normal * (p.normal_jitter * rng.normal());
    Eigen::Vector3d scales(s1, s2, thin);
    narrow_at_edges(shape, s, p.edge_sigmas, q, scales);
    painter.paint(s, {mean, q, scales, opacity()}, g);
  }
  out.surface_count = g.size();
  auto index = std::uint32_t(g.size());
  // The surface as the default world keeps it (opacity filter, 1 sigma), for the floaters' test.
  const CollisionWorld surface = CollisionWorld::build(g, WorldConfig{});
  ContactQuery touches(surface);
  for (std::size_t k = 0; k < floaters; ++k) {
    // Off a random surface point along its normal, at the stated distance from the whole surface
    // (near a concave corner the other face may be closer); redrawn, whole, until its ellipsoid
    // (largest semi-axis r) lies at least the clearance off the surface and, grown by the
    // clearance, touches none of the surface's Gaussians (a face's discs overhang an edge). A
    // floater in free space at the first draw is the one earlier versions drew.
    for (int attempt = 0;; ++attempt) {
      Eigen::Vector3d mean;
      double d;
      int tries = 0;
      do {
        const SurfaceSample& s = samples[std::size_t(rng.uniform(0, double(samples.size()))) % samples.size()];
        mean = s.position + s.normal * rng.uniform(p.floater_min, p.floater_max);
        d = shape.signed_distance(mean);
      } while ((d < p.floater_min || d > p.floater_max) && ++tries < 1000);
      const double r = p.spacing * rng.uniform(0.3, 1.0);
      const Eigen::Quaterniond q =
          Eigen::Quaterniond(rng.normal(), rng.normal(), rng.normal(), rng.normal()).normalized();
      // (The draws in the order GCC made them when they were one call's arguments: last first.)
      const double alpha = rng.uniform(0.05, 0.5);
      const double thin = rng.uniform(0.2, 1.0), mid = rng.uniform(0.5, 1.0);
      const Eigen::Vector3d axes(r, r * mid, r * thin);
      ToolEllipsoid grown;
      grown.center = mean;
      grown.rotation = q;
      grown.semi_axes = axes.array() + p.floater_clearance;
      if (attempt < 1000 && (d - r < p.floater_clearance || touches.any_contact(grown))) continue;
      g.push_back(mean.cast<float>(), axes.cast<float>(), to_wxyz(q), float(alpha), index++);
      break;
    }
  }
  out.floater_count = floaters;
  return out;
}

void write_synthetic_scene(const std::string& path, const SyntheticScene& s) {
  const nlohmann::json d = s.description();
  std::vector<std::string> comments = {"gshaptics synth: ground-truth scene, metres; the exact surface is in the .json beside this file"};
  comments.push_back("shape " + d["shape"].get<std::string>());
  for (const auto& [k, v] : d["parameters"].items()) comments.push_back(k + " " + v.dump());
  comments.push_back("surface_gaussians " + std::to_string(s.surface_count) + " floaters " + std::to_string(s.floater_count));
  write_inria_ply(path, s.scene, comments);
  write_file_atomically(path + ".json", d.dump(2) + "\n");
}

}  // namespace gshaptics
