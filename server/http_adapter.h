// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Between the wire and the routes. The listening socket is cpp-httplib's (bind, accept:
// http_adapter.cpp is the only file that includes httplib.h); every accepted socket goes to
// the FrontEnd, which reads heads and bodies and writes answers itself. Here a read head
// becomes a library-neutral HttpRequest, and an HttpAnswer the bytes the front end writes:
// the status line, the fields, Content-Length, one byte range when asked for.

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "server/front_end.h"
#include "server/http.h"

namespace stlrefine::server {

//! The listening socket and its accept loop (cpp-httplib 0.11.4's, used for that only).
//!  - Its default socket options set SO_REUSEPORT: a second daemon on the same port would
//!    bind successfully and share the traffic. Ours set SO_REUSEADDR only.
//!  - The library listens with a backlog of 5; bind() widens it.
//!  - Its accept loop hands each socket to `on_accept` at once and never reads from it.
class Listener {
 public:
  explicit Listener(std::function<void(int fd)> on_accept);
  ~Listener();
  Listener(const Listener&) = delete;
  Listener& operator=(const Listener&) = delete;

  //! Binds `host`; port 0 picks a free port. Returns the bound port.
  //! \throw std::runtime_error when the address cannot be bound.
  int bind(const std::string& host, int port);
  //! Accepts until stop(). \pre bind() succeeded
  void listen();
  //! Makes listen() return (thread-safe).
  void stop();
  bool is_running() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

//! The request a head and its body make, the path percent-decoded as cpp-httplib decodes it
//! (a '+' stays a '+'). `body` must outlive the request.
HttpRequest to_http_request(const RequestHead& head, std::string_view body = {});

//! A complete small answer, as the front end writes it (HEAD: without the body).
std::string whole_answer(int status, const std::string& content_type, const std::string& body,
                         const Fields& fields, bool head_only);

//! What the front end writes for `answer` to `request`: the status line, the answer's fields
//! (a Content-Length among them only for a 304, which keeps the length the 200 would have
//! had), Content-Length, Connection: close, then the body, or one byte range of it when
//! `ranges` and a GET asked for one (206 with Content-Range; 416 with a problem body and only
//! X-Request-Id and Content-Range kept); a HEAD or a 304 without a body. `done` is called once
//! on the event loop when it is written (Complete: the body bytes of the answer) or abandoned
//! (the body bytes sent), with the status the head carried.
using AnswerDoneFn =
    std::function<void(int status, std::uint64_t body_bytes, const AnswerEnd& end)>;
Answer frame_answer(const HttpRequest& request, HttpAnswer answer, bool ranges, AnswerDoneFn done);

}  // namespace stlrefine::server
