// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/registry.h"

#include <array>
#include <string>

#include "core/error.h"
#include "core/schemes/butterfly.h"
#include "core/schemes/butterfly_g1.h"
#include "core/schemes/loop.h"
#include "core/schemes/loop_g2.h"
#include "core/schemes/lsf.h"
#include "core/schemes/split4_host.h"
#include "core/schemes/sqrt3_host.h"
#include "core/schemes/sqrt3_interp.h"
#include "core/schemes/sqrt3_kobbelt.h"
#include "core/schemes/sqrt3_unified.h"

namespace stlrefine {

namespace {

// The options' declarations (scheme_options.h): the one place their ranges and defaults live.
constexpr SchemeOptionSpec kUnifiedOptions[] = {
    {.name = "alpha",
     .default_value = 1.0,
     .minimum = 0.0,
     .maximum = 1.0,
     .description = "sqrt3-unified: 1 interpolates, 0 approximates (Kobbelt), in between blends.",
     .help = "sqrt3-unified: 1 interpolates the input vertices, 0 approximates (Kobbelt's sqrt3)",
     .example = "0.5"},
    {.name = "alpha_features",
     .default_value = 1.0,
     .minimum = 0.0,
     .maximum = 1.0,
     .description = "sqrt3-unified: alpha of crease and corner vertices.",
     .help = "sqrt3-unified: alpha of crease and corner vertices, so feature lines can stay "
             "exact while the rest is smoothed",
     .example = "0.5"},
};
constexpr SchemeOptionSpec kLoopG2Options[] = {
    {.name = "kappa",
     .default_value = 0.5,
     .minimum = 0.0,
     .maximum = 1.0,
     .exclusive_minimum = true,
     .description = "loop-g2: the eigenvalues Prautzsch and Umlauf move go to kappa lambda^2.",
     .help = "loop-g2: the moved eigenvalues go to kappa lambda^2",
     .example = "0.25"},
    {.name = "ramp_steps",
     .integer = true,
     .default_value = 0,
     .minimum = 0,
     .maximum = 8,
     .description = "loop-g2: gradual modification (PU Remark 5.3) over this many steps; 0 = off.",
     .help = "loop-g2: modify gradually over this many steps (PU Remark 5.3; 0 = off)",
     .example = "4"},
};

// The one table of schemes (registry.h).
constexpr std::array<SchemeEntry, 8> kSchemes = {{
    {"butterfly",
     [](const SchemeOptions&) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Split4Stencil>>("butterfly",
                                                          std::make_unique<ButterflyStencil>());
     }},
    {"loop",
     [](const SchemeOptions&) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Split4Stencil>>("loop", std::make_unique<LoopStencil>());
     }},
    {"lsf",
     [](const SchemeOptions&) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Split4Stencil>>("lsf", std::make_unique<LsfStencil>());
     }},
    {"sqrt3",
     [](const SchemeOptions&) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Sqrt3Stencil>>("sqrt3",
                                                         std::make_unique<KobbeltStencil>());
     }},
    {"sqrt3-interp",
     [](const SchemeOptions&) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Sqrt3Stencil>>("sqrt3-interp",
                                                         std::make_unique<LabsikGreinerStencil>());
     }},
    {"sqrt3-unified",
     [](const SchemeOptions& o) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Sqrt3Stencil>>(
           "sqrt3-unified",
           std::make_unique<LinLuoStencil>(o.get("alpha"), o.get("alpha_features")));
     },
     kUnifiedOptions},
    {"loop-g2",
     [](const SchemeOptions& o) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Split4Stencil>>(
           "loop-g2", make_loop_g2_stencil(o.get("kappa"), static_cast<int>(o.get("ramp_steps"))));
     },
     kLoopG2Options,
     []() -> std::unique_ptr<Split4Stencil> { return std::make_unique<LoopStencil>(); }},
    {"butterfly-g1",
     [](const SchemeOptions&) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Split4Stencil>>("butterfly-g1",
                                                          make_butterfly_g1_stencil());
     },
     {},
     []() -> std::unique_ptr<Split4Stencil> {
       return std::make_unique<ButterflyStencil>(ButterflyStencil::Extraordinary::EightPoint);
     }},
}};

constexpr std::array<std::string_view, kSchemes.size()> kNames = [] {
  std::array<std::string_view, kSchemes.size()> names{};
  for (std::size_t i = 0; i < kSchemes.size(); ++i) names[i] = kSchemes[i].name;
  return names;
}();

}  // namespace

std::span<const SchemeEntry> scheme_registry() {
  return kSchemes;
}

const SchemeEntry* find_scheme(std::string_view name) {
  for (const SchemeEntry& entry : kSchemes)
    if (entry.name == name) return &entry;
  return nullptr;
}

std::span<const std::string_view> scheme_names() {
  return kNames;
}

const SchemeOptionSpec* find_scheme_option(std::string_view name) {
  for (const SchemeEntry& entry : kSchemes)
    for (const SchemeOptionSpec& spec : entry.options)
      if (spec.name == name) return &spec;
  return nullptr;
}

std::vector<const SchemeOptionSpec*> scheme_option_specs() {
  std::vector<const SchemeOptionSpec*> specs;
  for (const SchemeEntry& entry : kSchemes)
    for (const SchemeOptionSpec& spec : entry.options)
      if (find_scheme_option(spec.name) == &spec) specs.push_back(&spec);
  return specs;
}

void validate_scheme_options(const SchemeOptions& options) {
  for (const auto& [name, value] : options.values()) {
    const SchemeOptionSpec* spec = find_scheme_option(name);
    if (!spec)
      throw Error(ErrorCode::InvalidParameter, "unknown_parameter",
                  "'" + name + "' is no scheme's option")
          .with_field(name);
    spec->check(value);
  }
}

std::unique_ptr<Scheme> make_scheme(std::string_view name, const SchemeOptions& options) {
  if (const SchemeEntry* entry = find_scheme(name)) {
    validate_scheme_options(options);
    SchemeOptions complete;
    for (const SchemeOptionSpec& spec : entry->options)
      complete.set(spec.name, options.find(spec.name).value_or(spec.default_value));
    return entry->make(complete);
  }
  std::string known;
  for (std::string_view n : kNames) known += (known.empty() ? "" : ", ") + std::string(n);
  throw Error(ErrorCode::InvalidParameter, "unknown_scheme",
              "unknown scheme '" + std::string(name) + "' (known: " + known + ")")
      .with_field("scheme");
}

}  // namespace stlrefine
