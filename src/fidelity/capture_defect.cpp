#include "gshaptics/fidelity/capture_defect.h"

#include <fmt/format.h>

#include <charconv>
#include <limits>
#include <nlohmann/json.hpp>

#include "defect_painter.h"
#include "gshaptics/error.h"

namespace gshaptics {

const std::vector<DefectKind>& all_defects() {
  static const std::vector<DefectKind> kAll = {DefectKind::kFaintPatch, DefectKind::kHole, DefectKind::kLargeFlat,
                                               DefectKind::kInteriorClutter};
  return kAll;
}

std::string_view to_string(DefectKind kind) {
  switch (kind) {
    case DefectKind::kFaintPatch: return "faint-patch";
    case DefectKind::kHole: return "hole";
    case DefectKind::kLargeFlat: return "large-flat";
    case DefectKind::kInteriorClutter: return "interior-clutter";
  }
  return "?";
}

DefectKind parse_defect(std::string_view name, const std::string& source) {
  for (DefectKind k : all_defects())
    if (to_string(k) == name) return k;
  throw InputError(fmt::format("{}: unknown capture defect '{}' (faint-patch, hole, large-flat, interior-clutter)",
                               source, name));
}

CaptureDefect CaptureDefect::of(DefectKind kind) {
  CaptureDefect d;
  d.kind = kind;
  if (kind == DefectKind::kHole) d.radius = 0.004;
  return d;
}

nlohmann::json CaptureDefect::describe() const {
  nlohmann::json j = {{"kind", to_string(kind)}, {"radius_m", radius}, {"at", {at.x(), at.y(), at.z()}}};
  if (kind == DefectKind::kFaintPatch) {
    j["layers"] = faint_layers;
    j["opacity"] = {faint_opacity_min, faint_opacity_max};
  }
  if (kind == DefectKind::kLargeFlat) j["large_factor"] = large_factor;
  if (kind == DefectKind::kInteriorClutter) j["depth_m"] = {clutter_depth_min, clutter_depth_max};
  return j;
}

void CaptureDefect::validate(const std::string& source) const {
  if (!(radius > 0 && radius < 1) || !at.allFinite())
    throw InputError(fmt::format("{}: a {} patch needs a radius in (0, 1) m and a finite centre", source, to_string(kind)));
  if (!(faint_layers >= 1 && faint_layers <= 64 && faint_opacity_min > 0 && faint_opacity_max >= faint_opacity_min &&
        faint_opacity_max <= 1))
    throw InputError(source + ": a faint patch needs 1-64 layers and 0 < opacity min <= max <= 1");
  if (!(large_factor >= 1 && large_factor <= 20))
    throw InputError(source + ": large flat discs must be 1-20 spacings wide");
  if (!(clutter_depth_min > 0 && clutter_depth_max >= clutter_depth_min))
    throw InputError(source + ": interior clutter needs 0 < depth min <= depth max");
}

namespace {
Eigen::Vector3d nearest_sample(const std::vector<SurfaceSample>& samples, const Eigen::Vector3d& at) {
  Eigen::Vector3d best_point = at;
  double best = std::numeric_limits<double>::infinity();
  for (const SurfaceSample& s : samples)
    if (const double e = (s.position - at).squaredNorm(); e < best) {
      best = e;
      best_point = s.position;
    }
  return best_point;
}
}  // namespace

Eigen::Vector3d patch_center(const AnalyticShape& shape, const CaptureDefect& d, double spacing) {
  return nearest_sample(shape.sample_surface(spacing), d.at);
}

std::vector<CaptureDefect> default_capture_defects() {
  std::vector<CaptureDefect> out;
  for (DefectKind k : all_defects()) {
    out.push_back(CaptureDefect::of(k));
    if (k == DefectKind::kHole) {  // and one wider than the neighbours' discs close, still narrower than a 10 mm tool
      out.push_back(out.back());
      out.back().radius = 0.007;
    }
  }
  return out;
}

CaptureDefect parse_capture_defect(std::string_view spec, const std::string& source) {
  const std::size_t colon = spec.find(':');
  CaptureDefect d = CaptureDefect::of(parse_defect(spec.substr(0, colon), source));
  if (colon != std::string_view::npos) {
    const std::string_view r = spec.substr(colon + 1);
    double mm = std::numeric_limits<double>::quiet_NaN();
    const auto [end, ec] = std::from_chars(r.data(), r.data() + r.size(), mm);
    if (ec != std::errc() || end != r.data() + r.size() || !(mm > 0))
      throw InputError(fmt::format("{}: '{}': the patch radius after ':' must be a positive number of millimetres",
                                   source, spec));
    d.radius = mm * 1e-3;
  }
  d.validate(source);
  return d;
}

namespace synth_detail {

namespace {
Eigen::Vector4f wxyz(const Eigen::Quaterniond& q) { return {float(q.w()), float(q.x()), float(q.y()), float(q.z())}; }

Eigen::Quaterniond tangent_frame(const SurfaceSample& s) {
  Eigen::Matrix3d frame;
  frame << s.tangent, s.normal.cross(s.tangent), s.normal;
  return Eigen::Quaterniond(frame);
}
}  // namespace

DefectPainter::DefectPainter(const AnalyticShape& shape, const std::vector<CaptureDefect>& defects,
                             const std::vector<SurfaceSample>& samples, double spacing, std::uint64_t seed)
    : shape_(shape), spacing_(spacing), rng_(seed ^ 0x9e3779b97f4a7c15ULL) {
  for (const CaptureDefect& d : defects) {
    d.validate("synth");
    patches_.push_back(Patch{d, nearest_sample(samples, d.at), {}});
  }
}

void DefectPainter::push(const Eigen::Vector3d& mean, const Eigen::Vector3d& scales, const Eigen::Quaterniond& q,
                         double opacity, GaussianScene& out) {
  out.push_back(mean.cast<float>(), scales.cast<float>(), wxyz(q), float(opacity),
                std::uint32_t(out.size()));
}

void DefectPainter::paint(const SurfaceSample& s, const SurfaceDisc& d, GaussianScene& out) {
  for (Patch& p : patches_) {
    if ((s.position - p.center).norm() > p.defect.radius) continue;
    switch (p.defect.kind) {
      case DefectKind::kFaintPatch: return faint(p, s, d, out);
      case DefectKind::kHole: return;
      case DefectKind::kLargeFlat: return large_flat(p, s, out);
      case DefectKind::kInteriorClutter:
        push(d.mean, d.scales, d.rotation, d.opacity, out);
        return clutter(p, s, out);
    }
  }
  push(d.mean, d.scales, d.rotation, d.opacity, out);
}

// The disc's layers: each moved up to half a spacing in the plane and by the disc's own jitter
// along the normal, each too faint for the opacity filter.
void DefectPainter::faint(const Patch& p, const SurfaceSample& s, const SurfaceDisc& d, GaussianScene& out) {
  const Eigen::Vector3d b = s.normal.cross(s.tangent);
  const double along = (d.mean - s.position).dot(s.normal);
  for (int k = 0; k < p.defect.faint_layers; ++k) {
    const double up = rng_.uniform(-1, 1), u = rng_.uniform(-0.5, 0.5), v = rng_.uniform(-0.5, 0.5);
    const Eigen::Vector3d mean = s.position + s.normal * along * up + (s.tangent * u + b * v) * spacing_;
    push(mean, d.scales, d.rotation, rng_.uniform(p.defect.faint_opacity_min, p.defect.faint_opacity_max), out);
  }
}

// A large disc wherever none lies within large_factor spacings yet (greedy, in sample order).
void DefectPainter::large_flat(Patch& p, const SurfaceSample& s, GaussianScene& out) {
  const double size = p.defect.large_factor * spacing_;
  for (const Eigen::Vector3d& c : p.large_discs)
    if ((c - s.position).norm() < size) return;
  p.large_discs.push_back(s.position);
  const Eigen::Quaterniond spin(Eigen::AngleAxisd(rng_.uniform(0, 2 * kPi), Eigen::Vector3d::UnitZ()));
  const double second = size * rng_.uniform(0.7, 1.0), opacity = rng_.uniform(0.85, 1.0);
  push(s.position, Eigen::Vector3d(size, second, 0.03 * size), (tangent_frame(s) * spin).normalized(), opacity, out);
}

// One Gaussian of ordinary size somewhere under the sample, inside the solid (dropped where the
// solid is thinner than the clutter's depth, as in a plate).
void DefectPainter::clutter(const Patch& p, const SurfaceSample& s, GaussianScene& out) {
  const Eigen::Vector3d b = s.normal.cross(s.tangent);
  const double r = spacing_ * rng_.uniform(0.3, 1.0);
  const double depth = rng_.uniform(p.defect.clutter_depth_min, p.defect.clutter_depth_max);
  const double u = rng_.uniform(-0.5, 0.5), v = rng_.uniform(-0.5, 0.5);
  const Eigen::Vector3d mean = s.position - s.normal * depth + (s.tangent * u + b * v) * spacing_;
  const Eigen::Quaterniond q = Eigen::Quaterniond{rng_.normal(), rng_.normal(), rng_.normal(), rng_.normal()}.normalized();
  const double opacity = rng_.uniform(0.3, 1.0);
  if (shape_.signed_distance(mean) > -(p.defect.clutter_depth_min + r)) return;
  push(mean, Eigen::Vector3d(r, r * 0.7, r * 0.4), q, opacity, out);
}

}  // namespace synth_detail
}  // namespace gshaptics
