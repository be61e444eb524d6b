// Texture (force/texture.h, fidelity/texture_fidelity.h): the procedural reliefs, the point tip
// against a direct search, the spectral peak finder, and the spectral targets in small.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/fidelity/texture_fidelity.h"
#include "gshaptics/fidelity/wrench_fidelity.h"
#include "gshaptics/force/material.h"
#include "gshaptics/force/texture.h"

namespace gshaptics {
namespace {

TEST(ProceduralTexture, AGratingIsItsSinusoidAndNoiseHasItsRms) {
  ProceduralTexture g;
  g.kind = ProceduralTexture::Kind::kGrating;
  g.wavelength = 0.002;
  g.amplitude = 1e-4;
  g.prepare();
  EXPECT_NEAR(g.height(Eigen::Vector3d(0.0005, 0.3, -1)), 1e-4, 1e-12);  // a quarter wavelength: the crest
  EXPECT_NEAR(g.height(Eigen::Vector3d(0.0015, 0, 0)), -1e-4, 1e-12);
  ProceduralTexture n;
  n.kind = ProceduralTexture::Kind::kNoise;
  n.amplitude = 1e-4;
  n.wavelength = 0.001;
  n.wavelength_max = 0.004;
  n.prepare();
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> uni(-1, 1);
  double sq = 0;
  const int samples = 20000;
  for (int i = 0; i < samples; ++i) sq += std::pow(n.height(Eigen::Vector3d(uni(rng), uni(rng), uni(rng))), 2);
  EXPECT_NEAR(std::sqrt(sq / samples), 1e-4, 0.1e-4);
}

// The tip's height against a dense march down the ray testing every Gaussian's ellipsoid.
TEST(TextureTip, TheTipMeetsTheFirstEllipsoidAlongTheRay) {
  GratingParams p;
  p.wavelength = 0.002;
  p.amplitude = 2e-4;
  p.length = 0.02;
  p.width = 0.01;
  const CollisionWorld world = CollisionWorld::build(make_grating_scene(p), WorldConfig{});
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> uni(-1, 1);
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::Vector3d contact(0.008 * uni(rng), 0.003 * uni(rng), 0.0);
    const double reach = 0.001;
    const double h = tip_height(world, contact, Eigen::Vector3d::UnitZ(), reach);
    // March from the top in 1 um steps until a point lies inside some ellipsoid.
    double expected = -reach;
    for (double z = reach; z >= -reach; z -= 1e-6) {
      bool inside = false;
      for (const CollisionGaussian& g : world.gaussians()) {
        const Eigen::Vector3d local = rotation_matrix(g).transpose() *
                                      (Eigen::Vector3d(contact.x(), contact.y(), z) - Eigen::Vector3d(g.center[0], g.center[1], g.center[2]));
        if (std::pow(local.x() / g.semi_axes[0], 2) + std::pow(local.y() / g.semi_axes[1], 2) +
                std::pow(local.z() / g.semi_axes[2], 2) <= 1) {
          inside = true;
          break;
        }
      }
      if (inside) {
        expected = z;
        break;
      }
    }
    EXPECT_NEAR(h, expected, 1.5e-6) << "trial " << trial;
    EXPECT_NEAR(h, p.amplitude * std::sin(2 * M_PI * contact.x() / p.wavelength), 5e-5) << "trial " << trial;
  }
}

TEST(SpectralPeak, FindsASinusoidsFrequencyAndAmplitude) {
  std::vector<double> x;
  std::mt19937_64 rng(1);
  std::normal_distribution<double> noise(0, 0.02);
  for (int i = 0; i < 1500; ++i) x.push_back(0.3 + 0.1 * std::sin(2 * M_PI * 37.3 * i / 1000.0 + 0.4) + noise(rng));
  const auto [f, a] = spectral_peak(x, 1000, 2, 490);
  EXPECT_NEAR(f, 37.3, 0.05);
  EXPECT_NEAR(a, 0.1, 0.01);
}

// The targets in small: the peak at v / lambda within 5 %, growing with A, and a plane
// without relief all but quiet, through the servo step.
TEST(TextureDrag, ThePeakIsAtSpeedOverWavelengthAndGrowsWithAmplitude) {
  const RendererSpec proxy = ProxyModelSpec{};
  const PlayOptions play;
  const double r = 0.005, v = 0.05;
  GratingParams g;
  g.wavelength = 0.002;
  double last = 0;
  for (double a : {0.00005, 0.0001, 0.0002}) {
    g.amplitude = a;
    const TextureRow row = drag_over_grating(g, proxy, r, v, 1000, play, nullptr);
    EXPECT_NEAR(row.peak_hz, v / g.wavelength, 0.05 * v / g.wavelength) << "A " << a;
    EXPECT_GT(row.peak_n, last) << "A " << a;
    last = row.peak_n;
  }
  g.amplitude = 0.0001;
  const double reference = drag_over_grating(g, proxy, r, v, 1000, play, nullptr).rms_n;
  g.amplitude = 0;
  const double flat = drag_over_grating(g, proxy, r, v, 1000, play, nullptr).rms_n;
  EXPECT_LT(flat, 0.1 * reference);
  EXPECT_GT(reference, 0.01);  // 0.1 mm of relief at 1000 N/m: about 0.07 N RMS
}


// The same on the seen solid (SeenProxy): the tip reads the seen surface under the contact, and
// the proxy's normal does not follow relief finer than the tool (kNormalPath): before, a 5 mm
// sphere on the 1 mm grating peaked at 2 v / lambda (the normal tilting with every ridge).
TEST(TextureDrag, OnTheSeenSurfaceThePeakIsAtSpeedOverWavelengthAndGrowsWithAmplitude) {
  ProxyModelSpec spec;
  spec.params.surface = ProxySurface::kSeen;
  const double r = 0.005, v = 0.05;
  GratingParams g;
  for (double lambda : {0.001, 0.002}) {
    g.wavelength = lambda;
    double last = 0;
    for (double a : {0.00005, 0.0001, 0.0002}) {
      g.amplitude = a;
      const TextureRow row = drag_over_grating(g, spec, r, v, 1000, PlayOptions{}, nullptr);
      EXPECT_NEAR(row.peak_hz, v / lambda, 0.05 * v / lambda) << "lambda " << lambda << " A " << a;
      EXPECT_GT(row.peak_n, last) << "lambda " << lambda << " A " << a;
      last = row.peak_n;
    }
  }
  g.wavelength = 0.002;
  g.amplitude = 0.0001;
  const double reference = drag_over_grating(g, spec, r, v, 1000, PlayOptions{}, nullptr).rms_n;
  g.amplitude = 0;
  EXPECT_LT(drag_over_grating(g, spec, r, v, 1000, PlayOptions{}, nullptr).rms_n, 0.1 * reference);
}

// On the seen solid the relief is rendered once, by the sphere and the stylus alike: their
// proxies ride the seen surface under their leading points, and the texture tip adds only what
// they do not ride (there, nothing), so on the lambda 2 mm, A 0.1 mm grating at 2 N the peak is
// about k A = 0.1 N (the ellipsoid proxy's sphere gives 0.099 N); with the tip at the proxy's own
// height it was 0.217 N, the relief twice. The stylus's peak lies at v / lambda and grows with A.
TEST(TextureDrag, OnTheSeenSurfaceTheReliefIsRenderedOnceWithEveryTool) {
  ProxyModelSpec sphere;
  sphere.params.surface = ProxySurface::kSeen;
  const RendererSpec stylus_spec = renderer_spec_for(sphere, ProxyTool::kCompound);
  const CompoundTool stylus = WrenchTools{}.stylus;
  const double r = 0.005, v = 0.05, k = ProxyParams{}.stiffness;
  GratingParams g;
  g.wavelength = 0.002;
  g.amplitude = 0.0001;
  const TextureRow ball = drag_over_grating(g, sphere, r, v, 1000, PlayOptions{}, nullptr);
  EXPECT_NEAR(ball.peak_n, k * g.amplitude, 0.2 * k * g.amplitude);
  double last = 0;
  for (double a : {0.00005, 0.0001, 0.0002}) {
    g.amplitude = a;
    const TextureRow row = drag_over_grating(g, stylus_spec, r, v, 1000, PlayOptions{}, nullptr, &stylus);
    EXPECT_NEAR(row.peak_hz, v / g.wavelength, 0.05 * v / g.wavelength) << "A " << a;
    EXPECT_NEAR(row.peak_n, k * a, 0.2 * k * a) << "A " << a;
    EXPECT_GT(row.peak_n, last) << "A " << a;
    last = row.peak_n;
  }
}

// The stylus (a compound tool) on a steep grating (lambda 1 mm, A 0.1 mm: slopes to 32 degrees)
// keeps its 2 N and vibrates at v / lambda. Its ridges once read as convex edges (EdgeNormal),
// the normal jumped to 45-56 degrees, the energy bound withheld ~95 % of the spring, and the
// spectrum's peak fell to 3 Hz.
TEST(TextureDrag, AStylusOnASteepGratingVibratesAtSpeedOverWavelength) {
  const RendererSpec spec = renderer_spec_for(ProxyModelSpec{}, ProxyTool::kCompound);
  GratingParams g;
  g.wavelength = 0.001;
  g.amplitude = 0.0001;
  const CompoundTool stylus = WrenchTools{}.stylus;
  const TextureRow row = drag_over_grating(g, spec, 0.005, 0.05, 1000, PlayOptions{}, nullptr, &stylus);
  EXPECT_NEAR(row.peak_hz, 50.0, 2.5);
  EXPECT_GT(row.peak_n, 0.01);
}

// On the ellipsoids the stylus's tip sits in a pocket between a grating's Gaussians and hops to
// the next (lambda 2 mm, 20 mm/s): the texture's tip follows the hand across the surface
// (CompoundProxy::texture_tip), so the peak grows with the relief's amplitude. With the tip on
// the proxy it read 0.040 N for A 0.05, 0.1 and 0.2 mm alike.
TEST(TextureDrag, OnTheEllipsoidsAStylusCaughtInThePocketsFeelsTheReliefGrow) {
  const RendererSpec spec = renderer_spec_for(ProxyModelSpec{}, ProxyTool::kCompound);
  const CompoundTool stylus = WrenchTools{}.stylus;
  const double v = 0.02, k = ProxyParams{}.stiffness;
  GratingParams g;
  g.wavelength = 0.002;
  double last = 0;
  for (double a : {0.00005, 0.0001, 0.0002}) {
    g.amplitude = a;
    const TextureRow row = drag_over_grating(g, spec, 0.005, v, 1000, PlayOptions{}, nullptr, &stylus);
    EXPECT_NEAR(row.peak_hz, v / g.wavelength, 0.05 * v / g.wavelength) << "A " << a;
    EXPECT_NEAR(row.peak_n, k * a, 0.2 * k * a) << "A " << a;
    EXPECT_GT(row.peak_n, last) << "A " << a;
    last = row.peak_n;
  }
}

// Friction modulated by the relief (MaterialFollower::add_forces): while sliding, the tangential
// force changes by -mu_k times the relief's normal force, against the slide; at rest it does not;
// and texture_rms() is the texture force's RMS over its 20 ms window.
TEST(TextureFriction, FrictionFollowsTheReliefsNormalForceWhileSliding) {
  GratingParams g;
  g.wavelength = 0.002;
  g.amplitude = 1e-4;
  g.length = 0.04;
  const CollisionWorld world = CollisionWorld::build(make_grating_scene(g), WorldConfig{});
  MaterialMap map = textured_everywhere_map();
  map.materials[0].mu_s = 0.6;
  map.materials[0].mu_k = 0.4;
  ProxyParams base;
  MaterialFollower follower(MaterialField::resolve(map, world, base), base);
  const double r = 0.005, dt = 0.001, f_max = 30;
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  std::vector<Contact> held(1);  // a Gaussian of the grating holds the proxy (all are textured)
  held[0].opacity = 0.9f;
  double ms = 0, swing = 0;
  for (int pass = 0; pass < 2; ++pass) {
    const double v = pass == 0 ? 0.05 : 0.0;  // sliding at 50 mm/s, then pressed at rest
    for (int i = 0; i < 300; ++i) {
      const Eigen::Vector3d contact(-0.01 + (pass == 0 ? v * dt * i : 0.004 * std::sin(i * 0.1)), 0.001, 0);
      const Eigen::Vector3d coupling(-0.4 * 2.0, 0, 2.0);  // 2 N pressed, sliding friction along -x
      follower.update(contact + r * n, n, r, contact, held);
      const Eigen::Vector3d f = follower.add_forces(world, coupling, contact, n, Eigen::Vector3d(v, 0, 0), r, f_max, dt);
      const Eigen::Vector3d added = f - coupling;
      if (pass == 0) {
        EXPECT_NEAR(added.x(), -0.4 * added.z(), 1e-12) << i;  // Coulomb: mu_k of the relief's normal force
        swing = std::max(swing, std::abs(added.z()));
      } else {
        EXPECT_EQ(added.x(), 0.0) << i;  // at rest: no tangential buzz
      }
      EXPECT_EQ(added.y(), 0.0);
      ms += (added.squaredNorm() - ms) * -std::expm1(-dt / MaterialFollower::kVibrationWindow);
      EXPECT_NEAR(follower.texture_rms(), std::sqrt(ms), 1e-9) << pass << " " << i;
    }
  }
  EXPECT_GT(swing, 0.02);  // the relief was felt: 0.1 mm at 1000 N/m, gain 1
  follower.release();
  EXPECT_EQ(follower.texture_rms(), 0.0);
}

}  // namespace
}  // namespace gshaptics
