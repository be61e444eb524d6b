#pragma once
/// @file
/// K_min of the Gilitschenski-Hanebeck ellipsoid overlap test (paper eq. 5-6), in a form that
/// needs no absolute coordinates, no inverse of the shape matrices and has no cancellation.
///
/// For ellipsoids {x : (x - c)^T Sigma^-1 (x - c) <= 1} (tool T, Gaussian G) and d = c_G - c_T:
///   K(lambda) = 1 - lambda (1 - lambda) d^T [lambda Sigma_G + (1 - lambda) Sigma_T]^-1 d
/// (docs/design.md Sec. 3; algebraically equal to the paper's eq. 6). They overlap iff
/// K_min = min_{lambda in [0,1]} K(lambda) >= 0; the paper counts K_min > 0 as contact.
///
/// Normalising by the tool (Sigma_T = L L^T, M = L^-1 Sigma_G L^-T, v = L^-1 d) and writing
/// a = 1 - lambda, b = lambda gives K = 1 - a b g / h with
///   g = a^2 |v|^2 + a b v^T (tr(M) I - M) v + b^2 v^T adj(M) v
///   h = det(a I + b M) = a^3 + a^2 b tr(M) + a b^2 tr(adj M) + b^3 det(M)
/// Every coefficient is a sum of non-negative terms computed from the factors of M
/// (`PairCoefficients`), so flat (1e-7) and tiny Gaussians keep full relative precision where a
/// power-basis polynomial in lambda would cancel. K is convex on [0,1] (Gilitschenski & Hanebeck),
/// so a bracketed Newton iteration on K' converges in a few steps.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace gshaptics {

/// The six non-negative coefficients of one tool/Gaussian pair (see file comment).
struct PairCoefficients {
  double q0 = 0;  ///< |v|^2
  double q1 = 0;  ///< v^T (tr(M) I - M) v
  double q2 = 0;  ///< v^T adj(M) v
  double e1 = 0;  ///< tr(M)
  double e2 = 0;  ///< tr(adj M)
  double e3 = 0;  ///< det(M)
};

/// How K_min is searched for on [0, 1].
enum class Minimiser {
  kNewton,        ///< bracketed Newton on K' (default; converges to machine precision)
  kGoldenSection, ///< the paper's fixed-iteration golden-section search (Sec. III-B2)
};

/// Result of one pair test.
struct KMinResult {
  double k_min = 1.0;     ///< min K found (an upper bound of the true K_min when `separated_early`)
  double lambda = 0.5;    ///< where it was found
  int iterations = 0;     ///< K evaluations (golden) or Newton steps taken
  bool separated_early = false;  ///< stopped at the first lambda with K < 0 (separation proven)
};

/// Options of the minimiser.
struct KMinOptions {
  Minimiser minimiser = Minimiser::kNewton;
  int golden_iterations = 30;      ///< paper's fixed iteration count
  bool stop_when_separated = false;  ///< Newton only: return as soon as some K(lambda) < 0
};

/// Per-tick constants of the tool's normalisation L^-1 = diag(1/a) R_tool^T (same for every
/// candidate, so computed once per query).
struct ToolFrame {
  Eigen::Matrix3d rotation_t;  ///< R_tool^T
  Eigen::Vector3d inv_a;       ///< 1 / a
  Eigen::Vector3d inv_adj_a;   ///< (1/(a_y a_z), 1/(a_x a_z), 1/(a_x a_y))
  double inv_volume = 1;       ///< 1 / (a_x a_y a_z)
  /// From the tool's rotation (world frame) and semi-axes (all > 0).
  static ToolFrame from(const Eigen::Matrix3d& R_tool, const Eigen::Vector3d& a_tool) noexcept;
};

/// Coefficients of one pair from the tool's per-tick frame (fast path of the collision query).
[[nodiscard]] PairCoefficients pair_coefficients(const ToolFrame& tool,
                                                 const Eigen::Vector3d& d_world,
                                                 const Eigen::Matrix3d& R_gauss,
                                                 const Eigen::Vector3d& s_gauss) noexcept;

/// Coefficients from a Gaussian's centre offset and factors, in the tool's frame.
/// @param d_world   c_G - c_T (world frame, any unit)
/// @param R_gauss   rotation of the Gaussian (world frame), columns are its axes
/// @param s_gauss   semi-axes of the Gaussian's ellipsoid (k * scale, same unit), all > 0
/// @param R_tool    rotation of the tool ellipsoid (world frame)
/// @param a_tool    semi-axes of the tool ellipsoid, all > 0
[[nodiscard]] PairCoefficients pair_coefficients(const Eigen::Vector3d& d_world,
                                                 const Eigen::Matrix3d& R_gauss,
                                                 const Eigen::Vector3d& s_gauss,
                                                 const Eigen::Matrix3d& R_tool,
                                                 const Eigen::Vector3d& a_tool) noexcept;

/// K(lambda) for one pair (lambda in [0, 1]).
[[nodiscard]] double k_of_lambda(const PairCoefficients& c, double lambda) noexcept;

/// Minimises K over [0, 1]. Never throws or allocates.
[[nodiscard]] KMinResult k_min(const PairCoefficients& c, const KMinOptions& options = {}) noexcept;

}  // namespace gshaptics
