// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <string>

namespace stlrefine::server {

//! What this binary is: GET /v1/version's body and the labels of `stlrefine_build_info`.
struct BuildInfo {
  std::string version;     //!< the project version (CMake's PROJECT_VERSION)
  std::string api;         //!< the HTTP API's major version ("v1")
  std::string compiler;    //!< e.g. "gcc 12.2.0"
  std::string build_type;  //!< CMAKE_BUILD_TYPE, or "unknown"
};
const BuildInfo& build_info();

//! GET /v1/version: the build info plus what this build serves (schemes, formats).
std::string version_document();

//! The standard `process_*` metrics of a Prometheus client (CPU seconds, resident and
//! virtual memory, start time, open and maximum file descriptors), read from /proc/self at
//! scrape time, plus `stlrefine_build_info{...} 1`. Prometheus text format 0.0.4.
std::string process_metrics();

}  // namespace stlrefine::server
