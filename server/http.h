// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// What a route handler sees of HTTP: a request that carries its body, and an answer it
// fills. No HTTP library type: the front end (front_end.h) reads and writes the bytes, the
// adapter (http_adapter.h) turns a read head into an HttpRequest and an HttpAnswer into what
// the front end writes. A handler can be called with a request made in a test, no socket.

#include <cstddef>
#include <map>
#include <string>
#include <string_view>

#include "api/params.h"
#include "api/problem.h"
#include "server/front_end.h"

namespace stlrefine::server {

//! Header field names compare without case (RFC 9110 5.1).
struct FieldNameLess {
  bool operator()(const std::string& a, const std::string& b) const;
};
//! Header fields in the order of their names (ignoring case), every value of a repeated
//! field kept in the order it came.
using Fields = std::multimap<std::string, std::string, FieldNameLess>;

//! A request as the routes see it.
struct HttpRequest {
  std::string method;
  std::string target;  //!< as sent: the path and the query
  std::string path;    //!< the target's path, percent-decoded
  std::string version;
  Fields headers;
  std::string remote_addr;
  int remote_port = 0;
  //! The whole body (Content-Length bytes), kept alive by whoever made the request; empty
  //! when the route takes none or before it is read.
  std::string_view body;

  bool has_header(const std::string& name) const;
  //! The first value of a field, or "".
  std::string header(const std::string& name) const;
  std::size_t header_count(const std::string& name) const;
  //! The parameters, from the query string only (never from a form-encoded body, which
  //! here is STL bytes). \throw Error(InvalidParameter) for a malformed query.
  api::RawParams parameters() const;
};

//! An answer as a route fills it: a status, fields, and a body that is small (`body`) or
//! large and not copied (`large`: a view kept alive by large.keep, a file, or bytes made as
//! they are sent, of a length known before; large.head stays empty). The adapter adds the
//! framing (Content-Length, Connection, X-Request-Id, byte ranges).
struct HttpAnswer {
  int status = api::http::kOk;
  Fields headers;
  std::string body;
  Answer large;

  //! Adds a field (a value with CR or LF is dropped: it could not be sent).
  void set_header(const std::string& name, const std::string& value);
  //! The body and its Content-Type (replacing any Content-Type set before).
  void set_content(std::string content, const std::string& content_type);
  bool has_header(const std::string& name) const;
  std::string header(const std::string& name) const;
  bool has_large_body() const {
    return !large.body.empty() || large.file >= 0 || large.made || large.stream;
  }
};

}  // namespace stlrefine::server
