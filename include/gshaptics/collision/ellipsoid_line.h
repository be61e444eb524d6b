#pragma once
/// @file
/// Where a line leaves a tool ellipsoid: the part's front over a line parallel to a push, which
/// the seen compound proxy's footprints (force/seen_compound_proxy.h) and the seen-felt measure of
/// a shaped tool (fidelity/seen_felt.h) both read.

#include <Eigen/Core>

#include "gshaptics/collision/tool_ellipsoid.h"

namespace gshaptics {

/// The t at which the line p + t u (u unit; world frame, m) leaves `part` going along u: the
/// larger root of |diag(1/a) R^T (p + t u - c)|^2 = 1. NaN when the line misses the part.
/// Never allocates, locks, logs or throws.
[[nodiscard]] double exit_along(const ToolEllipsoid& part, const Eigen::Vector3d& p, const Eigen::Vector3d& u) noexcept;

}  // namespace gshaptics
