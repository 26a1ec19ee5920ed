// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A request head as the front end reads it, and its strict parser.

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace stlrefine::server {

//! A request line and header fields as the client sent them (values trimmed).
struct RequestHead {
  std::string method, target, version;
  std::vector<std::pair<std::string, std::string>> fields;
  std::string remote_ip;
  int remote_port = 0;

  //! The first value of a field (names are case-insensitive), or nullptr.
  const std::string* find(std::string_view name) const;
};

//! Why a head was refused: the status, the problem's slug and detail.
struct HeadError {
  int status;
  const char* slug;
  std::string detail;
};

//! Parses `text` (a whole head, ending with the blank line) into `head`. Strict: what is
//! accepted here is exactly what cpp-httplib parses the same way (no bare CR or LF, no
//! folded lines, no controls, one space between the request line's parts, at most
//! FrontEnd::kMaxFields fields of at most FrontEnd::kMaxLineBytes, a target of at most
//! FrontEnd::kMaxTargetBytes that is an absolute path, HTTP/1.0 or 1.1). Nullopt when it is
//! well-formed.
std::optional<HeadError> parse_head(std::string_view text, RequestHead& head);

bool equals_ignore_case(std::string_view a, std::string_view b);

}  // namespace stlrefine::server
