// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/cors.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>

namespace stlrefine::server {

namespace {

// What a browser puts in Origin (RFC 6454 serialisation): scheme "://" host [":" port],
// lower case scheme and host, no path.
bool serialised_origin(std::string_view o) {
  const std::size_t sep = o.find("://");
  if (sep == std::string_view::npos || sep == 0) return false;
  for (char c : o.substr(0, sep))
    if (!(std::islower(static_cast<unsigned char>(c)) ||
          std::isdigit(static_cast<unsigned char>(c)) || c == '+' || c == '-' || c == '.'))
      return false;
  const std::string_view authority = o.substr(sep + 3);
  if (authority.empty() || authority.size() > 255) return false;
  for (char c : authority)
    if (!(std::islower(static_cast<unsigned char>(c)) ||
          std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == '.' || c == ':' ||
          c == '[' || c == ']'))
      return false;
  return true;
}

// Request fields a page may send: the key, the body's type and name, byte ranges.
constexpr std::string_view kAllowedHeaders =
    "Authorization, X-Api-Key, Content-Type, Content-Disposition, Range, If-None-Match, "
    "X-Request-Id";
// Answer fields a script may read besides the CORS-safelisted ones.
constexpr std::string_view kExposedHeaders =
    "Location, Retry-After, Content-Disposition, X-Request-Id, X-Stlrefine-Report, ETag, "
    "Content-Range, Accept-Ranges";

}  // namespace

CorsPolicy::CorsPolicy(std::vector<std::string> origins) {
  for (std::string& o : origins) {
    if (o == "*") {
      any_ = true;
    } else if (!serialised_origin(o)) {
      throw std::invalid_argument("--cors-origin: \"" + o +
                                  "\" is not an origin (scheme://host[:port], lower case, no "
                                  "path) nor *");
    }
    origins_.push_back(std::move(o));
  }
}

bool CorsPolicy::allows(std::string_view origin) const {
  if (origin.empty() || !enabled()) return false;
  if (any_) return true;
  return std::find(origins_.begin(), origins_.end(), origin) != origins_.end();
}

Fields CorsPolicy::answer_fields(std::string_view origin) const {
  Fields f;
  if (!enabled()) return f;
  // The answer depends on Origin whenever CORS is on: caches must key on it.
  f.emplace("Vary", "Origin");
  if (!allows(origin)) return f;
  f.emplace("Access-Control-Allow-Origin", any_ ? std::string("*") : std::string(origin));
  f.emplace("Access-Control-Expose-Headers", std::string(kExposedHeaders));
  return f;
}

bool CorsPolicy::is_preflight(const HttpRequest& req) {
  return req.method == "OPTIONS" && req.has_header("Origin") &&
         req.has_header("Access-Control-Request-Method");
}

std::optional<Fields> CorsPolicy::preflight_fields(std::string_view origin,
                                                   std::string_view allow_methods) const {
  if (!allows(origin)) return std::nullopt;
  Fields f = answer_fields(origin);
  f.emplace("Access-Control-Allow-Methods", std::string(allow_methods));
  f.emplace("Access-Control-Allow-Headers", std::string(kAllowedHeaders));
  f.emplace("Access-Control-Max-Age", "600");
  return f;
}

}  // namespace stlrefine::server
