#pragma once
/// @file
/// The contact normal of a convex tool part resting on a patch of Gaussians, from support
/// functions: the direction that best separates the part from the patch (issue 36, item 5).
///
/// For convex sets the separation along a unit direction n is a support gap,
///   gap_i(n) = n . (c_p - c_i) - h_p(n) - h_i(n),   h(n) = sqrt(n^T M n),
/// (c_p, M_p: the part's centre and shape matrix R diag(a^2) R^T; c_i, M_i: Gaussian i's at the
/// world's sigma scale), and the direction maximising the smallest gap is the contact normal:
/// the dual of the minimum-distance problem that GJK solves with the same support functions
/// (Gilbert, Johnson & Keerthi 1988). Over a patch of Gaussians the smallest gap is replaced by
/// a soft minimum of width `tau`,
///   S(n) = -tau log sum_i w_i exp(-gap_i(n) / tau),
/// so the patch's local convex hull is felt, not the one disc that happens to stick out by the
/// training run's jitter. On a face S peaks at the face's normal; at a convex edge or corner it
/// peaks at the tool's own normal where it rests on the feature, which the shaded field
/// (shaded_normal.h), a blend of the faces' normals, cannot give.
///
/// Threading: pure functions; no allocation, lock, log or throw.

#include <Eigen/Core>
#include <span>

#include "gshaptics/collision/tool_ellipsoid.h"

namespace gshaptics {

/// One Gaussian of a contact patch: centre (m, world), shape matrix M = R diag(a^2) R^T (m^2,
/// world; a its semi-axes at the world's sigma scale) and weight (its opacity, > 0).
struct PatchGaussian {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Matrix3d shape = Eigen::Matrix3d::Zero();
  double weight = 1.0;
};

/// The patch size support_normal() evaluates in one pass (each Gaussian's support computed
/// once per evaluation); a longer patch is read whole but its further Gaussians' supports are
/// computed twice. EdgeNormal's patch holds at most this many.
inline constexpr std::size_t kSupportPatchOnePass = 256;

/// The result of support_normal().
struct SupportNormal {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< unit, patch -> part, world; zero if none
  double separation = 0;  ///< S at the normal, m (< 0: the part reaches into the patch's hull)
  int iterations = 0;     ///< Newton steps taken
};

/// Maximises S(n) over unit n (see the file comment) by Newton steps on the sphere, starting
/// from `start` (unit; the shaded normal or a sweep's contact normal), each step at most 0.25
/// rad and backtracked until S rises. `tau` > 0 (m): the soft minimum's width. Returns a zero
/// normal for an empty patch or a non-finite start.
[[nodiscard]] SupportNormal support_normal(const ToolEllipsoid& part, std::span<const PatchGaussian> patch,
                                           const Eigen::Vector3d& start, double tau) noexcept;

/// gap(n) = n . (c_p - c_i) - h_p(n) - h_i(n) of one patch Gaussian (m; see the file comment).
[[nodiscard]] double support_gap(const ToolEllipsoid& part, const PatchGaussian& g, const Eigen::Vector3d& n) noexcept;

/// The shape matrix R diag(a^2) R^T of a tool ellipsoid (m^2, world).
[[nodiscard]] Eigen::Matrix3d shape_matrix(const ToolEllipsoid& e) noexcept;

}  // namespace gshaptics
