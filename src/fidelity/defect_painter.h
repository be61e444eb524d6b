#pragma once
// Paints capture defects into a ground-truth scene while make_synthetic_scene draws it
// (internal to gshaptics_fidelity; the defects are described in fidelity/capture_defect.h).

#include <Eigen/Geometry>
#include <vector>

#include "gshaptics/fidelity/analytic_shape.h"
#include "gshaptics/fidelity/capture_defect.h"
#include "gshaptics/io/gaussian_scene.h"
#include "synth_rng.h"

namespace gshaptics::synth_detail {

// One surface disc as the defect-free scene draws it.
struct SurfaceDisc {
  Eigen::Vector3d mean;
  Eigen::Quaterniond rotation;
  Eigen::Vector3d scales;
  double opacity = 1;
};

class DefectPainter {
 public:
  // `samples` are the surface samples the scene is drawn on; the patches' centres are found
  // among them. Throws InputError (via CaptureDefect::validate) for a bad defect.
  DefectPainter(const AnalyticShape& shape, const std::vector<CaptureDefect>& defects,
                const std::vector<SurfaceSample>& samples, double spacing, std::uint64_t seed);
  // The sample's disc, or what a patch it lies in puts there instead, appended to `out`.
  void paint(const SurfaceSample& sample, const SurfaceDisc& disc, GaussianScene& out);

 private:
  struct Patch {
    CaptureDefect defect;
    Eigen::Vector3d center;
    std::vector<Eigen::Vector3d> large_discs;  // large flat: the centres placed so far
  };
  void faint(const Patch& p, const SurfaceSample& s, const SurfaceDisc& d, GaussianScene& out);
  void large_flat(Patch& p, const SurfaceSample& s, GaussianScene& out);
  void clutter(const Patch& p, const SurfaceSample& s, GaussianScene& out);
  void push(const Eigen::Vector3d& mean, const Eigen::Vector3d& scales, const Eigen::Quaterniond& q, double opacity,
            GaussianScene& out);

  const AnalyticShape& shape_;
  std::vector<Patch> patches_;
  double spacing_;
  Rng rng_;
};

}  // namespace gshaptics::synth_detail
