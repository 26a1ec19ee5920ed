// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/routes.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <iostream>
#include <random>
#include <vector>

#include "server/daemon.h"

namespace stlrefine::server {

namespace {

constexpr Route kRoutes[] = {
    {"/v1/refine", "POST", RouteKind::Compute},
    {"/v1/slice", "POST", RouteKind::Compute},
    {"/v1/info", "POST", RouteKind::Compute},
    {"/v1/jobs", "GET, HEAD, POST", RouteKind::Submit},
    {"/v1/jobs/", "GET, HEAD, DELETE", RouteKind::JobItem},
    {"/v1/openapi.json", "GET, HEAD", RouteKind::Plain},
    {"/v1/version", "GET, HEAD", RouteKind::Plain},
    {"/metrics", "GET, HEAD", RouteKind::Plain},
    {"/healthz", "GET, HEAD", RouteKind::Plain},
    {"/readyz", "GET, HEAD", RouteKind::Plain},
    {"/", "GET, HEAD", RouteKind::Page},
    {"/assets/", "GET, HEAD", RouteKind::Page},
};

}  // namespace

const Route* find_route(const std::string& path) {
  for (const Route& r : kRoutes) {
    const std::string_view p = r.path;
    const bool prefix = p.size() > 1 && p.back() == '/';  // "/v1/jobs/", "/assets/"
    if (prefix ? path.size() > p.size() && path.starts_with(p) : path == p) return &r;
  }
  return nullptr;
}

bool has_body(const Route& route, std::string_view method) {
  return route.kind == RouteKind::Compute || (route.kind == RouteKind::Submit && method == "POST");
}

bool method_allowed(const Route& route, const std::string& method) {
  // allow is a comma-separated list of tokens
  std::string_view allow = route.allow;
  while (!allow.empty()) {
    const std::size_t comma = allow.find(',');
    std::string_view token = allow.substr(0, comma);
    while (!token.empty() && token.front() == ' ') token.remove_prefix(1);
    if (token == method) return true;
    if (comma == std::string_view::npos) break;
    allow.remove_prefix(comma + 1);
  }
  return false;
}

std::vector<RouteInfo> served_routes() {
  std::vector<RouteInfo> out;
  for (const Route& r : kRoutes) {
    if (r.kind == RouteKind::JobItem) {
      out.push_back({"/v1/jobs/{id}", r.allow});
      out.push_back({"/v1/jobs/{id}/events", "GET, HEAD"});
      out.push_back({"/v1/jobs/{id}/{file}", "GET, HEAD"});
    } else if (r.path == std::string_view("/assets/")) {
      out.push_back({"/assets/{file}", r.allow});
    } else {
      out.push_back({r.path, r.allow});
    }
  }
  return out;
}

std::string shortened(std::string_view s) {
  constexpr std::size_t kMax = 120;
  return s.size() <= kMax ? std::string(s) : std::string(s.substr(0, kMax)) + "...";
}

void log_line(const std::string& line) {
  // One write: a line built with several << would interleave with other threads' lines.
  std::cerr << (line + "\n") << std::flush;
}

std::string request_id(const std::string& given) {
  const bool plain =
      !given.empty() && given.size() <= 64 && std::all_of(given.begin(), given.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.';
      });
  if (plain) return given;
  thread_local std::mt19937_64 engine{std::random_device{}()};
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(engine()));
  return text;
}

}  // namespace stlrefine::server
