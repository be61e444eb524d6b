#pragma once
/// @file
/// Which force renderer a run uses, with that renderer's own parameters: one value that every
/// runtime, probe run, fidelity run and the Python module take (RuntimeConfig::renderer,
/// ProbeRunParams::renderer, FidelityOptions::renderer). A caller's own ForceRenderer can be
/// handed to HapticRuntime and SimulatedRuntime directly instead.
///
/// The force limit F_max is not here: it is the safety layer's (SafetyParams::f_max), and it
/// binds every renderer together with the device's own limit.

#include <memory>
#include <span>
#include <string_view>
#include <variant>

#include "gshaptics/force/force_renderer.h"
#include "gshaptics/force/material.h"
#include "gshaptics/force/proxy_renderer.h"

namespace gshaptics {

/// The god-object proxy with virtual coupling (ProxyRenderer; Zilles and Salisbury 1995,
/// Colgate, Stanley and Brown 1995). The default.
struct ProxyModelSpec {
  ProxyParams params;
  /// Materials by region (force/material.h; --materials), resolved on each world the renderer is
  /// made for; nullptr: none.
  std::shared_ptr<const MaterialMap> materials;
};

/// The paper's penalty model: contact query, then eq. 7-11 (PaperRenderer).
struct PaperModelSpec {
  ForceParams params;
};

using RendererSpec = std::variant<ProxyModelSpec, PaperModelSpec>;

/// Which force model: the one place its names are defined (renderer_names()).
enum class RendererKind { kProxy, kPaper };

/// A force model's name as on the command line and in Python, and its kind.
struct RendererName {
  std::string_view name;
  RendererKind kind;
};
/// Every force model: {"proxy", kProxy} (the default), {"paper", kPaper}.
[[nodiscard]] std::span<const RendererName> renderer_names() noexcept;
/// The names, for help texts and messages: "proxy, paper".
[[nodiscard]] std::string_view force_model_names() noexcept;
/// The model `name` names. Throws InputError naming `name` and the known names.
[[nodiscard]] RendererKind renderer_kind(std::string_view name);
[[nodiscard]] RendererKind renderer_kind(const RendererSpec& spec) noexcept;
/// "proxy" or "paper", as on the command line.
[[nodiscard]] std::string_view renderer_name(RendererKind kind) noexcept;
[[nodiscard]] std::string_view renderer_name(const RendererSpec& spec) noexcept;
/// The model `kind` with its parameters (the other model's are not read).
[[nodiscard]] RendererSpec renderer_spec(RendererKind kind, const ProxyParams& proxy = {},
                                         const ForceParams& paper = {});
/// The opacity filter a world rendered by `spec` is built with unless the user sets one:
/// kSeenMinOpacity for the proxy on the seen solid (it composites the faint Gaussians a viewer
/// draws), kDefaultMinOpacity (paper Sec. III-A) otherwise.
[[nodiscard]] float default_min_opacity(const RendererSpec& spec) noexcept;
/// The named model with its default parameters. Throws InputError as renderer_kind().
[[nodiscard]] RendererSpec renderer_spec(std::string_view name);
/// The proxy's parameters for `tool` (proxy_params_for(): the fields that do not serve it at
/// their defaults); the paper model as it is.
[[nodiscard]] RendererSpec renderer_spec_for(const RendererSpec& spec, ProxyTool tool);
/// The renderer `spec` names, on `world`; `query` configures the paper model's contact query.
/// Throws InputError for invalid parameters (what the renderer's constructor throws).
[[nodiscard]] std::unique_ptr<ForceRenderer> make_force_renderer(const RendererSpec& spec, const CollisionWorld& world,
                                                                 const QueryOptions& query = {});

}  // namespace gshaptics
