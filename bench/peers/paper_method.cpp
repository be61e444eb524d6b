// The paper's collision check (Sec. III-B) written plainly: kd-tree of centres with a fixed
// search radius, bounding-sphere pre-filter (eq. 4), fixed 30-step golden section on K(lambda)
// with a 3x3 solve per evaluation, double precision.

#include <Eigen/Cholesky>
#include <algorithm>
#include <nanoflann.hpp>

#include "peers.h"

namespace gshaptics::peers {

namespace {
struct CentreCloud {
  std::vector<Eigen::Vector3d> pts;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return pts.size(); }
  [[nodiscard]] double kdtree_get_pt(std::size_t i, std::size_t d) const { return pts[i][int(d)]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const { return false; }
};
using KdTree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<double, CentreCloud>, CentreCloud, 3, std::uint32_t>;
}  // namespace

struct PaperMethodPeer::Impl {
  CentreCloud cloud;
  std::vector<Eigen::Matrix3d> cov;
  std::vector<double> radius;
  std::vector<std::uint32_t> index;
  double r_max = 0;
  std::unique_ptr<KdTree> tree;
  std::vector<std::pair<std::uint32_t, double>> hits;
};

PaperMethodPeer::PaperMethodPeer(const CollisionWorld& world) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  for (const auto& g : world.gaussians()) {
    m.cloud.pts.emplace_back(g.center[0], g.center[1], g.center[2]);
    const Eigen::Matrix3d R = rotation_matrix(g);
    const Eigen::Vector3d a(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
    m.cov.push_back(R * a.cwiseAbs2().asDiagonal() * R.transpose());
    m.radius.push_back(a.maxCoeff());
    m.index.push_back(g.source_index);
    m.r_max = std::max(m.r_max, a.maxCoeff());
  }
  m.tree = std::make_unique<KdTree>(3, m.cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  m.tree->buildIndex();
}

PaperMethodPeer::~PaperMethodPeer() = default;

std::size_t PaperMethodPeer::memory_bytes() const {
  const Impl& m = *impl_;
  return m.cloud.pts.capacity() * sizeof(Eigen::Vector3d) + m.cov.capacity() * sizeof(Eigen::Matrix3d) +
         m.radius.capacity() * 8 + m.index.capacity() * 4 + m.tree->usedMemory(*m.tree);
}

void PaperMethodPeer::query(const ToolEllipsoid& tool, PeerResult& out) {
  Impl& m = *impl_;
  out.contacts.clear();
  const Eigen::Matrix3d Rt = tool.rotation.normalized().toRotationMatrix();
  const Eigen::Matrix3d cov_t = Rt * tool.semi_axes.cwiseAbs2().asDiagonal() * Rt.transpose();
  const double r_tool = tool.semi_axes.maxCoeff();
  const double search = r_tool + m.r_max;
  m.hits.clear();
  nanoflann::SearchParams params;
  params.sorted = false;
  m.tree->radiusSearch(tool.center.data(), search * search, m.hits, params);
  out.candidates = std::uint32_t(m.hits.size());
  for (const auto& [i, dist2] : m.hits) {
    const double reach = m.radius[i] + r_tool;
    if (!(dist2 < reach * reach)) continue;  // eq. 4
    const Eigen::Vector3d d = m.cloud.pts[i] - tool.center;
    const auto K = [&](double l) {
      const Eigen::Matrix3d A = l * m.cov[i] + (1 - l) * cov_t;
      return 1.0 - l * (1 - l) * d.dot(A.ldlt().solve(d));
    };
    constexpr double kInvPhi = 0.6180339887498949;
    double lo = 0, hi = 1, x1 = hi - kInvPhi, x2 = kInvPhi;
    double f1 = K(x1), f2 = K(x2);
    for (int it = 0; it < 30; ++it) {
      if (f1 < f2) {
        hi = x2; x2 = x1; f2 = f1; x1 = hi - kInvPhi * (hi - lo); f1 = K(x1);
      } else {
        lo = x1; x1 = x2; f1 = f2; x2 = lo + kInvPhi * (hi - lo); f2 = K(x2);
      }
    }
    if (std::min(f1, f2) > 0) out.contacts.push_back(m.index[i]);
  }
  std::sort(out.contacts.begin(), out.contacts.end());
}

}  // namespace gshaptics::peers
