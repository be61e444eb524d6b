#pragma once
/// @file
/// K_min for a batch of up to kBatchCapacity (256) tool/Gaussian pairs at once: the same
/// cancellation-free form and bracketed Newton iteration as k_min(), written branch-free over
/// structure-of-arrays lanes so the compiler vectorises it (AVX-512, AVX2 or SSE2 clones chosen
/// at run time).
///
/// The batch is solved in stages, each a pass over all its pairs in blocks of kBatchLanes (16):
/// coefficients (for a spherical tool in the Gaussian's frame, a third of the flops; see
/// BatchTool::sphere), the starting point and two Newton steps for every pair, then the few pairs
/// still unconverged (about one in ten on real scenes) gathered into blocks of their own and
/// iterated to the end, then the double-precision certificate. Every pass works on independent
/// blocks, so the CPU overlaps them (throughput-bound) instead of waiting on one block's chain of
/// divisions (latency-bound); and a converged pair stops costing iterations (the "lane refill"
/// of issue 19). Every pair goes through exactly the same arithmetic wherever it sits in a batch:
/// its result does not depend on the batch's size or on the other pairs, to the last bit.

#include <cstdint>

#include "gshaptics/narrowphase/k_min.h"

namespace gshaptics {

/// The rotation matrix (row-major r_{3 row + col}) of the quaternion (w, x, y, z), which is
/// unit up to float rounding (|q|^2 = 1 + e, |e| < 1e-6): the usual formula with its factor 2
/// replaced by 2 / |q|^2 ~ 2 (2 - |q|^2) (error e^2), so the matrix is orthonormal to ~1e-12
/// whatever the rounding did, with no division. Inline and branch-free: the batch kernel calls
/// it per lane (vectorised) and rotation_matrix(CollisionGaussian) per record, with the same result.
template <typename T>
inline void rotation_from_quaternion(T w, T x, T y, T z, T& r0, T& r1, T& r2, T& r3, T& r4, T& r5,
                                     T& r6, T& r7, T& r8) noexcept {
  const T n2 = w * w + x * x + y * y + z * z;
  const T s = 2 * (2 - n2);
  const T xx = s * x * x, yy = s * y * y, zz = s * z * z;
  const T xy = s * x * y, xz = s * x * z, yz = s * y * z;
  const T wx = s * w * x, wy = s * w * y, wz = s * w * z;
  r0 = 1 - (yy + zz);
  r1 = xy - wz;
  r2 = xz + wy;
  r3 = xy + wz;
  r4 = 1 - (xx + zz);
  r5 = yz - wx;
  r6 = xz - wy;
  r7 = yz + wx;
  r8 = 1 - (xx + yy);
}

/// Width of the kernel's blocks: a multiple of every SIMD width we target. Batches are padded to
/// a multiple of it inside the kernel.
inline constexpr int kBatchLanes = 16;
/// Pairs in one batch (a multiple of kBatchLanes). The inputs, outputs and the kernel's stack
/// scratch of a full batch are about 65 KB.
inline constexpr int kBatchCapacity = 256;

/// Inputs and outputs of one batch, structure of arrays. Lanes >= `count` are ignored (the
/// kernel overwrites the padding it needs).
struct alignas(64) PairBatch {
  // Gaussian offset from the tool centre, world frame: d = c_G - c_T.
  double dx[kBatchCapacity], dy[kBatchCapacity], dz[kBatchCapacity];
  // Gaussian rotation R_G (world frame) as a unit quaternion (w, x, y, z) per lane: q[k][lane].
  // Single precision as stored in the world; the kernel makes the matrix in double
  // (rotation_from_quaternion), vectorised.
  float q[4][kBatchCapacity];
  float sx[kBatchCapacity], sy[kBatchCapacity], sz[kBatchCapacity];  ///< Gaussian semi-axes
  // outputs
  double k_min[kBatchCapacity];        ///< K_min; when separated, a negative upper bound of it
  std::uint8_t separated[kBatchCapacity];  ///< 1 when separation was proven early
  int count = 0;    ///< lanes in use (input), 0..kBatchCapacity
  int redone = 0;   ///< output: lanes whose float search was not certified and were solved again
                    ///< by the scalar double search (flat splats; for tests and profiling)
  int tail = 0;     ///< output: lanes still iterating after the first two Newton steps (profiling)
  int polished = 0; ///< output: lanes the certificate did not accept at the float point, so it
                    ///< took a double Newton step first (profiling)
};

/// Per-tick tool constants for the batch kernel.
struct BatchTool {
  double rt[9];         ///< R_tool^T, row-major
  double qt[4];         ///< R_tool^T as a unit quaternion (w, x, y, z): the tool's, conjugated
  double inv_a[3];      ///< 1 / a
  double inv_adj_a[3];  ///< (1/(a_y a_z), 1/(a_x a_z), 1/(a_x a_y))
  double inv_volume;    ///< 1 / (a_x a_y a_z)
  /// The tool is a sphere (a_x == a_y == a_z exactly, as ToolEllipsoid::sphere makes it): the
  /// kernel then takes the coefficients in the Gaussian's own frame, where they need neither the
  /// tool's rotation nor the Gaussian's axes in the tool frame (about a third of the flops).
  bool sphere = false;
};

/// Tool constants from its rotation (world frame) and semi-axes (all > 0).
[[nodiscard]] BatchTool make_batch_tool(const Eigen::Matrix3d& R_tool, const Eigen::Vector3d& a_tool) noexcept;

/// Solves every lane < batch.count (same mathematics as pair_coefficients() + k_min(); each
/// reported K_min is certified within 1e-6 of the true minimum). With `stop_when_separated`, a
/// lane stops at the first lambda where K < 0. Writes the padding lanes up to the next multiple
/// of kBatchLanes. noexcept, no allocation (about 45 KB of stack: the coefficients, the float
/// search state and the packed tail of a full batch).
void k_min_batch(PairBatch& batch, const BatchTool& tool, bool stop_when_separated) noexcept;

}  // namespace gshaptics
