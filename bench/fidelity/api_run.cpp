// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/api_run.h"

#include <cstdint>
#include <span>
#include <stdexcept>
#include <utility>

#include "api/ingest.h"
#include "api/pipeline.h"
#include "core/refine.h"

namespace stlrefine::fidelity {
namespace {

std::span<const std::uint8_t> as_bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

}  // namespace

api::RequestLimits cli_request_limits() {
  // As cli/main.cpp's refine command.
  api::RequestLimits limits;
  limits.max_faces = (std::uint64_t{1} << 31) - 1;
  limits.default_max_faces = RefineParams{}.max_faces;
  limits.accept_threads = true;
  return limits;
}

std::pair<std::string, std::string> split_param(std::string_view text) {
  const std::size_t eq = text.find('=');
  if (eq == std::string_view::npos || eq == 0)
    throw std::invalid_argument("expected name=value, got '" + std::string(text) + "'");
  return {std::string(text.substr(0, eq)), std::string(text.substr(eq + 1))};
}

api::RawParams merge_params(api::RawParams base, const api::RawParams& overrides) {
  for (const auto& kv : overrides) {
    bool replaced = false;
    for (auto& b : base)
      if (b.first == kv.first) b.second = kv.second, replaced = true;
    if (!replaced) base.push_back(kv);
  }
  return base;
}

api::RefineRequest check_refine_params(const api::RawParams& params) {
  return api::parse_refine_params(params, cli_request_limits());
}

Mesh ingest_request_stl(const std::string& stl) {
  return api::ingest_stl(as_bytes(stl), 0.0).result.mesh;
}

ApiRun run_api_refine(const std::string& stl, const api::RawParams& params) {
  const api::RefineRequest request = check_refine_params(params);
  api::RefineOutcome outcome = api::run_refine(as_bytes(stl), request);
  ApiRun run;
  run.mesh = ingest_request_stl(outcome.stl);
  run.fold_fallbacks = outcome.report.value("fold_fallbacks", std::size_t{0});
  run.report = std::move(outcome.report);
  return run;
}

}  // namespace stlrefine::fidelity
