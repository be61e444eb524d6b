#include "gshaptics/fidelity/texture_fidelity.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "gshaptics/collision/collision_world.h"
#include "gshaptics/error.h"
#include "gshaptics/fidelity/analytic_shape.h"
#include "gshaptics/force/renderer_spec.h"
#include "gshaptics/percentile.h"

namespace gshaptics {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDepth = 0.002;       // m past the mean plane: 2 N at 1000 N/m
constexpr double kDragLength = 0.06;   // m
constexpr double kScoredFrom = -0.01, kScoredTo = 0.02;  // m of x: the drag runs from -3 to +3 cm

// |DFT| of the windowed signal at frequency f (Goertzel).
double magnitude_at(const std::vector<double>& x, double f, double rate_hz) {
  const double w = 2 * kPi * f / rate_hz, c = 2 * std::cos(w);
  double s1 = 0, s2 = 0;
  for (double v : x) {
    const double s0 = v + c * s1 - s2;
    s2 = s1;
    s1 = s0;
  }
  const double re = s1 - s2 * std::cos(w), im = s2 * std::sin(w);
  return std::hypot(re, im);
}

}  // namespace

double GratingParams::spacing_across() const noexcept { return std::min(wavelength / 8, 0.0005); }

GaussianScene make_grating_scene(const GratingParams& p) {
  if (!(p.wavelength > 0) || !(p.amplitude >= 0) || !(p.length > 0) || !(p.width > 0))
    throw InputError("grating: the wavelength, length and width must be > 0 and the amplitude >= 0");
  const double dx = p.spacing_across(), dy = 0.002, k = 2 * kPi / p.wavelength;
  GaussianScene s;
  const int nx = int(std::floor(p.length / dx)) + 1, ny = int(std::floor(p.width / dy)) + 1;
  s.reserve(std::size_t(nx) * std::size_t(ny));
  for (int i = 0; i < nx; ++i) {
    const double x = -p.length / 2 + i * dx;
    const double z = p.amplitude * std::sin(k * x), slope = p.amplitude * k * std::cos(k * x);
    // The disc's normal (-slope, 0, 1) / norm: +z turned about +y by -atan(slope).
    const double half = -0.5 * std::atan(slope);
    const Eigen::Vector4f q(float(std::cos(half)), 0.0f, float(std::sin(half)), 0.0f);
    const Eigen::Vector3f scale(float(0.6 * dx * std::sqrt(1 + slope * slope)), float(dy), 1e-5f);
    for (int j = 0; j < ny; ++j) {
      const double y = -p.width / 2 + j * dy;
      s.push_back(Eigen::Vector3f(float(x), float(y), float(z)), scale, q, 0.9f, std::uint32_t(s.size()));
    }
  }
  return s;
}

MaterialMap textured_everywhere_map() {
  return MaterialMap::parse(nlohmann::json::parse(R"({"materials": [{"name": "textured", "texture_gain": 1}],
      "regions": [{"material": "textured", "box": {"min": [-1, -1, -1], "max": [1, 1, 1]}}]})"),
                            "the gratings' material");
}

std::pair<double, double> spectral_peak(const std::vector<double>& signal, double rate_hz, double f_lo, double f_hi) {
  const std::size_t n = signal.size();
  if (n < 8) return {NAN, NAN};
  double mean = 0;
  for (double v : signal) mean += v;
  mean /= double(n);
  std::vector<double> x(n);
  double wsum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double w = 0.5 - 0.5 * std::cos(2 * kPi * double(i) / double(n - 1));
    x[i] = (signal[i] - mean) * w;
    wsum += w;
  }
  constexpr double kStep = 0.05;
  double best_f = f_lo, best = -1, below = 0, above = 0;
  double prev = magnitude_at(x, f_lo, rate_hz), here = prev;
  for (double f = f_lo + kStep; f <= f_hi; f += kStep) {
    const double m = magnitude_at(x, f, rate_hz);
    if (here > best && here >= prev && here >= m) {
      best = here;
      best_f = f - kStep;
      below = prev;
      above = m;
    }
    prev = here;
    here = m;
  }
  // A parabola through the peak and its neighbours.
  const double d = below - 2 * best + above;
  const double shift = d < 0 ? 0.5 * (below - above) / d : 0.0;
  return {best_f + shift * kStep, 2 * best / wsum};
}

TextureRow drag_over_grating(const GratingParams& g, const RendererSpec& spec, double tool_radius, double speed,
                             double rate_hz, const PlayOptions& play, std::size_t* ticks, const CompoundTool* stylus) {
  const auto* proxy = std::get_if<ProxyModelSpec>(&spec);
  if (!proxy) throw InputError("fidelity: texture is read by the proxy only (--force-model proxy)");
  WorldConfig config;
  config.min_opacity = default_min_opacity(spec);  // the seen solid keeps the faint Gaussians
  const CollisionWorld world = CollisionWorld::build(make_grating_scene(g), config);
  ProxyModelSpec with = *proxy;
  with.materials = std::make_shared<const MaterialMap>(textured_everywhere_map());
  const auto renderer = make_force_renderer(with, world);
  Script s = slide_script(AnalyticShape(ShapeKind::kPlane), tool_radius, rate_hz, kDepth, kDragLength, speed);
  if (stylus != nullptr) {  // the tip (the TCP) where the sphere's lowest point was
    s.tool = *stylus;
    for (ScriptTick& t : s.ticks) t.position.z() -= tool_radius;
  }
  const ScriptTrace tr = play_script(*renderer, s, rate_hz, play);
  if (ticks) *ticks += s.ticks.size();
  std::vector<double> fz, us;
  for (std::size_t i = 0; i < s.ticks.size(); ++i) {
    const double x = s.ticks[i].position.x();
    if (!s.ticks[i].measured || x < kScoredFrom || x > kScoredTo) continue;
    fz.push_back(tr.force[i].z());
    us.push_back(double(tr.render_us[i]));
  }
  TextureRow r;
  r.wavelength = g.wavelength;
  r.amplitude = g.amplitude;
  r.speed = speed;
  r.tool_radius = stylus != nullptr ? 0.0 : tool_radius;
  r.stylus = stylus != nullptr;
  r.expected_hz = speed / g.wavelength;
  const auto [f, a] = spectral_peak(fz, rate_hz, 2.0, std::min(490.0, 0.49 * rate_hz));
  r.peak_hz = f;
  r.peak_n = a;
  double mean = 0, sq = 0;
  for (double v : fz) mean += v;
  mean /= double(std::max<std::size_t>(1, fz.size()));
  for (double v : fz) sq += (v - mean) * (v - mean);
  r.rms_n = std::sqrt(sq / double(std::max<std::size_t>(1, fz.size())));
  r.tick_p99_us = us.empty() ? NAN : percentile(us, 99);
  return r;
}

std::string texture_table(const std::vector<TextureRow>& rows) {
  // The reference of the plain plane: the lambda 2 mm, A 0.1 mm grating at the same speed.
  std::map<std::pair<double, double>, double> reference_rms;  // (tool radius, speed)
  for (const TextureRow& r : rows)
    if (std::abs(r.wavelength - 0.002) < 1e-9 && std::abs(r.amplitude - 0.0001) < 1e-9)
      reference_rms[{r.tool_radius, r.speed}] = r.rms_n;
  std::string t =
      "| tool (mm) | lambda mm | A mm | v mm/s | v / lambda Hz | peak Hz | peak off | peak N | RMS N | grows with A | "
      "tick us p99 | held |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---|\n";
  for (const TextureRow& r : rows) {
    std::string grows = "-", verdict;
    if (r.amplitude > 0) {
      // The next smaller amplitude at the same wavelength and speed, if any.
      double below = -1;
      for (const TextureRow& q : rows)
        if (q.wavelength == r.wavelength && q.speed == r.speed && q.tool_radius == r.tool_radius && q.stylus == r.stylus &&
            q.amplitude > 0 && q.amplitude < r.amplitude &&
            (below < 0 || q.amplitude > below))
          below = q.amplitude;
      bool up = true;
      for (const TextureRow& q : rows)
        if (q.wavelength == r.wavelength && q.speed == r.speed && q.tool_radius == r.tool_radius && q.stylus == r.stylus &&
            q.amplitude == below)
          up = r.peak_n > q.peak_n;
      grows = below < 0 ? "(smallest)" : up ? "yes" : "**no**";
      const bool on_peak = std::abs(r.peak_hz / r.expected_hz - 1) <= 0.05;
      verdict = on_peak && grows != "**no**" ? "yes" : "**no**";
    } else {
      const auto ref = reference_rms.find({r.tool_radius, r.speed});
      const bool quiet = ref != reference_rms.end() && r.rms_n < 0.1 * ref->second;
      verdict = ref == reference_rms.end() ? "-" : quiet ? fmt::format("yes ({:.0f} % of the reference)", 100 * r.rms_n / ref->second)
                                                        : "**no**";
    }
    t += fmt::format("| {} | {:g} | {:g} | {:g} | {:.1f} | {:.2f} | {} | {:.4f} | {:.4f} | {} | {:.1f} | {} |\n",
                     r.stylus ? std::string("stylus") : fmt::format("sphere {:g}", r.tool_radius * 1e3), r.wavelength * 1e3,
                     r.amplitude * 1e3, r.speed * 1e3, r.expected_hz, r.peak_hz,
                     r.amplitude > 0 ? fmt::format("{:+.1f} %", 100 * (r.peak_hz / r.expected_hz - 1)) : "-", r.peak_n,
                     r.rms_n, grows, r.tick_p99_us, verdict);
  }
  return t;
}

}  // namespace gshaptics
