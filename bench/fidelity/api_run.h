// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Our schemes run the way a user's request runs them (issue 17 item 7): raw request
// parameters -> api::parse_refine_params -> api::run_refine on STL bytes -> the STL it
// answers, read back. Whatever the pipeline does after the scheme (post-passes) is in the
// mesh measured.

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "api/params.h"
#include "core/mesh/mesh.h"

namespace stlrefine::fidelity {

//! The limits the CLI applies (its cap is the core's maximum, `threads` accepted).
api::RequestLimits cli_request_limits();

//! "name=value" -> {name, value}. \throw std::invalid_argument without '=' or a name.
std::pair<std::string, std::string> split_param(std::string_view text);

//! `base`, then every pair of `overrides` replacing a pair of the same name (or appended).
api::RawParams merge_params(api::RawParams base, const api::RawParams& overrides);

//! Parses `params` as a refine request would (cli_request_limits()).
//! \throw stlrefine::Error (InvalidParameter) naming the field, as the CLI would answer.
api::RefineRequest check_refine_params(const api::RawParams& params);

//! STL bytes read through the request path's ingest (api::ingest_stl, exact welding): the
//! mesh a request with these bytes starts from. \throw stlrefine::Error as ingest does.
Mesh ingest_request_stl(const std::string& stl);

struct ApiRun {
  Mesh mesh;                      //!< the answered STL, read back (exact welding)
  nlohmann::ordered_json report;  //!< the refine report of the request
  std::size_t fold_fallbacks = 0;
};

//! Runs `params` on `stl` (binary STL bytes) through api::run_refine.
//! \throw stlrefine::Error as the request would fail.
ApiRun run_api_refine(const std::string& stl, const api::RawParams& params);

}  // namespace stlrefine::fidelity
