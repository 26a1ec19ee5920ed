// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/page.h"

#include "web/assets.h"

namespace stlrefine::server {

// The embedded page (web/assets.h). Cache-Control no-cache with a strong ETag: a browser
// revalidates and gets 304, and never keeps a page from an older daemon.
void serve_page(const RouteContext& ctx, const HttpRequest& req, std::string_view name,
                HttpAnswer& res) {
  if (web::assets().empty())
    return ctx.respond(res, api::not_found("page-not-built", std::string(web::missing_reason())));
  const web::Asset* asset = web::find_asset(name);
  if (!asset)
    return ctx.respond(res, api::not_found("not-found", "no route " + shortened(req.path)));
  res.set_header("ETag", std::string(asset->etag));
  res.set_header("Cache-Control", "no-cache");
  res.set_header("X-Content-Type-Options", "nosniff");
  if (name == "index.html") {
    res.set_header("Content-Security-Policy",
                   "default-src 'self'; img-src 'self' data: blob:; object-src 'none'; "
                   "base-uri 'none'; form-action 'none'; frame-ancestors 'none'");
    res.set_header("Referrer-Policy", "no-referrer");
  }
  const std::string match = req.header("If-None-Match");
  if (!match.empty() && (match == "*" || match.find(asset->etag) != std::string::npos)) {
    res.status = api::http::kNotModified;
    // The library writes "Content-Length: 0" on an empty answer; a 304 may only carry the
    // length the 200 would have had (RFC 9110 8.6).
    res.set_header("Content-Length", std::to_string(asset->bytes.size()));
    return;
  }
  res.set_header("Content-Type", std::string(asset->content_type));
  res.large.body = asset->bytes;  // embedded in the binary
}

}  // namespace stlrefine::server
