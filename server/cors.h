// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Cross-origin requests from browser pages served elsewhere (a bureau's own portal calling
// this API): only for the origins the operator names (--cors-origin). Without any, no CORS
// header is ever sent and browsers keep their same-origin rule.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "server/http.h"

namespace stlrefine::server {

class CorsPolicy {
 public:
  CorsPolicy() = default;
  //! `origins`: "scheme://host[:port]" as a browser sends it in Origin (no path, no
  //! trailing slash), or "*" for any origin.
  //! \throw std::invalid_argument for anything else (naming the value).
  explicit CorsPolicy(std::vector<std::string> origins);

  bool enabled() const { return !origins_.empty(); }
  //! Is `origin` (a request's Origin field) one of the configured ones?
  bool allows(std::string_view origin) const;
  //! Fields for an answer to a request with this Origin (none when it is not allowed or
  //! absent): Access-Control-Allow-Origin, Vary and the fields a script may read.
  Fields answer_fields(std::string_view origin) const;
  //! Is this a preflight (OPTIONS with Origin and Access-Control-Request-Method)?
  static bool is_preflight(const HttpRequest& req);
  //! The fields of the 204 answering a preflight for a route allowing `allow_methods`, or
  //! nothing when the origin is not allowed (the caller answers 403).
  std::optional<Fields> preflight_fields(std::string_view origin,
                                         std::string_view allow_methods) const;

 private:
  std::vector<std::string> origins_;
  bool any_ = false;
};

}  // namespace stlrefine::server
