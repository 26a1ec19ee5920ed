// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A raw HTTP/1.1 client over a loopback socket, for the requests httplib's own client
// will not send (chunked uploads, no Content-Length, lying headers, pipelining) and for
// looking at exactly what the server wrote.

#include <chrono>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace stlrefine::test {

//! One parsed response.
struct RawResponse {
  int status = 0;
  std::map<std::string, std::string> headers;  //!< names lower-cased; last value wins
  std::string body;
  bool has_header(const std::string& lower_name) const { return headers.count(lower_name) > 0; }
  std::string header(const std::string& lower_name) const {
    auto it = headers.find(lower_name);
    return it == headers.end() ? std::string() : it->second;
  }
};

//! Every complete response in `raw` (a connection may, wrongly, carry several).
//! Bodies are framed by Content-Length, else run to the end; 1xx answers (no body) are
//! parsed as responses too.
std::vector<RawResponse> parse_responses(std::string_view raw);

//! A TCP connection to 127.0.0.1:port.
class RawConnection {
 public:
  explicit RawConnection(int port);
  ~RawConnection();
  RawConnection(const RawConnection&) = delete;
  RawConnection& operator=(const RawConnection&) = delete;

  //! Sends everything; false when the peer has closed (EPIPE / ECONNRESET).
  bool send(std::string_view bytes);
  //! No more bytes from us (FIN): how a client ends a body without Content-Length.
  void shutdown_write();
  //! Reads until `marker` is in what was read, the peer closes, or `timeout`.
  std::string read_until(std::string_view marker, std::chrono::milliseconds timeout);
  //! Reads until the peer closes (or resets) or `timeout`. `closed()` tells which.
  std::string read_all(std::chrono::milliseconds timeout);
  bool closed() const { return closed_; }

 private:
  int fd_ = -1;
  bool closed_ = false;
  std::string buffer_;
};

//! Sends `request` on a fresh connection and returns all the server wrote until it closed
//! (at most `timeout`).
std::string exchange(int port, std::string_view request,
                     std::chrono::milliseconds timeout = std::chrono::seconds(5));

//! "POST target HTTP/1.1" with Host, the given extra header lines (each ending in \r\n),
//! and Content-Length + body unless `with_length` is false.
std::string post_text(std::string_view target, std::string_view content_type, std::string_view body,
                      std::string_view extra_headers = {}, bool with_length = true);

}  // namespace stlrefine::test
