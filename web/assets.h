// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <span>
#include <string_view>

// The web page's files, embedded into stlrefined at build time (web/CMakeLists.txt runs
// web/embed_assets.cpp over web/page/ and the three.js files npm ci installed).
namespace stlrefine::web {

struct Asset {
  std::string_view name;          //!< "index.html", "app.js", "three.module.js", ...
  std::string_view content_type;  //!< "text/javascript; charset=utf-8", ...
  std::string_view etag;          //!< strong validator, quoted: "\"0123456789abcdef\""
  std::string_view bytes;
};

//! Every embedded file; empty when the page was not built.
std::span<const Asset> assets();
//! The embedded file with this name, or null.
const Asset* find_asset(std::string_view name);
//! Why the page was not built (node or npm missing, STLREFINE_WEB=OFF); empty when it was.
std::string_view missing_reason();

}  // namespace stlrefine::web
