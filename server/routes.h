// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The daemon's routes (path, methods, what kind of request each is) and the small helpers
// every route handler uses.

#include <string>
#include <string_view>

namespace stlrefine::server {

inline constexpr const char* kStlContentType = "model/stl";
inline constexpr const char* k3mfContentType = "model/3mf";
inline constexpr const char* kJsonContentType = "application/json";
inline constexpr const char* kZipContentType = "application/zip";
//! The report of a refine or slice answer, compact ASCII JSON.
inline constexpr const char* kReportHeader = "X-Stlrefine-Report";

enum class RouteKind {
  Compute,  //!< POST with an STL body, answered synchronously, takes a compute slot
  Submit,   //!< POST /v1/jobs: an STL body queued as a job; GET /v1/jobs: the caller's jobs
  JobItem,  //!< /v1/jobs/{id} and /v1/jobs/{id}/{file}
  Plain,    //!< GET without a body
  Page,     //!< the web page: / and /assets/{file}, embedded at build time (web/), no API key
};

struct Route {
  const char* path;   //!< a prefix when it ends with '/' ("/v1/jobs/", "/assets/")
  const char* allow;  //!< the Allow header of a 405
  RouteKind kind;
};

//! The route of a (decoded) path, or nullptr.
const Route* find_route(const std::string& path);
//! True for the requests that take an STL body (POST on a Compute or Submit route; GET
//! /v1/jobs lists jobs and takes none).
bool has_body(const Route& route, std::string_view method = "POST");
bool method_allowed(const Route& route, const std::string& method);

//! Paths and header values are echoed in details: at most 120 characters, then "...".
std::string shortened(std::string_view s);
//! One line on stderr in one write (workers log concurrently).
void log_line(const std::string& line);
//! A client's X-Request-Id when it is short and plain; otherwise a new random one.
std::string request_id(const std::string& given);

}  // namespace stlrefine::server
