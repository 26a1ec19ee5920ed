// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/request_head.h"

#include <algorithm>
#include <cctype>
#include <cstring>

#include "api/problem.h"
#include "server/front_end.h"

namespace stlrefine::server {

namespace {

// RFC 9110 tchar.
bool is_tchar(unsigned char c) {
  return std::isalnum(c) || std::strchr("!#$%&'*+-.^_`|~", c) != nullptr;
}

std::string_view trim_ows(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

}  // namespace

bool equals_ignore_case(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

const std::string* RequestHead::find(std::string_view name) const {
  for (const auto& field : fields)
    if (equals_ignore_case(field.first, name)) return &field.second;
  return nullptr;
}

std::optional<HeadError> parse_head(std::string_view text, RequestHead& head) {
  // text ends with "\r\n\r\n". Empty lines before the request line are skipped (RFC 9112
  // 2.2); a head that is nothing else has no request line at all.
  std::size_t line_start = 0;
  while (text.substr(line_start, 2) == "\r\n" && line_start + 4 < text.size()) line_start += 2;
  if (text.substr(line_start, 2) == "\r\n")
    return HeadError{api::http::kBadRequest, "bad-request", "the request line is empty"};
  std::size_t lines = 0;
  while (line_start < text.size()) {
    const std::size_t end = text.find("\r\n", line_start);
    const std::string_view line = text.substr(line_start, end - line_start);
    line_start = end + 2;
    if (line.empty()) break;  // the blank line
    for (const char ch : line) {
      const auto c = static_cast<unsigned char>(ch);
      if (c == '\r' || c == '\n' || c == 0)
        return HeadError{api::http::kBadRequest, "bad-request",
                         "a bare CR, LF or NUL in the request head"};
    }
    if (lines++ == 0) {
      const std::size_t sp1 = line.find(' ');
      const std::size_t sp2 = sp1 == std::string_view::npos ? sp1 : line.find(' ', sp1 + 1);
      if (sp2 == std::string_view::npos || line.find(' ', sp2 + 1) != std::string_view::npos)
        return HeadError{api::http::kBadRequest, "bad-request",
                         "the request line is not METHOD TARGET VERSION"};
      head.method = std::string(line.substr(0, sp1));
      head.target = std::string(line.substr(sp1 + 1, sp2 - sp1 - 1));
      head.version = std::string(line.substr(sp2 + 1));
      if (head.method.empty() || !std::all_of(head.method.begin(), head.method.end(), [](char c) {
            return is_tchar(static_cast<unsigned char>(c));
          }))
        return HeadError{api::http::kBadRequest, "bad-request", "the method is not a token"};
      if (head.target.size() > FrontEnd::kMaxTargetBytes)
        return HeadError{api::http::kUriTooLong, "uri-too-long",
                         "the request target is longer than 8192 bytes"};
      if (head.target.empty() || head.target.front() != '/' ||
          std::any_of(head.target.begin(), head.target.end(), [](char ch) {
            const auto c = static_cast<unsigned char>(ch);
            return c <= 0x20 || c == 0x7f;
          }))
        return HeadError{api::http::kBadRequest, "bad-request",
                         "the request target must be an absolute path"};
      if (head.version != "HTTP/1.1" && head.version != "HTTP/1.0")
        return HeadError{api::http::kBadRequest, "bad-request",
                         "only HTTP/1.0 and HTTP/1.1 are spoken here"};
      continue;
    }
    if (head.fields.size() >= FrontEnd::kMaxFields)
      return HeadError{api::http::kHeaderFieldsTooLarge, "header-fields-too-large",
                       "more than " + std::to_string(FrontEnd::kMaxFields) + " header fields"};
    if (line.size() > FrontEnd::kMaxLineBytes)
      return HeadError{api::http::kHeaderFieldsTooLarge, "header-fields-too-large",
                       "a header field line is longer than " +
                           std::to_string(FrontEnd::kMaxLineBytes) + " bytes"};
    const std::size_t colon = line.find(':');
    if (colon == 0 || colon == std::string_view::npos)
      return HeadError{api::http::kBadRequest, "bad-request", "a header field line has no name"};
    const std::string_view name = line.substr(0, colon);
    if (!std::all_of(name.begin(), name.end(),
                     [](char c) { return is_tchar(static_cast<unsigned char>(c)); }))
      return HeadError{api::http::kBadRequest, "bad-request", "a header field name is not a token"};
    const std::string_view value = trim_ows(line.substr(colon + 1));
    if (std::any_of(value.begin(), value.end(), [](char ch) {
          const auto c = static_cast<unsigned char>(ch);
          return (c < 0x20 && c != '\t') || c == 0x7f;
        }))
      return HeadError{api::http::kBadRequest, "bad-request",
                       "a header field value has a control character"};
    head.fields.emplace_back(std::string(name), std::string(value));
  }
  return std::nullopt;
}

}  // namespace stlrefine::server
