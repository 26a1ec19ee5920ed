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

constexpr std::string_view kUnifiedOptions[] = {"alpha", "alpha_features"};
constexpr std::string_view kLoopG2Options[] = {"kappa", "ramp_steps"};

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
           "sqrt3-unified", std::make_unique<LinLuoStencil>(o.alpha, o.alpha_features));
     },
     kUnifiedOptions},
    {"loop-g2",
     [](const SchemeOptions& o) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Split4Stencil>>("loop-g2",
                                             make_loop_g2_stencil(o.kappa, o.ramp_steps));
     },
     kLoopG2Options,
     []() -> std::unique_ptr<Split4Stencil> { return std::make_unique<LoopStencil>(); }},
    {"butterfly-g1",
     [](const SchemeOptions&) -> std::unique_ptr<Scheme> {
       return std::make_unique<HostScheme<Split4Stencil>>("butterfly-g1", make_butterfly_g1_stencil());
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

std::unique_ptr<Scheme> make_scheme(std::string_view name, const SchemeOptions& options) {
  if (const SchemeEntry* entry = find_scheme(name)) return entry->make(options);
  std::string known;
  for (std::string_view n : kNames) known += (known.empty() ? "" : ", ") + std::string(n);
  throw Error(ErrorCode::InvalidParameter, "unknown_scheme",
              "unknown scheme '" + std::string(name) + "' (known: " + known + ")")
      .with_field("scheme");
}

}  // namespace stlrefine
