// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/http_adapter.h"

// httplib.h must see the same CPPHTTPLIB_*_SUPPORT macros Debian's libcpp-httplib.so was
// built with (Request has an extra member under OPENSSL): they come from the
// httplib::httplib target (pkg-config cflags), never from here. This is the only file of
// server/ that includes it.
#include <httplib.h>
#include <sys/socket.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <limits>
#include <optional>
#include <stdexcept>
#include <utility>

namespace stlrefine::server {

namespace {

//! The accept loop's task queue: runs the task at once. The task only hands the socket to
//! the FrontEnd (HttpServer::process_and_close_socket), so the accept loop never waits.
class InlineTaskQueue : public httplib::TaskQueue {
 public:
  void enqueue(std::function<void()> fn) override { fn(); }
  void shutdown() override {}
};

//! httplib::Server used for binding and accepting only: its accepted sockets go to the
//! FrontEnd, which reads requests and writes answers itself (the library's response writer
//! stops mid-body once its accept loop has ended, and serves Range requests past the body).
class HttpServer : public httplib::Server {
 public:
  std::function<void(socket_t)> on_accept;

  //! 0.11.4 listens with a backlog of 5 (CPPHTTPLIB_LISTEN_BACKLOG, built into the shared
  //! library); listen() again on the bound socket raises it.
  void widen_backlog() {
    const socket_t sock = svr_sock_;
    if (sock != INVALID_SOCKET) ::listen(sock, SOMAXCONN);
  }

 private:
  bool process_and_close_socket(socket_t sock) override {
    on_accept(sock);
    return true;
  }
};

std::string lowercase(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

//! A byte range of an answer (RFC 9110 14.1.2).
struct ByteRange {
  enum class Kind { Whole, Partial, Unsatisfiable };
  Kind kind = Kind::Whole;
  std::uint64_t first = 0, last = 0;  // Partial: inclusive, inside the body
};

// A decimal number; saturates at the largest value (a last position past the body is
// clamped anyway, a first position past it is unsatisfiable either way).
std::optional<std::uint64_t> range_number(std::string_view text) {
  if (text.empty() ||
      !std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return std::nullopt;
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec == std::errc::result_out_of_range) return std::numeric_limits<std::uint64_t>::max();
  if (ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

//! The one range of `header` against a body of `length` bytes. A header that is not one
//! well-formed byte range (another unit, bad syntax, several ranges) is ignored: the whole
//! body is sent, as RFC 9110 allows. Nothing outside [0, length) is ever selected.
ByteRange parse_byte_range(std::string_view header, std::uint64_t length) {
  ByteRange whole;
  constexpr std::string_view kUnit = "bytes=";
  if (header.size() < kUnit.size() || lowercase(header.substr(0, kUnit.size())) != kUnit)
    return whole;
  std::string_view spec = header.substr(kUnit.size());
  while (!spec.empty() && (spec.front() == ' ' || spec.front() == '\t')) spec.remove_prefix(1);
  while (!spec.empty() && (spec.back() == ' ' || spec.back() == '\t')) spec.remove_suffix(1);
  const std::size_t dash = spec.find('-');
  if (dash == std::string_view::npos || spec.find(',') != std::string_view::npos) return whole;
  const std::string_view first_text = spec.substr(0, dash), last_text = spec.substr(dash + 1);
  ByteRange r;
  if (first_text.empty()) {  // a suffix: the last N bytes
    const std::optional<std::uint64_t> suffix = range_number(last_text);
    if (!suffix) return whole;
    if (*suffix == 0 || length == 0) return {ByteRange::Kind::Unsatisfiable, 0, 0};
    r.first = length - std::min(*suffix, length);
    r.last = length - 1;
  } else {
    const std::optional<std::uint64_t> first = range_number(first_text);
    if (!first) return whole;
    std::uint64_t last = std::numeric_limits<std::uint64_t>::max();
    if (!last_text.empty()) {
      const std::optional<std::uint64_t> given = range_number(last_text);
      if (!given || *given < *first) return whole;  // invalid: ignored
      last = *given;
    }
    if (*first >= length) return {ByteRange::Kind::Unsatisfiable, 0, 0};
    r.first = *first;
    r.last = std::min(last, length - 1);
  }
  r.kind = ByteRange::Kind::Partial;
  return r;
}

std::string status_line(int status) {
  return "HTTP/1.1 " + std::to_string(status) + " " + api::reason_phrase(status) + "\r\n";
}

}  // namespace

struct Listener::Impl {
  HttpServer http;
};

Listener::Listener(std::function<void(int fd)> on_accept) : impl_(std::make_unique<Impl>()) {
  impl_->http.new_task_queue = [] { return new InlineTaskQueue; };
  impl_->http.on_accept = std::move(on_accept);
  // The library's default options add SO_REUSEPORT, with which a second daemon binds the
  // same port and silently takes half the connections. SO_REUSEADDR alone still allows a
  // quick restart.
  impl_->http.set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
}

Listener::~Listener() = default;

int Listener::bind(const std::string& host, int port) {
  if (port < 0 || port > 65535) throw std::runtime_error("port must be in [0, 65535]");
  if (port == 0) {
    const int bound = impl_->http.bind_to_any_port(host);
    if (bound < 0) throw std::runtime_error("cannot bind " + host + " (any port)");
    impl_->http.widen_backlog();
    return bound;
  }
  if (!impl_->http.bind_to_port(host, port))
    throw std::runtime_error("cannot bind " + host + ":" + std::to_string(port));
  impl_->http.widen_backlog();
  return port;
}

void Listener::listen() {
  impl_->http.listen_after_bind();
}

void Listener::stop() {
  impl_->http.stop();
}

bool Listener::is_running() const {
  return impl_->http.is_running();
}

HttpRequest to_http_request(const RequestHead& head, std::string_view body) {
  HttpRequest req;
  req.method = head.method;
  req.target = head.target;
  req.version = head.version;
  const std::size_t q = head.target.find('?');
  req.path = httplib::detail::decode_url(head.target.substr(0, q), false);
  for (const auto& [name, value] : head.fields) req.headers.emplace(name, value);
  req.remote_addr = head.remote_ip;
  req.remote_port = head.remote_port;
  req.body = body;
  return req;
}

std::string whole_answer(int status, const std::string& content_type, const std::string& body,
                         const Fields& fields, bool head_only) {
  std::string out = status_line(status);
  // A 204 has neither (RFC 9110 8.6, 15.3.5).
  if (status != api::http::kNoContent) {
    out += "Content-Type: " + content_type + "\r\n";
    out += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  }
  out += "Connection: close\r\n";
  for (const auto& [name, value] : fields) out += name + ": " + value + "\r\n";
  out += "\r\n";
  if (!head_only) out += body;
  return out;
}

Answer frame_answer(const HttpRequest& req, HttpAnswer res, bool ranges, AnswerDoneFn done) {
  const bool small = !res.has_large_body();
  const std::uint64_t length =
      small ? res.body.size()
            : res.large.body.size() + res.large.file_length + res.large.made_length;
  std::uint64_t first = 0, count = length;
  // A stream's end is the close, and it has no byte ranges.
  const bool stream = !small && res.large.stream;
  if (ranges && !stream) {
    res.set_header("Accept-Ranges", "bytes");
    // If-Range: the range only applies to the representation the client has (its ETag).
    const std::string if_range = req.header("If-Range");
    const bool same =
        if_range.empty() || (res.has_header("ETag") && if_range == res.header("ETag"));
    if (res.status == api::http::kOk && req.method == "GET" && req.has_header("Range") && same) {
      const ByteRange range = parse_byte_range(req.header("Range"), length);
      if (range.kind == ByteRange::Kind::Partial) {
        res.status = api::http::kPartialContent;
        res.set_header("Content-Range", "bytes " + std::to_string(range.first) + "-" +
                                            std::to_string(range.last) + "/" +
                                            std::to_string(length));
        first = range.first;
        count = range.last - range.first + 1;
      } else if (range.kind == ByteRange::Kind::Unsatisfiable) {
        HttpAnswer refused;
        refused.set_header("X-Request-Id", res.header("X-Request-Id"));
        refused.set_header("Content-Range", "bytes */" + std::to_string(length));
        api::Problem p = api::range_not_satisfiable(
            "range-not-satisfiable",
            "the range is outside the " + std::to_string(length) + "-byte body");
        p.field = "Range";
        refused.status = p.status;
        refused.set_content(api::problem_body(p), api::kProblemContentType);
        return frame_answer(req, std::move(refused), false, std::move(done));
      }
    }
  }
  // The head: status line, the handler's fields, our framing.
  std::string head = status_line(res.status);
  const bool not_modified =
      res.status == api::http::kNotModified;  // keeps the length the 200 would have had
  for (const auto& [name, value] : res.headers) {
    if (!not_modified && lowercase(name) == "content-length") continue;
    head += name + ": " + value + "\r\n";
  }
  if (!not_modified && !stream) head += "Content-Length: " + std::to_string(count) + "\r\n";
  head += "Connection: close\r\n\r\n";
  const bool head_only = req.method == "HEAD" || not_modified;
  Answer out;
  if (head_only) {
    out.head = std::move(head);
  } else if (small) {
    out.head = std::move(head);
    out.head.append(res.body, static_cast<std::size_t>(first), static_cast<std::size_t>(count));
  } else {
    out = std::move(res.large);
    out.head = std::move(head);
    if (out.file >= 0) {
      out.file_offset += first;
      out.file_length = count;
    } else if (out.made) {
      out.made_offset += first;
      out.made_length = count;
    } else {
      out.body = out.body.substr(static_cast<std::size_t>(first), static_cast<std::size_t>(count));
    }
  }
  if (stream) {
    out.done = [done = std::move(done), status = res.status,
                head_bytes = out.head.size()](const AnswerEnd& end) {
      done(status, end.bytes_sent > head_bytes ? end.bytes_sent - head_bytes : 0, end);
    };
    return out;
  }
  const std::uint64_t body_bytes = head_only ? 0 : count;
  const std::uint64_t head_bytes = out.head.size() - (small && !head_only ? count : 0);
  out.done = [done = std::move(done), status = res.status, head_bytes,
              body_bytes](const AnswerEnd& end) {
    if (end.outcome == AnswerEnd::Outcome::Complete) return done(status, body_bytes, end);
    done(status, end.bytes_sent > head_bytes ? end.bytes_sent - head_bytes : 0, end);
  };
  return out;
}

}  // namespace stlrefine::server
