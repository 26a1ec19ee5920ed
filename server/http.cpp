// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/http.h"

#include <algorithm>
#include <cctype>

namespace stlrefine::server {

namespace {

bool has_crlf(const std::string& s) {
  return s.find_first_of("\r\n") != std::string::npos;
}

}  // namespace

bool FieldNameLess::operator()(const std::string& a, const std::string& b) const {
  return std::lexicographical_compare(
      a.begin(), a.end(), b.begin(), b.end(),
      [](unsigned char x, unsigned char y) { return std::tolower(x) < std::tolower(y); });
}

bool HttpRequest::has_header(const std::string& name) const {
  return headers.find(name) != headers.end();
}

std::string HttpRequest::header(const std::string& name) const {
  const auto it = headers.find(name);
  return it == headers.end() ? std::string() : it->second;
}

std::size_t HttpRequest::header_count(const std::string& name) const {
  return headers.count(name);
}

api::RawParams HttpRequest::parameters() const {
  const std::size_t q = target.find('?');
  if (q == std::string::npos) return {};
  return api::parse_query(std::string_view(target).substr(q + 1));
}

void HttpAnswer::set_header(const std::string& name, const std::string& value) {
  if (!has_crlf(name) && !has_crlf(value)) headers.emplace(name, value);
}

void HttpAnswer::set_content(std::string content, const std::string& content_type) {
  body = std::move(content);
  headers.erase("Content-Type");
  set_header("Content-Type", content_type);
}

bool HttpAnswer::has_header(const std::string& name) const {
  return headers.find(name) != headers.end();
}

std::string HttpAnswer::header(const std::string& name) const {
  const auto it = headers.find(name);
  return it == headers.end() ? std::string() : it->second;
}

}  // namespace stlrefine::server
