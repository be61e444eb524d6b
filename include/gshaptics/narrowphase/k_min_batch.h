#pragma once
/// @file
/// K_min for a batch of up to kBatchLanes (16) tool/Gaussian pairs at once: the same cancellation-free form
/// and bracketed Newton iteration as k_min(), written branch-free over structure-of-arrays lanes
/// so the compiler vectorises it (AVX-512, AVX2 or SSE2 clones chosen at run time).

#include <cstdint>

#include "gshaptics/narrowphase/k_min.h"

namespace gshaptics {

/// Lanes of one batch; a multiple of every SIMD width we target.
inline constexpr int kBatchLanes = 16;

/// Inputs and outputs of one batch, structure of arrays. Lanes >= `count` are ignored.
struct alignas(64) PairBatch {
  // Gaussian offset from the tool centre, world frame: d = c_G - c_T.
  double dx[kBatchLanes], dy[kBatchLanes], dz[kBatchLanes];
  // Gaussian rotation R_G (world frame), row-major per lane: r[3 * row + col][lane]. Single
  // precision as stored in the world; widened inside the kernel, vectorised.
  float r[9][kBatchLanes];
  float sx[kBatchLanes], sy[kBatchLanes], sz[kBatchLanes];  ///< Gaussian semi-axes
  // outputs
  double k_min[kBatchLanes];        ///< K_min; when separated, a negative upper bound of it
  std::uint8_t separated[kBatchLanes];  ///< 1 when separation was proven early
  int count = 0;    ///< lanes in use (input)
  int redone = 0;   ///< output: lanes whose float search was not certified and were solved again
                    ///< by the scalar double search (flat splats; for tests and profiling)
};

/// Per-tick tool constants for the batch kernel.
struct BatchTool {
  double rt[9];         ///< R_tool^T, row-major
  double inv_a[3];      ///< 1 / a
  double inv_adj_a[3];  ///< (1/(a_y a_z), 1/(a_x a_z), 1/(a_x a_y))
  double inv_volume;    ///< 1 / (a_x a_y a_z)
};

/// Tool constants from its rotation (world frame) and semi-axes (all > 0).
[[nodiscard]] BatchTool make_batch_tool(const Eigen::Matrix3d& R_tool, const Eigen::Vector3d& a_tool) noexcept;

/// Solves every lane of `batch` (same mathematics as pair_coefficients() + k_min()).
/// With `stop_when_separated`, a lane stops at the first lambda where K < 0. noexcept, no
/// allocation.
void k_min_batch(PairBatch& batch, const BatchTool& tool, bool stop_when_separated) noexcept;

}  // namespace gshaptics
