#include "gshaptics/collision/contact_query.h"

#include "gshaptics/broadphase/bvh.h"

namespace gshaptics {

ContactQuery::ContactQuery(const CollisionWorld& world, const QueryOptions& options)
    : world_(&world), options_(options), result_(options.max_contacts) {}

QueryStatus ContactQuery::run(const ToolEllipsoid& tool) noexcept {
  result_.clear();
  if (!tool.valid()) return QueryStatus::kInvalidTool;
  const Eigen::Matrix3d R_tool = tool.rotation.normalized().toRotationMatrix();
  const ToolFrame frame = ToolFrame::from(R_tool, tool.semi_axes);
  const Eigen::Vector3d half = ellipsoid_half_extent(R_tool, tool.semi_axes);
  float box_lo[3], box_hi[3];
  for (int k = 0; k < 3; ++k) {
    box_lo[k] = round_down_to_float(tool.center[k] - half[k]);
    box_hi[k] = round_up_to_float(tool.center[k] + half[k]);
  }
  const double r_tool = tool.bounding_radius();
  const CollisionGaussian* gs = world_->gaussians().data();
  QueryStatus status = QueryStatus::kOk;
  QueryCounts counts;

  world_->bvh().for_each_overlapping_leaf(box_lo, box_hi, [&](std::uint32_t first,
                                                              std::uint32_t count) {
    counts.candidates += count;
    for (std::uint32_t k = first; k < first + count; ++k) {
      const CollisionGaussian& g = gs[k];
      const Eigen::Vector3d d(g.center[0] - tool.center.x(), g.center[1] - tool.center.y(),
                              g.center[2] - tool.center.z());
      const double reach = double(g.bounding_radius) + r_tool;
      if (!(d.squaredNorm() <= reach * reach)) continue;  // eq. 4 (inclusive: touching is kept)
      ++counts.prefiltered;
      const Eigen::Vector3d s(g.semi_axes[0], g.semi_axes[1], g.semi_axes[2]);
      const PairCoefficients c = pair_coefficients(frame, d, rotation_matrix(g), s);
      const KMinResult r = k_min(c, options_.narrow_phase);
      if (r.separated_early || !(r.k_min > 0)) continue;
      ++counts.contacts;
      Contact contact;
      contact.index = g.source_index;
      contact.opacity = g.opacity;
      contact.k_min = r.k_min;
      contact.center = Eigen::Vector3d(g.center[0], g.center[1], g.center[2]);
      if (!result_.push(contact)) status = QueryStatus::kContactOverflow;
    }
  });
  result_.counts = counts;
  return status;
}

}  // namespace gshaptics
