#include "gshaptics/fidelity/material_fidelity.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "gshaptics/error.h"
#include "gshaptics/fidelity/analytic_shape.h"

namespace gshaptics {

namespace {

constexpr double kBorderRadii = 3;  // the blend's reach (MaterialField::at): this close, a side is not scored

double median_of(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// The presses' median stiffness (N/mm) on the side of sign `side` (-1 soft, +1 hard).
double side_stiffness(ForceRenderer& renderer, const AnalyticShape& plane, int side, double radius, double rate_hz,
                      const PlayOptions& play, int presses, std::size_t* ticks) {
  std::vector<double> k;
  for (int i = 0; i < presses; ++i) {
    ContactSite site;
    site.point = Eigen::Vector3d(side * (0.025 + 0.01 * (i % 2)), 0.01 * (i / 2) - 0.005 * (presses / 2), 0);
    const Script s = press_script(plane, site, radius, 0.010, rate_hz);
    const PressMetrics m = press_metrics(plane, s, play_script(renderer, s, rate_hz, play));
    if (!std::isnan(m.stiffness_n_per_mm)) k.push_back(m.stiffness_n_per_mm);
    if (ticks) *ticks += s.ticks.size();
  }
  return median_of(std::move(k));
}

}  // namespace

nlohmann::json two_material_json(const TwoMaterials& m) {
  using nlohmann::json;
  return json{{"frame", "scene"},
              {"materials", json::array({json{{"name", "soft"}, {"stiffness", m.soft_stiffness}, {"mu_s", m.soft_mu_s},
                                              {"mu_k", m.soft_mu_k}},
                                         json{{"name", "hard"}, {"stiffness", m.hard_stiffness}, {"mu_s", m.hard_mu_s},
                                              {"mu_k", m.hard_mu_k}}})},
              {"regions", json::array({json{{"material", "soft"}, {"box", {{"min", {-1e3, -1e3, -1e3}}, {"max", {0, 1e3, 1e3}}}}},
                                       json{{"material", "hard"}, {"box", {{"min", {0, -1e3, -1e3}}, {"max", {1e3, 1e3, 1e3}}}}}})}};
}

MaterialMap two_material_map(const TwoMaterials& m) { return MaterialMap::parse(two_material_json(m), "two-material plane"); }

std::vector<MaterialRow> run_material_cases(const CollisionWorld& world, const RendererSpec& spec, double spacing,
                                            double tool_radius, double rate_hz, const PlayOptions& play, int presses,
                                            std::size_t* ticks) {
  const auto* proxy = std::get_if<ProxyModelSpec>(&spec);
  if (!proxy) throw InputError("fidelity: materials are read by the proxy only (--force-model proxy)");
  const TwoMaterials set;
  ProxyModelSpec with = *proxy;
  with.materials = std::make_shared<const MaterialMap>(two_material_map(set));
  const auto renderer = make_force_renderer(with, world);
  const AnalyticShape plane(ShapeKind::kPlane);
  std::vector<MaterialRow> rows(2);
  rows[0].side = "soft";
  rows[1].side = "hard";
  rows[0].stiffness_set = set.soft_stiffness * 1e-3;
  rows[1].stiffness_set = set.hard_stiffness * 1e-3;
  rows[0].mu_k = set.soft_mu_k;
  rows[1].mu_k = set.hard_mu_k;
  for (int side = 0; side < 2; ++side) {
    rows[std::size_t(side)].stiffness =
        side_stiffness(*renderer, plane, side ? 1 : -1, tool_radius, rate_hz, play, presses, ticks);
    rows[std::size_t(side)].presses = presses;
  }
  // The slide from x = -5 cm to +5 cm across the border at x = 0.
  const Script s = slide_script(plane, tool_radius, rate_hz);
  const ScriptTrace tr = play_script(*renderer, s, rate_hz, play);
  if (ticks) *ticks += s.ticks.size();
  double ft[2] = {0, 0}, fn[2] = {0, 0}, step = 0;
  for (std::size_t i = 1; i < s.ticks.size(); ++i) {
    if (!s.ticks[i].measured) continue;
    const double x = s.ticks[i].position.x();
    const Eigen::Vector3d& f = tr.force[i];
    if (std::abs(x) < kBorderRadii * tool_radius) {
      step = std::max(step, (f - tr.force[i - 1]).norm());
      continue;
    }
    ft[x > 0] += -f.x();  // friction opposes the slide (+x); the bumps' sideways pushes cancel out
    fn[x > 0] += f.z();
  }
  for (int side = 0; side < 2; ++side) {
    MaterialRow& r = rows[std::size_t(side)];
    r.spacing = spacing;
    r.tool_radius = tool_radius;
    r.tangential_over_normal = fn[side] > 0 ? ft[side] / fn[side] : NAN;
    r.border_step = step;
    r.rate_limit = play.safety.max_force_rate / rate_hz;
  }
  return rows;
}

std::string material_table(const std::vector<MaterialRow>& rows) {
  std::string t =
      "| side | spacing mm | tool mm | presses | stiffness N/mm: set / felt | F_t / F_n: mu_k / felt | border step N "
      "(limit) | within 5 %, under the limit |\n|---|---:|---:|---:|---|---|---|---|\n";
  for (const MaterialRow& r : rows) {
    const bool ok = std::abs(r.stiffness / r.stiffness_set - 1) <= 0.05 &&
                    std::abs(r.tangential_over_normal / r.mu_k - 1) <= 0.05 && r.border_step < r.rate_limit;
    t += fmt::format("| {} | {:g} | {:g} | {} | {:.3f} / {:.3f} | {:.2f} / {:.3f} | {:.2f} ({:.1f}) | {} |\n", r.side,
                     r.spacing * 1e3, r.tool_radius * 1e3, r.presses, r.stiffness_set, r.stiffness, r.mu_k,
                     r.tangential_over_normal, r.border_step, r.rate_limit, ok ? "yes" : "**no**");
  }
  return t;
}

}  // namespace gshaptics
