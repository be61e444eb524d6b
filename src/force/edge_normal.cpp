#include "gshaptics/force/edge_normal.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>

#include "gshaptics/broadphase/bvh.h"

namespace gshaptics {

namespace {

// The patch's thin-axis scatter (each axis weighted by its Gaussian's opacity and flatness): one
// face has one direction (rank 1), a clean edge two, with almost nothing out of their plane. A
// messy patch (a real scene's Gaussians in every orientation) or a corner spreads in all three.
struct PatchShape {
  bool feature = false;                            // a clean edge: two faces
  Eigen::Vector3d edge = Eigen::Vector3d::Zero();  // its direction
  bool face = false;                               // one flat face (rank 1)
  Eigen::Vector3d face_normal = Eigen::Vector3d::Zero();  // its principal thin axis (either sign)
};

// `edges`, `faces`: which answers are asked for.
PatchShape patch_shape(std::span<const Eigen::Vector3d> axes, bool edges, bool faces) noexcept {
  PatchShape out;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  std::size_t flat = 0;
  for (const Eigen::Vector3d& a : axes) {
    scatter.noalias() += a * a.transpose();
    flat += a.squaredNorm() > 0 ? 1 : 0;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(scatter);
  const Eigen::Vector3d l = es.eigenvalues();  // ascending
  if (!(l[2] > 0) || !l.allFinite()) return out;
  if (faces && l[1] < EdgeNormal::kFaceShare * l[2] && flat >= EdgeNormal::kFaceMinGaussians) {
    out.face = true;
    out.face_normal = es.eigenvectors().col(2);
    return out;
  }
  if (!edges || !(l[1] > EdgeNormal::kFeatureShare * l[2] && l[0] < EdgeNormal::kEdgeShare * l[1])) return out;
  out.feature = true;
  out.edge = es.eigenvectors().col(0);
  return out;
}

// A clean convex edge, or not (a groove, or a corrugation): the patch split into its two faces
// (each thin axis turned toward the tool, on either side of their mean across the edge), each
// face's weighted centroid p and normal n. At a convex edge each face lies behind the other's
// plane, (p_B - p_A) . (n_A - n_B) < 0; in a groove each rises in front of it.
// `faces` gets the two faces' unit normals (toward the tool: outward at a convex edge).
bool clean_convex_edge(std::span<const Eigen::Vector3d> axes, std::span<const PatchGaussian> patch,
                       const Eigen::Vector3d& tool_center, const Eigen::Vector3d& edge,
                       std::array<Eigen::Vector3d, 3>& faces, Eigen::Vector3d& apex) noexcept {
  const auto toward_tool = [&](std::size_t i) {
    return axes[i].dot(tool_center - patch[i].center) >= 0 ? Eigen::Vector3d(axes[i]) : Eigen::Vector3d(-axes[i]);
  };
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < axes.size(); ++i) mean += toward_tool(i);
  const Eigen::Vector3d side = edge.cross(mean);  // across the edge, among the faces' normals
  if (!(side.norm() > 0)) return false;
  Eigen::Vector3d n[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  Eigen::Vector3d c[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  double w[2] = {0, 0};
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const Eigen::Vector3d a = toward_tool(i);
    const double wi = a.norm();
    const int f = a.dot(side) >= 0 ? 0 : 1;
    n[f] += a;
    c[f] += wi * patch[i].center;
    w[f] += wi;
  }
  if (!(w[0] > 0 && w[1] > 0)) return false;
  if (!((c[1] / w[1] - c[0] / w[0]).dot(n[0].normalized() - n[1].normalized()) < 0)) return false;
  // Two faces, not a corrugation: each face's thin axes tight about its mean against the angle
  // between the faces. A clean edge's discs lie within a few degrees of their face (the fidelity
  // cube's: 3 degrees about faces 90 degrees apart); a relief whose discs turn continuously
  // (a grating's ridge under a stylus) splits into two "faces" as wide as they are apart, and
  // its support normal tilts past the relief's own slopes (45-56 degrees on a 32-degree grating).
  const Eigen::Vector3d m[2] = {n[0].normalized(), n[1].normalized()};
  const double apart = std::acos(std::clamp(m[0].dot(m[1]), -1.0, 1.0));
  double spread[2] = {0, 0};
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const Eigen::Vector3d a = toward_tool(i);
    const double wi = a.norm();
    if (!(wi > 0)) continue;
    const int f = a.dot(side) >= 0 ? 0 : 1;
    const double angle = std::acos(std::clamp(a.dot(m[f]) / wi, -1.0, 1.0));
    spread[f] += wi * angle * angle;
  }
  const double widest = std::sqrt(std::max(spread[0] / w[0], spread[1] / w[1]));
  faces[0] = m[0], faces[1] = m[1];
  // The edge line's point nearest the tool: tool + a m0 + b m1 on both faces' planes.
  const double g = m[0].dot(m[1]), det = 1 - g * g;
  const double r0 = m[0].dot(c[0] / w[0] - tool_center), r1 = m[1].dot(c[1] / w[1] - tool_center);
  apex = tool_center + ((r0 - g * r1) * m[0] + (r1 - g * r0) * m[1]) / std::max(det, 1e-9);
  return widest <= EdgeNormal::kFaceTightness * apart;
}

// A clean convex corner (three faces). Each thin axis is turned away from the patch's weighted
// centroid (inside the solid at a convex corner, so each face's axes point out of it, even where
// the tool's centre lies behind a face's plane, as it does 2 mm from an edge); the axes fall into
// three groups, each seeded by the heaviest axis left and holding those within `spread` of it.
// Then:
// - the three directions span space (an edge with a row of bevelled discs along it has three
//   groups too, all across the edge);
// - none points away from the tool (a cosine below -kAgainst with both `start`, the shaded
//   normal, and `away`, the god-object's spring direction, when given: in a groove or an inside
//   corner the centroid lies in the air and turns the walls' axes inward, into the solid, where
//   they face away from both; at a convex corner each face's normal is within a few degrees of
//   square to a direction in the cone, or nearer, and a fin can turn the shaded normal far out of
//   the cone, but not the spring too);
// - every pair of faces is convex (each behind the other's plane, as clean_convex_edge() tests an edge);
// - and the tool lies on the outer side of the centroid.
enum class CornerTest { kNo, kMessy, kCorner };  // kMessy: three directions hold under half the weight
// `faces` gets the three faces' unit outward normals.
CornerTest clean_corner(std::span<const Eigen::Vector3d> axes, std::span<const PatchGaussian> patch,
                        const Eigen::Vector3d& tool_center, const Eigen::Vector3d& start, const Eigen::Vector3d& away,
                        double spread, double apart, double share, double leftover,
                        std::array<Eigen::Vector3d, 3>& normals, Eigen::Vector3d& vertex) noexcept {
  constexpr double kAgainst = 0.25;  // the cosine a face's normal may reach against `start` or `away`
  constexpr double kSpan = 0.25;     // |d0 . (d1 x d2)| at least (1 for a cube's corner)
  const std::size_t n = std::min(axes.size(), EdgeNormal::kMaxPatch);
  if (n < 3) return CornerTest::kNo;
  std::array<double, EdgeNormal::kMaxPatch> w;  // each axis's weight (its length)
  std::array<std::int8_t, EdgeNormal::kMaxPatch> group;
  group.fill(-1);
  Eigen::Vector3d mid = Eigen::Vector3d::Zero();
  double total = 0;
  for (std::size_t i = 0; i < n; ++i) {
    w[i] = axes[i].norm();
    mid += w[i] * patch[i].center;
    total += w[i];
  }
  if (!(total > 0)) return CornerTest::kNo;
  mid /= total;
  const auto outward = [&](std::size_t i) {
    return axes[i].dot(patch[i].center - mid) >= 0 ? Eigen::Vector3d(axes[i]) : Eigen::Vector3d(-axes[i]);
  };
  Eigen::Vector3d dir[3], c[3];
  double weight[3] = {0, 0, 0};
  const double cos_spread = std::cos(spread);
  double left = total;
  int faces = 0;
  while (left > leftover * total) {
    std::size_t seed = n;
    double heaviest = 0;
    for (std::size_t i = 0; i < n; ++i)
      if (group[i] < 0 && w[i] > heaviest) heaviest = w[i], seed = i;
    if (seed == n) break;
    // A fourth direction holds weight: not three faces. Messy (a real scene's noise) when the
    // three hold under half the patch; else a clean feature with strays (a floater in the patch).
    if (faces == 3) return total - left < 0.5 * total ? CornerTest::kMessy : CornerTest::kNo;
    const Eigen::Vector3d u = outward(seed) / heaviest;
    dir[faces].setZero();
    c[faces].setZero();
    for (std::size_t i = 0; i < n; ++i) {
      if (group[i] >= 0 || !(w[i] > 0)) continue;
      const Eigen::Vector3d a = outward(i);
      if (a.dot(u) < cos_spread * w[i]) continue;
      group[i] = std::int8_t(faces);
      dir[faces] += a;
      c[faces] += w[i] * patch[i].center;
      weight[faces] += w[i];
      left -= w[i];
    }
    ++faces;
  }
  if (faces != 3) return CornerTest::kNo;
  for (int f = 0; f < 3; ++f) {
    if (!(weight[f] >= share * total) || !(dir[f].norm() > 0)) return CornerTest::kNo;
    dir[f].normalize();
    c[f] /= weight[f];
  }
  if (!(std::abs(dir[0].dot(dir[1].cross(dir[2]))) >= kSpan)) return CornerTest::kNo;
  const double sl = start.norm(), al = away.norm();
  for (const Eigen::Vector3d& d : dir)
    if (!(d.dot(start) > -kAgainst * sl) && !(al > 0 && d.dot(away) > -kAgainst * al)) return CornerTest::kNo;
  const double cos_apart = std::cos(apart);
  for (int f = 0; f < 3; ++f)
    for (int g = f + 1; g < 3; ++g)
      if (dir[f].dot(dir[g]) > cos_apart || !((c[g] - c[f]).dot(dir[f] - dir[g]) < 0)) return CornerTest::kNo;
  normals = {dir[0], dir[1], dir[2]};
  Eigen::Matrix3d planes;  // (invertible: the three directions span space, kSpan above)
  planes << dir[0].transpose(), dir[1].transpose(), dir[2].transpose();
  vertex = planes.partialPivLu().solve(Eigen::Vector3d(dir[0].dot(c[0]), dir[1].dot(c[1]), dir[2].dot(c[2])));
  return (tool_center - mid).dot(dir[0] + dir[1] + dir[2]) > 0 ? CornerTest::kCorner : CornerTest::kNo;
}

// A clean convex edge's answer: its normal, its two faces' normals, its line and apex.
EdgeNormalAnswer edge_answer(const Eigen::Vector3d& normal, const std::array<Eigen::Vector3d, 3>& faces,
                             const Eigen::Vector3d& line, const Eigen::Vector3d& apex) noexcept {
  EdgeNormalAnswer a{normal, true, false, false};
  a.faces = faces;
  a.face_count = 2;
  a.edge_line = line;
  a.apex = apex;
  return a;
}

}  // namespace

Eigen::Vector3d EdgeNormal::turned_toward(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double t) noexcept {
  const Eigen::Vector3d mix = (1.0 - t) * from + t * to;
  return mix.norm() > 1e-9 ? Eigen::Vector3d(mix.normalized()) : from;
}

EdgeNormal::EdgeNormal(const CollisionWorld& world) : world_(&world) {}

EdgeNormalAnswer EdgeNormal::read(const ToolEllipsoid& part, const Eigen::Vector3d& start, double band, double reuse,
                                  BlockFilter floaters, EdgeNormalCache& sc, ConvexFeatures features,
                                  const Eigen::Vector3d& away) noexcept {
  const double rho = part.semi_axes.minCoeff();
  if (sc.valid && (part.center - sc.center).norm() <= reuse &&
      sc.rotation.angularDistance(part.rotation) * part.semi_axes.maxCoeff() <= reuse)
    return sc.answer;
  sc = {part.center, part.rotation, {}, true};
  // The patch: the Gaussians whose bounding sphere reaches within `band` of the part and whose
  // own box meets the part's box grown by `band` (a cheap superset of the exact test, enough for
  // a hull), less those whose centre is inside the part (floaters it passed: the proxy overlaps
  // no Gaussian that blocks it). The own box keeps the BVH query to the part's box: grown by the
  // world's largest Gaussian instead (0.72 m on halo, whose median is 11 mm), a stylus part's
  // query read a good share of the scene at every reading.
  const Eigen::Vector3d half = part.aabb_half_extent() + Eigen::Vector3d::Constant(band);
  float lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = round_down_to_float(part.center[k] - half[k]);
    hi[k] = round_up_to_float(part.center[k] + half[k]);
  }
  const Eigen::Matrix3d rp = part.rotation.normalized().toRotationMatrix();
  std::size_t n = 0;
  const CollisionGaussian* gs = world_->gaussians().data();
  world_->bvh().for_each_overlapping_leaf(lo, hi, [&](std::uint32_t first, std::uint32_t count) {
    for (std::uint32_t k = first; k < first + count && n < kMaxPatch; ++k) {
      const CollisionGaussian& g = gs[k];
      const Eigen::Vector3d c(g.center[0], g.center[1], g.center[2]);
      const Eigen::Vector3d local = rp.transpose() * (c - part.center);
      const double reach = band + double(g.radius);
      double inside = 0, grown = 0;
      for (int q = 0; q < 3; ++q) {
        inside += local[q] * local[q] / (part.semi_axes[q] * part.semi_axes[q]);
        grown += local[q] * local[q] / ((part.semi_axes[q] + reach) * (part.semi_axes[q] + reach));
      }
      if (grown > 1.0 || inside < 1.0) continue;
      const Eigen::Matrix3d r = rotation_matrix(g);
      const Eigen::Vector3d a(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
      const Eigen::Vector3d h = ellipsoid_half_extent(r, a);
      bool apart = false;
      for (int q = 0; q < 3; ++q) apart = apart || c[q] + h[q] < double(lo[q]) || c[q] - h[q] > double(hi[q]);
      if (apart) continue;
      slot_[n] = k;
      // (a round Gaussian states no normal: flatness 0)
      axis_[n] = r.col(thinnest_axis(g)) * (double(g.opacity) * flatness(g));
      patch_[n++] = {c, r * a.array().square().matrix().asDiagonal() * r.transpose(), double(g.opacity)};
    }
  });
  const bool cones_only = (std::uint8_t(features) & std::uint8_t(ConvexFeatures::kEdges)) == 0 &&
                          (std::uint8_t(features) & std::uint8_t(ConvexFeatures::kEdgeCones)) != 0;
  const bool edges = cones_only || (std::uint8_t(features) & std::uint8_t(ConvexFeatures::kEdges)) != 0;
  const bool corners = (std::uint8_t(features) & std::uint8_t(ConvexFeatures::kCorners)) != 0;
  const bool faces = (std::uint8_t(features) & std::uint8_t(ConvexFeatures::kFaces)) != 0;
  // A clean edge (when asked for), else a clean convex corner (when asked for), else nothing.
  PatchShape shape;
  bool corner = false;
  std::array<Eigen::Vector3d, 3> faces_found{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  Eigen::Vector3d apex = Eigen::Vector3d::Zero();
  const auto classify = [&] {
    shape = edges || faces ? patch_shape({axis_.data(), n}, edges, faces) : PatchShape{};
    const CornerTest c = !shape.feature && corners ? clean_corner({axis_.data(), n}, {patch_.data(), n}, part.center,
                                                                  start, away, kCornerSpread, kCornerApart,
                                                                  kFeatureShare, kEdgeShare, faces_found, apex)
                                                   : CornerTest::kNo;
    corner = c == CornerTest::kCorner;
    sc.answer.messy = c == CornerTest::kMessy;
    return shape.feature || corner;
  };
  if (!classify()) {  // a face, or a patch of no clean feature: the shaded normal stands
    if (shape.face) {  // (faces asked for: its mean thin axis, for face_blend)
      sc.answer.face = true;
      sc.answer.normal = shape.face_normal.dot(start) >= 0 ? shape.face_normal : Eigen::Vector3d(-shape.face_normal);
    }
    return sc.answer;
  }
  if (shape.feature && cones_only) return edge_cone(shape.edge, part.center, n, sc);
  // Floaters that the part did not pass but that the grown part reaches (one hanging beside a
  // stylus) would bend the hull: the Gaussians that hold the answer (within a few soft-minimum
  // widths of the smallest gap) are put to the floater rule, and floaters leave the patch (with
  // the caller's budget of uncached isolation tests; past it a Gaussian stays).
  const double tau = kSupportTau * rho;
  SupportNormal sn = support_normal(part, {patch_.data(), n}, start, tau);
  for (int round = 0; round < 3 && floaters.blocks != nullptr && sn.normal.squaredNorm() > 0; ++round) {
    bool dropped = false;
    for (std::size_t i = 0; i < n;) {
      if (support_gap(part, patch_[i], sn.normal) <= sn.separation + 3 * tau &&
          !floaters.blocks(floaters.context, slot_[i])) {
        --n;
        patch_[i] = patch_[n];
        slot_[i] = slot_[n];
        axis_[i] = axis_[n];
        dropped = true;
      } else {
        ++i;
      }
    }
    if (!dropped) break;
    if (!classify()) return sc.answer;
    // (From the last round's answer: the floaters it dropped moved it little, and the search
    // converges in a step or two from there instead of four or five from `start`.)
    sn = support_normal(part, {patch_.data(), n}, sn.normal, tau);
  }
  if (!(sn.normal.squaredNorm() > 0)) return sc.answer;
  if (corner) {  // (convex, with the tool outside: clean_corner)
    sc.answer = {sn.normal, false, true, false};
    sc.answer.faces = faces_found;
    sc.answer.face_count = 3;
    sc.answer.apex = apex;
    return sc.answer;
  }
  // A groove (a concave edge) keeps the shaded normal: its hull spans the groove's opening, and
  // the support normal there would be the bisector whichever wall the tool touches. So does a
  // corrugation (faces as wide as they are apart): its ridges are no edge.
  if (!clean_convex_edge({axis_.data(), n}, {patch_.data(), n}, part.center, shape.edge, faces_found, apex))
    return sc.answer;
  // At an edge the normal lies across it: the hull's tilt along the edge is the rims' jitter.
  Eigen::Vector3d normal = sn.normal;
  if (shape.edge.squaredNorm() > 0) {
    const Eigen::Vector3d across = normal - normal.dot(shape.edge) * shape.edge;
    if (across.norm() > 0.5) normal = across.normalized();
  }
  sc.answer = edge_answer(normal, faces_found, shape.edge, apex);
  return sc.answer;
}

const EdgeNormalAnswer& EdgeNormal::edge_cone(const Eigen::Vector3d& edge, const Eigen::Vector3d& tool_center,
                                              std::size_t n, EdgeNormalCache& sc) const noexcept {
  std::array<Eigen::Vector3d, 3> faces{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  Eigen::Vector3d apex = Eigen::Vector3d::Zero();
  if (!clean_convex_edge({axis_.data(), n}, {patch_.data(), n}, tool_center, edge, faces, apex)) return sc.answer;
  const Eigen::Vector3d mean = faces[0] + faces[1];
  if (!(mean.norm() > 1e-9)) return sc.answer;
  sc.answer = edge_answer(mean.normalized(), faces, edge, apex);
  return sc.answer;
}

double EdgeNormal::crest_depth(const EdgeNormalAnswer& answer, const Eigen::Vector3d& direction) noexcept {
  constexpr double kOutside = -1.5707963267948966;
  if (!answer.feature() || !(direction.norm() > 0)) return kOutside;
  if (answer.face_count == 2) {
    // The wedge between the two faces' normals, in the plane across the edge line.
    const Eigen::Vector3d& a = answer.faces[0];
    const Eigen::Vector3d& b = answer.faces[1];
    const Eigen::Vector3d across = direction - direction.dot(answer.edge_line) * answer.edge_line;
    const Eigen::Vector3d axis = a.cross(b);
    if (!(axis.norm() > 1e-6) || !(across.norm() > 1e-12 * direction.norm())) return kOutside;
    const Eigen::Vector3d u = axis.normalized();
    const double from_a = std::atan2(a.cross(across).dot(u), a.dot(across));
    const double to_b = std::atan2(across.cross(b).dot(u), across.dot(b));
    return std::min(from_a, to_b);
  }
  if (answer.face_count != 3) return kOutside;
  // The trihedral cone: the angle to each bounding plane (spanned by two faces' normals), signed
  // positive on the third's side.
  const Eigen::Vector3d d = direction.normalized();
  double depth = 1.5707963267948966;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d& p = answer.faces[(k + 1) % 3];
    const Eigen::Vector3d& q = answer.faces[(k + 2) % 3];
    Eigen::Vector3d m = p.cross(q);
    if (!(m.norm() > 1e-6)) return kOutside;
    m.normalize();
    if (m.dot(answer.faces[k]) < 0) m = -m;
    depth = std::min(depth, std::asin(std::clamp(m.dot(d), -1.0, 1.0)));
  }
  return depth;
}

Eigen::Vector3d EdgeNormal::blend(const Eigen::Vector3d& shaded, const EdgeNormalAnswer& answer,
                                  const Eigen::Vector3d& contact) noexcept {
  if (!answer.feature() || !(answer.normal.dot(contact) > 0)) return shaded;
  const double apart = std::atan2(answer.normal.cross(shaded).norm(), answer.normal.dot(shaded));
  const double t = std::clamp((apart - kBlendFrom) / (kBlendTo - kBlendFrom), 0.0, 1.0);
  return turned_toward(shaded, answer.normal, t);
}

Eigen::Vector3d EdgeNormal::face_blend(const Eigen::Vector3d& shaded, const EdgeNormalAnswer& answer,
                                       const Eigen::Vector3d& contact) noexcept {
  if (!answer.face || !(answer.normal.dot(contact) > 0)) return shaded;
  const double apart = std::atan2(answer.normal.cross(shaded).norm(), answer.normal.dot(shaded));
  const double t = kFaceShareOfMean * std::clamp((kFaceTo - apart) / (kFaceTo - kFaceFrom), 0.0, 1.0);
  return turned_toward(shaded, answer.normal, t);
}

}  // namespace gshaptics
