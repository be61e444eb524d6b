#pragma once
/// @file
/// Texture against its ground truth (issue 74): gratings, planes with a sinusoidal relief
/// h(x) = A sin(2 pi x / lambda) of ridges along y, drawn with Gaussians as dense as the relief
/// needs, dragged over by the sphere tool at a constant depth (2 N at the default 1000 N/m
/// coupling) and constant speed v. The normal force's spectrum should peak at v / lambda (the
/// relief's temporal frequency under the moving contact), its amplitude grow with A, and a plane
/// drawn the same way without relief should carry almost no vibration. Every force is the one the
/// servo step commands (safety layer and execution mode included), as in interaction.h.

#include <string>
#include <vector>

#include "gshaptics/fidelity/interaction.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/io/gaussian_scene.h"

namespace gshaptics {

/// A grating scene: the plane z = 0 (top) over x in [-length/2, length/2], y in [-width/2,
/// width/2], with the relief A sin(2 pi x / lambda).
struct GratingParams {
  double wavelength = 0.002;  ///< lambda, m (> 0)
  double amplitude = 0.0001;  ///< A, m (>= 0; 0: the plane without relief)
  double length = 0.12, width = 0.03;  ///< m
  /// Gaussians: every lambda / 8 (at most 0.5 mm) across the ridges, every 2 mm along them; flat
  /// discs tangent to the relief (sigma 0.6 x the spacing across, the spacing along, 10 um thick),
  /// opacity 0.9.
  [[nodiscard]] double spacing_across() const noexcept;
};
/// The grating's Gaussians (scene frame = world frame, metres; INRIA conventions as the synthetic
/// scenes). Throws InputError for a wavelength <= 0 or a negative amplitude.
[[nodiscard]] GaussianScene make_grating_scene(const GratingParams& p);

/// The texture material of the gratings: texture gain 1 everywhere ({"texture_gain": 1} on a
/// box around the grating).
[[nodiscard]] MaterialMap textured_everywhere_map();

/// One drag over one grating.
struct TextureRow {
  double wavelength = 0, amplitude = 0, speed = 0;  ///< m, m, m/s (amplitude 0: the plain plane)
  double tool_radius = 0;   ///< m (the sphere's; 0 for the stylus)
  bool stylus = false;      ///< dragged with the stylus (FidelityOptions::wrench_tools.stylus)
  double expected_hz = 0;   ///< v / lambda
  double peak_hz = 0;       ///< the normal force's spectral peak (1-490 Hz)
  double peak_n = 0;        ///< the amplitude of the sinusoid at the peak, N
  double rms_n = 0;         ///< the normal force's RMS about its mean over the scored stretch, N
  double tick_p99_us = 0;
};

/// The frequency (Hz) and amplitude (N) of the strongest sinusoid in `signal` (sampled at
/// `rate_hz`, mean removed, Hann window) between `f_lo` and `f_hi`: the windowed DFT's magnitude
/// on a 0.05 Hz grid, refined by a parabola through the peak's neighbours.
[[nodiscard]] std::pair<double, double> spectral_peak(const std::vector<double>& signal, double rate_hz, double f_lo,
                                                       double f_hi);

/// Drags the sphere of `tool_radius` 2 mm deep at `speed` over the grating `g` (a world built with
/// the default WorldConfig, its opacity filter default_min_opacity(spec): the seen solid keeps the
/// faint Gaussians) with the proxy `spec` reading textured_everywhere_map(); the scored
/// stretch leaves out the first 2 cm and the last 1 cm of the 6 cm drag. With `stylus` (a
/// compound tool whose tip is its TCP, held upright), the stylus instead, its tip 2 mm deep
/// (`tool_radius` is then only the row's label).
[[nodiscard]] TextureRow drag_over_grating(const GratingParams& g, const RendererSpec& spec, double tool_radius,
                                           double speed, double rate_hz, const PlayOptions& play, std::size_t* ticks,
                                           const CompoundTool* stylus = nullptr);

/// The Markdown table with the verdicts: the peak within 5 % of v / lambda; the amplitude growing
/// with A (per lambda and v); the plain plane's RMS under 10 % of the lambda 2 mm, A 0.1 mm
/// grating's at the same speed.
[[nodiscard]] std::string texture_table(const std::vector<TextureRow>& rows);

}  // namespace gshaptics
