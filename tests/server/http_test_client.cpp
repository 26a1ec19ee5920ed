// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "http_test_client.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <stdexcept>

namespace stlrefine::test {

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

}  // namespace

std::vector<RawResponse> parse_responses(std::string_view raw) {
  std::vector<RawResponse> out;
  while (!raw.empty()) {
    const std::size_t head_end = raw.find("\r\n\r\n");
    if (head_end == std::string_view::npos || raw.substr(0, 5) != "HTTP/") break;
    std::string_view head = raw.substr(0, head_end);
    RawResponse r;
    const std::size_t line_end = head.find("\r\n");
    const std::string_view status_line = head.substr(0, line_end);
    const std::size_t sp = status_line.find(' ');
    if (sp == std::string_view::npos) break;
    r.status = std::stoi(std::string(status_line.substr(sp + 1, 3)));
    std::string_view rest =
        line_end == std::string_view::npos ? std::string_view() : head.substr(line_end + 2);
    while (!rest.empty()) {
      const std::size_t e = rest.find("\r\n");
      const std::string_view line = rest.substr(0, e);
      const std::size_t colon = line.find(':');
      if (colon != std::string_view::npos)
        r.headers[lower(line.substr(0, colon))] = std::string(trim(line.substr(colon + 1)));
      rest = e == std::string_view::npos ? std::string_view() : rest.substr(e + 2);
    }
    raw.remove_prefix(head_end + 4);
    // Without Content-Length the body runs to the close (1xx answers have none).
    std::size_t length = r.status < 200 ? 0 : raw.size();
    if (r.has_header("content-length")) length = std::stoul(r.header("content-length"));
    if (length > raw.size()) {  // truncated: keep what there is, and stop
      r.body = std::string(raw);
      out.push_back(std::move(r));
      break;
    }
    r.body = std::string(raw.substr(0, length));
    raw.remove_prefix(length);
    out.push_back(std::move(r));
  }
  return out;
}

RawConnection::RawConnection(int port) {
  fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd_ < 0) throw std::runtime_error("socket() failed");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd_);
    throw std::runtime_error("connect() failed");
  }
}

RawConnection::~RawConnection() {
  if (fd_ >= 0) ::close(fd_);
}

bool RawConnection::send(std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
  return true;
}

void RawConnection::shutdown_write() {
  ::shutdown(fd_, SHUT_WR);
}

std::string RawConnection::read_until(std::string_view marker, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!closed_ && (marker.empty() || buffer_.find(marker) == std::string::npos)) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) break;
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
    char chunk[65536];
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {  // 0: orderly close; < 0: reset. Either way nothing more will come.
      closed_ = true;
      break;
    }
    buffer_.append(chunk, static_cast<std::size_t>(n));
  }
  std::string out;
  if (marker.empty() || closed_) {
    out.swap(buffer_);
  } else {
    const std::size_t at = buffer_.find(marker);
    const std::size_t end = at == std::string::npos ? buffer_.size() : at + marker.size();
    out = buffer_.substr(0, end);
    buffer_.erase(0, end);
  }
  return out;
}

std::string RawConnection::read_all(std::chrono::milliseconds timeout) {
  return read_until({}, timeout);
}

std::string exchange(int port, std::string_view request, std::chrono::milliseconds timeout) {
  RawConnection c(port);
  c.send(request);  // the server may close before taking it all; what it wrote still counts
  return c.read_all(timeout);
}

std::string post_text(std::string_view target, std::string_view content_type, std::string_view body,
                      std::string_view extra_headers, bool with_length) {
  std::string r = "POST " + std::string(target) + " HTTP/1.1\r\nHost: 127.0.0.1\r\n";
  if (!content_type.empty()) r += "Content-Type: " + std::string(content_type) + "\r\n";
  if (with_length) r += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  r += extra_headers;
  r += "\r\n";
  r += body;
  return r;
}

}  // namespace stlrefine::test
