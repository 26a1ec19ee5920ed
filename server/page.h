// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The web page (web/: index.html and its assets, embedded at build time), served at / and
// /assets/{file} without an API key.

#include <string_view>

#include "server/http.h"
#include "server/route_context.h"

namespace stlrefine::server {

//! The embedded file `name` ("index.html", an asset), or 404.
void serve_page(const RouteContext& ctx, const HttpRequest& req, std::string_view name,
                HttpAnswer& res);

}  // namespace stlrefine::server
