// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/scheme.h"

#include <array>
#include <string>

#include "core/error.h"
#include "core/schemes/butterfly.h"
#include "core/schemes/loop.h"
#include "core/schemes/lsf.h"
#include "core/schemes/split4_host.h"

namespace stlrefine {

namespace {

struct SchemeEntry {
  std::string_view name;
  std::unique_ptr<Scheme> (*make)();
};

// The one table of schemes: name -> factory. No static self-registration.
constexpr std::array<SchemeEntry, 3> kSchemes = {{
    {"butterfly",
     []() -> std::unique_ptr<Scheme> {
       return std::make_unique<Split4Scheme>("butterfly", std::make_unique<ButterflyStencil>());
     }},
    {"loop",
     []() -> std::unique_ptr<Scheme> {
       return std::make_unique<Split4Scheme>("loop", std::make_unique<LoopStencil>());
     }},
    {"lsf",
     []() -> std::unique_ptr<Scheme> {
       return std::make_unique<Split4Scheme>("lsf", std::make_unique<LsfStencil>());
     }},
}};

constexpr std::array<std::string_view, kSchemes.size()> kNames = [] {
  std::array<std::string_view, kSchemes.size()> names{};
  for (std::size_t i = 0; i < kSchemes.size(); ++i) names[i] = kSchemes[i].name;
  return names;
}();

}  // namespace

std::span<const std::string_view> scheme_names() {
  return kNames;
}

std::unique_ptr<Scheme> make_scheme(std::string_view name) {
  for (const SchemeEntry& entry : kSchemes)
    if (entry.name == name) return entry.make();
  std::string known;
  for (std::string_view n : kNames) known += (known.empty() ? "" : ", ") + std::string(n);
  throw Error(ErrorCode::InvalidParameter, "unknown_scheme",
              "unknown scheme '" + std::string(name) + "' (known: " + known + ")")
      .with_field("scheme");
}

}  // namespace stlrefine
