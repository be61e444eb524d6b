#pragma once
/// @file
/// Texture: the relief finer than the tool, felt as a stylus dragged over a real surface feels
/// it. The proxy rests on the surface at the tool's scale; a virtual tip much smaller than the
/// tool follows the solid under the proxy's contact point along the path (the micro-geometry the
/// splats carry), and the part of its height finer than the tool, high-passed over one tool radius
/// of path, is rendered as a force along the contact normal: F = g k (h - h_bar) n, with k the
/// coupling stiffness under the contact and g the material's texture gain. Dragged at tangential
/// speed v over a relief of wavelength lambda the force oscillates at v / lambda, its amplitude
/// growing with the relief's: the vibration a stylus picks up (the data-driven texture rendering
/// of Culbertson, Lopez Delgado and Kuchenbecker 2014 plays such vibrations back from
/// recordings; here they come from the scene's own geometry). A material may add a procedural
/// relief (a grating, or band-limited noise) for surfaces whose capture is too smooth.
///
/// The tip is a point: its height is where the ray from above the contact point along -n first
/// enters a Gaussian's ellipsoid (the solid the ellipsoid proxy rests on), within +-half a tool
/// radius of the contact point. Units: m, N; frames: world.
/// Threading: one thread; relief() and TextureState::force() allocate, lock, log and throw nothing.

#include <Eigen/Core>
#include <array>
#include <cstdint>

#include "gshaptics/collision/collision_world.h"

namespace gshaptics {

/// A procedural relief h(x) (m) on a material's surface, a function of the world position.
struct ProceduralTexture {
  enum class Kind { kNone, kGrating, kNoise };
  Kind kind = Kind::kNone;
  double amplitude = 0;  ///< m: the grating's; the noise's standard deviation
  double wavelength = 0;  ///< m: the grating's; the noise's shortest
  double wavelength_max = 0;  ///< m: the noise's longest
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  ///< the grating's ridges run across it (unit)
  std::uint64_t seed = 1;  ///< the noise's
  /// h at world position `x`: A sin(2 pi x.d / lambda) for a grating; for noise, 16 sinusoids of
  /// wavelengths spread evenly in 1 / lambda over [wavelength, wavelength_max], random directions
  /// across the normal's plane and phases (from `seed`), scaled to the amplitude's RMS.
  [[nodiscard]] double height(const Eigen::Vector3d& x) const noexcept;
  /// Fills the noise's components from its parameters (a grating or none needs nothing).
  void prepare();

 private:
  static constexpr int kNoiseTerms = 16;
  std::array<Eigen::Vector3d, kNoiseTerms> k_{};  // wave vectors, rad/m
  std::array<double, kNoiseTerms> phase_{};
  double scale_ = 0;
};

/// The point tip's height above `contact` along the unit `normal` (m, in [-reach, reach]): where
/// the ray from contact + reach n along -n first enters a Gaussian's ellipsoid in `world`; -reach
/// when it enters none within 2 reach (a hole under the tip). No allocation.
[[nodiscard]] double tip_height(const CollisionWorld& world, const Eigen::Vector3d& contact, const Eigen::Vector3d& normal,
                                double reach) noexcept;

/// The texture of one contact: the tip's high-passed height and the force from it.
class TextureState {
 public:
  /// One tick in contact: `tip` the tip's height (m: tip_height() on the ellipsoids, or the
  /// caller's reading on its own solid, the seen proxy's leading point), `contact` the proxy's
  /// contact point (world, m), `normal` its unit normal, `radius` the tool's bounding radius (m),
  /// `k` the coupling stiffness under it (N/m), `gain` the material's texture gain (0: none),
  /// `procedural` its procedural relief at the contact point (m, added to the tip's height).
  /// Returns the texture force, N, along `normal`.
  Eigen::Vector3d force(double tip, const Eigen::Vector3d& contact, const Eigen::Vector3d& normal, double radius,
                        double k, double gain, double procedural) noexcept;
  /// How far above and below the contact point the tip is read: half the tool's radius.
  [[nodiscard]] static double tip_reach(double radius) noexcept { return 0.5 * radius; }
  /// Out of contact: the next contact starts its high-pass afresh.
  void release() noexcept { started_ = false; }
  /// The last relief, m (h - h_bar; 0 out of contact).
  [[nodiscard]] double relief() const noexcept { return relief_; }

 private:
  bool started_ = false;
  Eigen::Vector3d last_ = Eigen::Vector3d::Zero();
  double mean_ = 0, relief_ = 0;
};

}  // namespace gshaptics
