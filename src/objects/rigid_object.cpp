#include "gshaptics/objects/rigid_object.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>

#include "gshaptics/error.h"

namespace gshaptics {

namespace {

// Every `stride`-th of `items`, so at most `most` of them.
std::vector<std::size_t> strided(const std::vector<std::size_t>& items, std::size_t most) {
  const std::size_t stride = (items.size() + most - 1) / most;
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < items.size(); i += std::max<std::size_t>(stride, 1)) out.push_back(items[i]);
  return out;
}

// The best cut of one piece: the disc whose tangent plane has the most of the piece's centres on
// its minority side (an estimate from the strided samples, scaled to the piece).
struct Cut {
  std::size_t disc = 0;
  double minority = 0;
};

Cut best_cut(const std::vector<std::size_t>& piece, std::span<const Eigen::Vector3d> centres,
             std::span<const Eigen::Vector3d> normals, double tolerance) {
  const std::vector<std::size_t> discs = strided(piece, 256), counted = strided(piece, 4096);
  Cut best;
  for (std::size_t c : discs) {
    const double d0 = normals[c].dot(centres[c]);
    std::size_t plus = 0, minus = 0;
    for (std::size_t q : counted) {
      const double s = normals[c].dot(centres[q]) - d0;
      plus += s > tolerance;
      minus += s < -tolerance;
    }
    const double minority = double(std::min(plus, minus)) * double(piece.size()) / double(counted.size());
    if (minority > best.minority) best = {c, minority};
  }
  return best;
}

// The connected components of `items` (centres within `link` of each other are linked), by a
// hash grid of cell `link`: each item's component, 0-based.
std::vector<int> components(const std::vector<std::size_t>& items, std::span<const Eigen::Vector3d> centres, double link) {
  const auto cell = [link](const Eigen::Vector3d& x) {
    return Eigen::Vector3i(int(std::floor(x.x() / link)), int(std::floor(x.y() / link)), int(std::floor(x.z() / link)));
  };
  const auto key = [](const Eigen::Vector3i& c) {
    return (std::uint64_t(std::uint32_t(c.x()) & 0x1FFFFF) << 42) | (std::uint64_t(std::uint32_t(c.y()) & 0x1FFFFF) << 21) |
           std::uint64_t(std::uint32_t(c.z()) & 0x1FFFFF);
  };
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> grid;  // cell -> positions in items
  for (std::size_t k = 0; k < items.size(); ++k) grid[key(cell(centres[items[k]]))].push_back(k);
  std::vector<int> component(items.size(), -1);
  int count = 0;
  std::vector<std::size_t> stack;
  for (std::size_t seed = 0; seed < items.size(); ++seed) {
    if (component[seed] >= 0) continue;
    component[seed] = count;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const std::size_t k = stack.back();
      stack.pop_back();
      const Eigen::Vector3d& x = centres[items[k]];
      const Eigen::Vector3i c = cell(x);
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            const auto it = grid.find(key(c + Eigen::Vector3i(dx, dy, dz)));
            if (it == grid.end()) continue;
            for (std::size_t m : it->second)
              if (component[m] < 0 && (centres[items[m]] - x).squaredNorm() <= link * link) {
                component[m] = count;
                stack.push_back(m);
              }
          }
    }
    ++count;
  }
  return component;
}

// Cuts `piece` along disc `c`'s plane: the far side's centres go to `far`; the centres within
// the tolerance go with their nearest centre off it. Then a stray bit of one side (a connected
// component under a tenth of it, linked at twice the tolerance: the ends of a face that meets
// the cut at a concave edge and went with the wrong side) joins the other side when it touches it.
void cut_piece(const std::vector<std::size_t>& piece, std::size_t c, int far, std::span<const Eigen::Vector3d> centres,
               std::span<const Eigen::Vector3d> normals, double tolerance, std::vector<int>& label) {
  const int near = label[piece.front()];
  const double d0 = normals[c].dot(centres[c]);
  std::vector<std::size_t> on, off;
  for (std::size_t q : piece) {
    const double s = normals[c].dot(centres[q]) - d0;
    if (std::abs(s) <= tolerance) on.push_back(q);
    else off.push_back(q);
    if (s > tolerance) label[q] = far;
  }
  const std::vector<std::size_t> anchors = strided(off, 4096);
  for (std::size_t q : on) {
    std::size_t nearest = anchors.front();
    for (std::size_t a : anchors)
      if ((centres[a] - centres[q]).squaredNorm() < (centres[nearest] - centres[q]).squaredNorm()) nearest = a;
    label[q] = label[nearest];
  }
  // Which sides each component of the whole piece holds (bit 0: near, bit 1: far): a stray bit
  // is a whole component of its side, so a link from it through the piece crosses the cut.
  const double link = 2 * tolerance;
  const std::vector<int> whole = components(piece, centres, link);
  std::vector<int> sides(piece.size(), 0);
  for (std::size_t k = 0; k < piece.size(); ++k) sides[std::size_t(whole[k])] |= label[piece[k]] == near ? 1 : 2;
  for (const int side : {near, far}) {
    std::vector<std::size_t> members, at;  // the side's centres and their positions in piece
    for (std::size_t k = 0; k < piece.size(); ++k)
      if (label[piece[k]] == side) {
        members.push_back(piece[k]);
        at.push_back(k);
      }
    const std::vector<int> parts = components(members, centres, link);
    std::vector<std::size_t> size(members.size(), 0);
    for (int p : parts) ++size[std::size_t(p)];
    for (std::size_t k = 0; k < members.size(); ++k)
      if (10 * size[std::size_t(parts[k])] < members.size() && sides[std::size_t(whole[at[k]])] == 3)
        label[members[k]] = side == near ? far : near;
  }
}

}  // namespace

std::vector<int> split_into_pieces(std::span<const Eigen::Vector3d> centres, std::span<const Eigen::Vector3d> normals,
                                   double tolerance, int pieces) {
  std::vector<int> label(centres.size(), 0);
  if (!(tolerance > 0) || !std::isfinite(tolerance)) return label;  // no scale to cut at
  for (int count = 1; count < pieces; ++count) {
    std::vector<std::vector<std::size_t>> members(static_cast<std::size_t>(count));
    for (std::size_t i = 0; i < centres.size(); ++i) members[std::size_t(label[i])].push_back(i);
    int worst = -1;
    Cut cut;
    for (int p = 0; p < count; ++p) {
      const Cut c = best_cut(members[std::size_t(p)], centres, normals, tolerance);
      const double enough = std::max(double(kMinPieceGaussians), 0.02 * double(members[std::size_t(p)].size()));
      if (c.minority >= enough && c.minority > cut.minority) {
        cut = c;
        worst = p;
      }
    }
    if (worst < 0) break;  // every piece is convex to within the tolerance
    cut_piece(members[std::size_t(worst)], cut.disc, count, centres, normals, tolerance, label);
  }
  // Dense labels in order of first appearance (a side emptied by the stray bits' moves leaves none).
  std::vector<int> dense(std::size_t(std::max(pieces, 1)), -1);
  int next = 0;
  for (int& l : label) {
    if (dense[std::size_t(l)] < 0) dense[std::size_t(l)] = next++;
    l = dense[std::size_t(l)];
  }
  return label;
}

RigidObject make_rigid_object(const GaussianScene& world_gaussians, const ObjectSpec& spec, const WorldConfig& config) {
  WorldConfig body_config = config;
  body_config.up = UpAxis::kNone;
  body_config.registration = {};
  // The Gaussians that span the hull (the opaque ones, or every kept one if none is opaque).
  std::vector<std::size_t> opaque;
  for (const float min_opacity : {kHullMinOpacity, 0.0f}) {
    for (std::size_t i = 0; i < world_gaussians.size(); ++i)
      if (world_gaussians.opacities[i] >= min_opacity && world_gaussians.opacities[i] > config.min_opacity) opaque.push_back(i);
    if (!opaque.empty()) break;
  }
  if (opaque.empty()) throw InputError("--object '" + spec.text + "': no Gaussian passes the opacity filter");
  std::vector<Eigen::Vector3d> centres, normals;
  std::vector<double> sizes;  // each Gaussian's largest semi-axis at the world's sigma
  for (std::size_t i : opaque) {
    centres.push_back(world_gaussians.means[i].cast<double>());
    const Eigen::Vector3f& sc = world_gaussians.scales[i];
    int thin = 0;
    sc.minCoeff(&thin);
    const Eigen::Vector4f& q = world_gaussians.rotations[i];
    normals.push_back(Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix().col(thin));
    sizes.push_back(config.sigma * double(sc.maxCoeff()));
  }
  // The cuts' tolerance: the median Gaussian's size (the surface's own roughness).
  std::nth_element(sizes.begin(), sizes.begin() + std::ptrdiff_t(sizes.size() / 2), sizes.end());
  const std::vector<int> label = split_into_pieces(centres, normals, sizes[sizes.size() / 2], spec.hulls);
  const int pieces = 1 + *std::max_element(label.begin(), label.end());
  // The hull's points in the world first, piece by piece: the body origin is the centre of their box.
  std::vector<Eigen::Vector3d> tips;
  RigidObject object;
  for (int k = 0; k < pieces; ++k) {
    for (std::size_t j = 0; j < opaque.size(); ++j) {
      if (label[j] != k) continue;
      const std::size_t i = opaque[j];
      const Eigen::Vector4f& q = world_gaussians.rotations[i];
      const Eigen::Matrix3d R = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
      for (int a = 0; a < 3; ++a) {
        const Eigen::Vector3d axis = R.col(a) * (config.sigma * world_gaussians.scales[i][a]);
        tips.push_back(centres[j] + axis);
        tips.push_back(centres[j] - axis);
      }
    }
    object.piece_ends.push_back(tips.size());
  }
  Eigen::Vector3d lo = tips.front(), hi = tips.front();
  for (const Eigen::Vector3d& p : tips) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  object.spec = spec;
  object.rest_origin = 0.5 * (lo + hi);
  // Every tip goes to MuJoCo, which builds their hull: cutting them down to 256 or 1024 extreme
  // points saved little of the step and moved a sliding box's friction by up to 11 %.
  object.hull_points.reserve(tips.size());
  for (const Eigen::Vector3d& p : tips) object.hull_points.push_back(p - object.rest_origin);
  body_config.registration.translation = -object.rest_origin;
  object.body = std::make_shared<const CollisionWorld>(CollisionWorld::build(world_gaussians, body_config));
  return object;
}

}  // namespace gshaptics
