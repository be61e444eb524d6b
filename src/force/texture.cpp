#include "gshaptics/force/texture.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "gshaptics/broadphase/bvh.h"

namespace gshaptics {

namespace {

constexpr double kTwoPi = 6.28318530717958647692;
constexpr double kReliefLimit = 0.25;  // tool radii: the relief is clipped here (a hole under the tip)

// Where o + t d (d unit) first enters the ellipsoid of `g` for t in [0, t_max] (+inf: not).
double ray_entry(const CollisionGaussian& g, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max) noexcept {
  const Eigen::Matrix3d r = rotation_matrix(g);
  const Eigen::Vector3d inv(1.0 / g.semi_axes[0], 1.0 / g.semi_axes[1], 1.0 / g.semi_axes[2]);
  const Eigen::Vector3d p = (r.transpose() * (o - Eigen::Vector3d(g.center[0], g.center[1], g.center[2]))).cwiseProduct(inv);
  const Eigen::Vector3d q = (r.transpose() * d).cwiseProduct(inv);
  const double a = q.squaredNorm(), b = p.dot(q), c = p.squaredNorm() - 1;
  const double disc = b * b - a * c;
  if (!(disc >= 0) || !(a > 0)) return std::numeric_limits<double>::infinity();
  const double root = std::sqrt(disc);
  const double t0 = (-b - root) / a, t1 = (-b + root) / a;
  if (t1 < 0 || t0 > t_max) return std::numeric_limits<double>::infinity();
  return std::max(0.0, t0);
}

}  // namespace

void ProceduralTexture::prepare() {
  if (kind != Kind::kNoise) return;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0, 1);
  std::uniform_real_distribution<double> uni(0, 1);
  const double f_lo = 1 / std::max(wavelength, wavelength_max), f_hi = 1 / std::min(wavelength, wavelength_max);
  for (int j = 0; j < kNoiseTerms; ++j) {
    Eigen::Vector3d dir(gauss(rng), gauss(rng), gauss(rng));
    dir.normalize();
    const double f = f_lo + (f_hi - f_lo) * (j + 0.5) / kNoiseTerms;  // evenly in 1 / lambda
    k_[std::size_t(j)] = kTwoPi * f * dir;
    phase_[std::size_t(j)] = kTwoPi * uni(rng);
  }
  scale_ = amplitude / std::sqrt(kNoiseTerms / 2.0);  // the sum's RMS is sqrt(n / 2)
}

double ProceduralTexture::height(const Eigen::Vector3d& x) const noexcept {
  switch (kind) {
    case Kind::kNone: return 0;
    case Kind::kGrating: return amplitude * std::sin(kTwoPi * x.dot(direction) / wavelength);
    case Kind::kNoise: {
      double h = 0;
      for (int j = 0; j < kNoiseTerms; ++j) h += std::sin(k_[std::size_t(j)].dot(x) + phase_[std::size_t(j)]);
      return scale_ * h;
    }
  }
  return 0;
}

double tip_height(const CollisionWorld& world, const Eigen::Vector3d& contact, const Eigen::Vector3d& normal,
                  double reach) noexcept {
  const Eigen::Vector3d o = contact + reach * normal, d = -normal;
  const double t_max = 2 * reach;
  float lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    const double a = o[k], b = o[k] + t_max * d[k];
    lo[k] = round_down_to_float(std::min(a, b));
    hi[k] = round_up_to_float(std::max(a, b));
  }
  double best = t_max;
  const std::span<const CollisionGaussian> g = world.gaussians();
  world.bvh().for_each_overlapping_leaf(lo, hi, [&](std::uint32_t first, std::uint32_t count) {
    for (std::uint32_t k = first; k < first + count; ++k) {
      // (The bounding sphere first: most of a leaf's Gaussians are beside the ray.)
      const Eigen::Vector3d w = Eigen::Vector3d(g[k].center[0], g[k].center[1], g[k].center[2]) - o;
      const double along = std::clamp(w.dot(d), 0.0, best);
      if ((w - along * d).squaredNorm() > double(g[k].radius) * double(g[k].radius)) continue;
      best = std::min(best, ray_entry(g[k], o, d, best));
    }
  });
  return reach - best;
}

Eigen::Vector3d TextureState::force(double tip, const Eigen::Vector3d& contact, const Eigen::Vector3d& normal,
                                    double radius, double k, double gain, double procedural) noexcept {
  if (!(gain > 0)) {
    started_ = false;
    relief_ = 0;
    return Eigen::Vector3d::Zero();
  }
  const double h = tip + procedural;
  if (!started_) {
    started_ = true;
    mean_ = h;
    last_ = contact;
  }
  // The high-pass over one tool radius of path (the proxy renders the surface at the tool's
  // scale; what is left is finer): an average that moves as the contact slides, not with time.
  const Eigen::Vector3d step = contact - last_;
  const double ds = (step - step.dot(normal) * normal).norm();
  last_ = contact;
  mean_ += (1 - std::exp(-ds / radius)) * (h - mean_);
  relief_ = std::clamp(h - mean_, -kReliefLimit * radius, kReliefLimit * radius);
  return gain * k * relief_ * normal;
}

}  // namespace gshaptics
