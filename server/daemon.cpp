// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/daemon.h"

// httplib.h must see the same CPPHTTPLIB_*_SUPPORT macros Debian's libcpp-httplib.so was
// built with (Request has an extra member under OPENSSL): they come from the
// httplib::httplib target (pkg-config cflags), never from here.
#include <arpa/inet.h>
#include <httplib.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <charconv>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <deque>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>
#include <new>
#include <optional>
#include <random>
#include <span>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "api/memory_model.h"
#include "api/params.h"
#include "api/pipeline.h"
#include "api/problem.h"
#include "api/zip.h"
#include "core/error.h"
#include "server/front_end.h"
#include "server/metrics.h"
#include "server/request_watch.h"
#include "slicer/writers.h"
#include "web/assets.h"

// Hardening around cpp-httplib 0.11.4 (Debian 12), and why each piece is needed:
//
//  - No library thread ever reads from a client. 0.11.4 reads a connection's head and body
//    on a pool thread with a per-recv timeout and no limit on the head's size or field
//    count: a few hundred clients trickling bytes starve every other request, and a 100 MB
//    header line is buffered whole. HttpServer hands every accepted socket to the
//    FrontEnd (front_end.h), one epoll thread that reads heads (bounded size, field count
//    and time: 431 / 408), decides on them here (Impl::decide), reads accepted bodies at a
//    minimum rate, and only then gives the complete request to a worker, which runs the
//    library's own request processing on a stream that replays the head. /healthz and
//    /readyz are answered on the event loop itself, so they never wait for a worker.
//  - decide() runs every check that needs only the request line and headers before the
//    body is read: route (404), method (405), Transfer-Encoding or no Content-Length on
//    POST (411: 0.11.4 reads such bodies without applying the payload limit), any
//    Content-Encoding (415: the library would inflate gzip/brotli bodies with no limit on
//    the inflated size), Content-Type (415), Content-Length over the cap (413), a body on
//    a route that takes none (400), parameters (400) and a full house (503). An
//    `Expect: 100-continue` gets the refusal instead of 100, so a refused upload is never
//    sent. After any answer the front end drops what the client still sends and then
//    closes, so a client still uploading is not reset and reads its answer.
//  - keep_alive_max_count(1): every connection carries one request.
//  - set_payload_max_length stays as the library's own backstop; the error handler gives
//    every library answer >= 400 with an empty body (400, 404, 413, ...) a problem+json body.
//  - Compute requests take a ComputeSlots lease and get 503 + Retry-After at once when
//    none is free. A RequestWatch cancels them when the client hangs up or their deadline
//    (--request-deadline) passes.
//  - Memory: decide() reserves a compute request's (or job's) body in the MemoryBudget
//    before it is read (503 when it does not fit now, 413 when it never can); the handler grows
//    that to the request's predicted peak (api/memory_model.h) before any work (422 naming the
//    parameter when one request may never have that much, 503 when it does not fit next to
//    the running ones) and shrinks it to the answer once computed; the rest is given back
//    when the connection closes.
//  - httplib's default socket options set SO_REUSEPORT: a second daemon on the same port
//    would bind successfully and share the traffic. Ours set SO_REUSEADDR only. The
//    library listens with a backlog of 5; HttpServer widens it.
//  - Without an exception handler 0.11.4 copies what() into an EXCEPTION_WHAT response
//    header; ours answers a generic 500 and logs what() on stderr only.

namespace stlrefine::server {

namespace {

using httplib::Request;
using httplib::Response;
using HandlerResponse = httplib::Server::HandlerResponse;

constexpr const char* kStlContentType = "model/stl";
constexpr const char* kJsonContentType = "application/json";
constexpr const char* kReportHeader = "X-Stlrefine-Report";
constexpr const char* kZipContentType = "application/zip";

//! The accept loop's task queue: runs the task at once. The task only hands the socket to
//! the FrontEnd (HttpServer::process_and_close_socket), so the accept loop never waits.
class InlineTaskQueue : public httplib::TaskQueue {
 public:
  void enqueue(std::function<void()> fn) override { fn(); }
  void shutdown() override {}
};

//! httplib::Server whose accepted sockets go to the FrontEnd instead of a pool thread, and
//! whose request processing runs on a stream the FrontEnd has already read.
class HttpServer : public httplib::Server {
 public:
  std::function<void(socket_t)> on_accept;

  //! The library's processing of one request (parse, route, handlers, answer, logger).
  bool serve(httplib::Stream& stream) {
    bool closed = false;
    return process_request(stream, true, closed, nullptr);
  }
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

//! A connection whose request the FrontEnd has read: reads replay the head (the body is
//! taken from FrontEnd::current() by the handlers, without a copy); writes go to the socket.
class ConnectionStream : public httplib::Stream {
 public:
  ConnectionStream(const ReadRequest& request, std::chrono::milliseconds write_timeout)
      : request_(request), write_timeout_(write_timeout) {}

  bool is_readable() const override { return read_ < request_.head.size(); }
  bool is_writable() const override {
    pollfd p{request_.fd, POLLOUT, 0};
    return ::poll(&p, 1, static_cast<int>(write_timeout_.count())) > 0 &&
           (p.revents & (POLLERR | POLLHUP)) == 0;
  }
  ssize_t read(char* ptr, std::size_t size) override {
    const std::size_t n = std::min(size, request_.head.size() - read_);
    std::memcpy(ptr, request_.head.data() + read_, n);
    read_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, std::size_t size) override {
    for (;;) {
      if (!is_writable()) return -1;
      const ssize_t n = ::send(request_.fd, ptr, size, MSG_NOSIGNAL);
      if (n >= 0 || (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) return n;
    }
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = request_.remote_ip;
    port = request_.remote_port;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage addr{};
    socklen_t len = sizeof addr;
    if (::getsockname(request_.fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) return;
    char text[INET6_ADDRSTRLEN] = {};
    const void* where =
        addr.ss_family == AF_INET6
            ? static_cast<const void*>(&reinterpret_cast<const sockaddr_in6*>(&addr)->sin6_addr)
            : &reinterpret_cast<const sockaddr_in*>(&addr)->sin_addr;
    ::inet_ntop(addr.ss_family, where, text, sizeof text);
    ip = text;
    port =
        ntohs(addr.ss_family == AF_INET6 ? reinterpret_cast<const sockaddr_in6*>(&addr)->sin6_port
                                         : reinterpret_cast<const sockaddr_in*>(&addr)->sin_port);
  }
  socket_t socket() const override { return request_.fd; }

 private:
  const ReadRequest& request_;
  std::chrono::milliseconds write_timeout_;
  std::size_t read_ = 0;
};

enum class RouteKind {
  Compute,  // POST with an STL body, answered synchronously, takes a compute slot
  Submit,   // POST /v1/jobs: an STL body queued as a job
  JobItem,  // /v1/jobs/{id} and /v1/jobs/{id}/{file}
  Plain,    // GET without a body
  Page,     // the web page: / and /assets/{file}, embedded at build time (web/), no API key
};

struct Route {
  const char* path;   // a prefix when kind == JobItem
  const char* allow;  // the Allow header of a 405
  RouteKind kind;
};

constexpr Route kRoutes[] = {
    {"/v1/refine", "POST", RouteKind::Compute},
    {"/v1/slice", "POST", RouteKind::Compute},
    {"/v1/info", "POST", RouteKind::Compute},
    {"/v1/jobs", "POST", RouteKind::Submit},
    {"/v1/jobs/", "GET, HEAD, DELETE", RouteKind::JobItem},
    {"/v1/openapi.json", "GET, HEAD", RouteKind::Plain},
    {"/metrics", "GET, HEAD", RouteKind::Plain},
    {"/healthz", "GET, HEAD", RouteKind::Plain},
    {"/readyz", "GET, HEAD", RouteKind::Plain},
    {"/", "GET, HEAD", RouteKind::Page},
    {"/assets/", "GET, HEAD", RouteKind::Page},
};

const Route* find_route(const std::string& path) {
  for (const Route& r : kRoutes) {
    const std::string_view p = r.path;
    const bool prefix = p.size() > 1 && p.back() == '/';  // "/v1/jobs/", "/assets/"
    if (prefix ? path.size() > p.size() && path.starts_with(p) : path == p) return &r;
  }
  return nullptr;
}

bool has_body(const Route& route) {
  return route.kind == RouteKind::Compute || route.kind == RouteKind::Submit;
}

bool method_allowed(const Route& route, const std::string& method) {
  // allow is a comma-separated list of tokens
  std::string_view allow = route.allow;
  while (!allow.empty()) {
    const std::size_t comma = allow.find(',');
    std::string_view token = allow.substr(0, comma);
    while (!token.empty() && token.front() == ' ') token.remove_prefix(1);
    if (token == method) return true;
    if (comma == std::string_view::npos) break;
    allow.remove_prefix(comma + 1);
  }
  return false;
}

// The pre-routing handler and the logger of one request run on the same worker thread.
thread_local std::chrono::steady_clock::time_point request_start{};

void mark_request_start() {
  request_start = std::chrono::steady_clock::now();
}

double request_seconds() {
  if (request_start == std::chrono::steady_clock::time_point{}) return 0;
  const double s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - request_start).count();
  request_start = {};
  return s;
}

std::string iso8601_now() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t secs = std::chrono::system_clock::to_time_t(now);
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char text[96];
  std::snprintf(text, sizeof text, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(ms));
  return text;
}

// Result files a job may have.
bool job_file_name(const std::string& name) {
  return name == "result.stl" || name == "report.json" || name == "contours.json" ||
         name == "contours.svg" || name == "contours.cli";
}

// Constant-time comparison: the time taken does not reveal how many bytes matched.
bool same_secret(std::string_view a, std::string_view b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  const std::size_t n = std::max(a.size(), b.size());
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char x = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char y = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= static_cast<unsigned char>(x ^ y);
  }
  return diff == 0;
}

// A client's X-Request-Id is kept when it is short and plain; otherwise we make one.
std::string request_id(const std::string& given) {
  const bool plain =
      !given.empty() && given.size() <= 64 && std::all_of(given.begin(), given.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.';
      });
  if (plain) return given;
  thread_local std::mt19937_64 engine{std::random_device{}()};
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(engine()));
  return text;
}

std::string request_id(const Request& req) {
  return request_id(req.get_header_value("X-Request-Id"));
}

std::string lowercase(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// Paths and header values are echoed in details: keep them short.
std::string shortened(std::string_view s) {
  constexpr std::size_t kMax = 120;
  return s.size() <= kMax ? std::string(s) : std::string(s.substr(0, kMax)) + "...";
}

// "model/STL ; charset=x" -> "model/stl".
std::string media_type(const std::string& content_type) {
  std::string_view v = content_type;
  v = v.substr(0, v.find(';'));
  while (!v.empty() && (v.back() == ' ' || v.back() == '\t')) v.remove_suffix(1);
  while (!v.empty() && (v.front() == ' ' || v.front() == '\t')) v.remove_prefix(1);
  return lowercase(v);
}

// Parameters come from the query string only. httplib also decodes an
// application/x-www-form-urlencoded *body* into req.params, which for us is STL bytes.
// Its query parser is not used either: it keeps only the last '='-part of a value
// ("levels=x=2" is levels 2), drops pairs without a name and merges identical duplicates.
api::RawParams raw_params(const Request& req) {
  const std::size_t q = req.target.find('?');
  if (q == std::string::npos) return {};
  return api::parse_query(std::string_view(req.target).substr(q + 1));
}

// One write per line: worker threads log concurrently, and a line built with several <<
// would interleave with theirs.
void log_line(const std::string& line) {
  std::cerr << (line + "\n") << std::flush;
}

void send_problem(Response& res, const api::Problem& problem) {
  res.status = problem.status;
  res.set_content(api::problem_body(problem), api::kProblemContentType);
}

const char* reason_phrase(int status) {
  switch (status) {
    case 200:
      return "OK";
    case 400:
      return "Bad Request";
    case 401:
      return "Unauthorized";
    case 404:
      return "Not Found";
    case 405:
      return "Method Not Allowed";
    case 408:
      return "Request Timeout";
    case 411:
      return "Length Required";
    case 413:
      return "Payload Too Large";
    case 414:
      return "URI Too Long";
    case 415:
      return "Unsupported Media Type";
    case 422:
      return "Unprocessable Content";
    case 431:
      return "Request Header Fields Too Large";
    case 500:
      return "Internal Server Error";
    case 503:
      return "Service Unavailable";
    default:
      return status >= 500 ? "Server Error" : "Client Error";
  }
}

//! A complete HTTP/1.1 answer the front end writes itself (one request per connection).
std::string raw_answer(int status, const std::string& content_type, const std::string& body,
                       const httplib::Headers& headers, bool head_only) {
  std::string out = "HTTP/1.1 " + std::to_string(status) + " " + reason_phrase(status) + "\r\n";
  out += "Content-Type: " + content_type + "\r\n";
  out += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  out += "Connection: close\r\n";
  for (const auto& [name, value] : headers) out += name + ": " + value + "\r\n";
  out += "\r\n";
  if (!head_only) out += body;
  return out;
}

//! A request as httplib would have parsed it from the head, for the checks in decide().
Request to_request(const RequestHead& head) {
  Request req;
  req.method = head.method;
  req.target = head.target;
  req.version = head.version;
  const std::size_t q = head.target.find('?');
  req.path = httplib::detail::decode_url(head.target.substr(0, q), false);
  if (q != std::string::npos)
    httplib::detail::parse_query_text(head.target.substr(q + 1), req.params);
  for (const auto& [name, value] : head.fields) req.headers.emplace(name, value);
  req.remote_addr = head.remote_ip;
  req.remote_port = head.remote_port;
  return req;
}

}  // namespace

struct Daemon::Impl : FrontEndDelegate {
  explicit Impl(DaemonConfig c);

  void install();
  std::optional<api::Problem> precheck(const Request& req) const;
  api::Problem busy_problem(bool stopping) const;
  //! The body for an answer httplib made itself (status set, body empty).
  api::Problem library_problem(int status, const Request& req) const;
  //! Headers a problem's status calls for (Retry-After, Allow, WWW-Authenticate).
  httplib::Headers problem_headers(const api::Problem& problem) const;
  void respond(Response& res, const api::Problem& problem) const;
  void compute(const Request& req, std::string_view body, Response& res, const Route& route);
  void submit_job(const Request& req, std::string_view body, Response& res);
  void job_item(const Request& req, Response& res);
  void page(const Request& req, Response& res, std::string_view name) const;
  //! /readyz: 200 with the slots, or the busy / shutting-down problem.
  std::pair<std::string, std::optional<api::Problem>> readiness() const;
  bool authorized(const Request& req) const;
  //! Metrics and the access log line of one answer.
  void record(const std::string& method, const std::string& path, int status, std::size_t bytes,
              double seconds, const std::string& id, const std::string& remote);

  // FrontEndDelegate
  Verdict decide(const RequestHead& head) override;
  void serve(ReadRequest& request) override;
  std::string refusal(const RequestHead* head, int status, std::string_view slug,
                      std::string detail) override;
  //! A problem answer written by the front end, recorded like any other.
  std::string front_answer(const Request* req, const api::Problem& problem);

  //! 503 busy for want of memory (a request fits alone, not next to the running ones).
  api::Problem memory_busy_problem(std::uint64_t predicted) const;

  DaemonConfig config;
  api::RequestLimits limits;
  ComputeSlots slots;
  MemoryBudget memory;
  HttpServer http;
  std::unique_ptr<FrontEnd> front;
  RequestWatch watch;
  std::atomic<bool> running{false};   // run() is active
  std::atomic<bool> stopping{false};  // stop() was called
  Metrics metrics;
  std::unique_ptr<JobStore> jobs;  // null when jobs are not enabled
};

namespace {

DaemonConfig checked(DaemonConfig c) {
  if (c.compute_slots == 0) c.compute_slots = std::max(1u, std::thread::hardware_concurrency());
  if (c.memory_budget == 0) c.memory_budget = default_memory_budget();
  if (c.memory_budget < 2 * kDaemonReserve)
    throw std::invalid_argument("the memory budget must be at least " +
                                std::to_string(2 * kDaemonReserve >> 20) + " MiB");
  if (c.compute_nice < 0 || c.compute_nice > 19)
    throw std::invalid_argument("compute_nice must be in [0, 19]");
  if (c.request_deadline.count() < 0)
    throw std::invalid_argument("the request deadline must be >= 0");
  if (c.http_threads == 0) c.http_threads = c.compute_slots + 4;
  if (c.compute_slots > 4096) throw std::invalid_argument("compute_slots must be <= 4096");
  if (c.http_threads > 4096) throw std::invalid_argument("http_threads must be <= 4096");
  if (c.max_body_bytes == 0) throw std::invalid_argument("max_body_bytes must be > 0");
  if (c.max_faces < 1 || c.max_faces >= (std::uint64_t{1} << 31))
    throw std::invalid_argument("max_faces must be in [1, 2^31)");
  if (c.read_timeout.count() < 1 || c.write_timeout.count() < 1)
    throw std::invalid_argument("timeouts must be at least 1 s");
  if (c.max_slice_points < 1 || c.max_slice_points > (std::uint64_t{1} << 40))
    throw std::invalid_argument("max_slice_points must be in [1, 2^40]");
  if (c.retry_after_seconds < 0) throw std::invalid_argument("retry_after_seconds must be >= 0");
  if (c.max_connections < 1 || c.max_connections > (std::size_t{1} << 20))
    throw std::invalid_argument("max_connections must be in [1, 2^20]");
  if (!c.jobs.data_dir.empty() && (c.jobs.max_queued < 1 || c.jobs.max_queued > 100000))
    throw std::invalid_argument("the job queue length must be in [1, 100000]");
  if (!c.jobs.data_dir.empty() && c.jobs.retention.count() < 1)
    throw std::invalid_argument("job retention must be at least 1 s");
  for (const std::string& key : c.api_keys)
    if (key.size() < 16) throw std::invalid_argument("API keys must be at least 16 characters");
  return c;
}

}  // namespace

Daemon::Impl::Impl(DaemonConfig c)
    : config(checked(std::move(c))),
      limits{.max_faces = config.max_faces,
             .default_max_faces = 0,
             .max_slice_points = config.max_slice_points,
             .accept_threads = false},
      slots(config.compute_slots),
      memory(config.memory_budget, kDaemonReserve) {
  if (!config.jobs.data_dir.empty()) {
    JobsConfig jc = config.jobs;
    if (jc.runners == 0) jc.runners = config.compute_slots;
    jc.memory = &memory;
    jc.deadline = config.request_deadline;
    jc.runner_nice = config.compute_nice;
    jobs = std::make_unique<JobStore>(jc, slots, [this](const JobView& job, double seconds) {
      const auto& r = job.report;
      const std::uint64_t in = r.contains("input") ? r["input"].value("faces", 0ull) : 0;
      const std::uint64_t out = r.contains("output") ? r["output"].value("faces", 0ull) : 0;
      metrics.refinement(job.scheme, to_string(job.state), seconds, in, out);
    });
  }
  FrontEnd::Options fo;
  fo.workers = config.http_threads;
  fo.max_queued = 4 * config.http_threads;
  fo.max_connections = config.max_connections;
  fo.head_timeout = config.read_timeout;
  fo.idle_timeout = config.read_timeout;
  fo.write_timeout = config.write_timeout;
  fo.worker_nice = config.compute_nice;
  front = std::make_unique<FrontEnd>(fo, *this);
  install();
}

std::optional<api::Problem> Daemon::Impl::precheck(const Request& req) const {
  using api::make_problem;
  const Route* route = find_route(req.path);
  if (!route) return make_problem(404, "not-found", "no route " + shortened(req.path));
  if (!method_allowed(*route, req.method)) {
    api::Problem p = make_problem(
        405, "method-not-allowed",
        req.method + " is not allowed on " + route->path + " (allowed: " + route->allow + ")");
    p.extensions["allow"] = route->allow;
    return p;
  }
  if (!authorized(req)) {
    api::Problem p = make_problem(401, "unauthorized",
                                  "this server needs an API key: Authorization: Bearer <key>");
    p.extensions["www_authenticate"] = "Bearer";
    return p;
  }
  if ((route->kind == RouteKind::Submit || route->kind == RouteKind::JobItem) && !jobs)
    return make_problem(404, "jobs-disabled",
                        "jobs are not enabled on this server (start it with --data-dir DIR)");
  if (!has_body(*route)) {
    // The library reads a DELETE body (a chunked one without any limit) and leaves a GET
    // body unread; neither route takes one.
    // get_header_value returns a copy: keep it alive while the view is used.
    const std::string length_header = req.get_header_value("Content-Length");
    std::string_view length = length_header;
    while (length.size() > 1 && length.front() == '0') length.remove_prefix(1);
    if (req.has_header("Transfer-Encoding") || (!length.empty() && length != "0")) {
      api::Problem p = make_problem(400, "bad-request",
                                    req.method + " " + route->path + " takes no request body");
      p.field = req.has_header("Transfer-Encoding") ? "Transfer-Encoding" : "Content-Length";
      return p;
    }
    return std::nullopt;
  }

  // Body framing. Only Content-Length bodies are accepted: 0.11.4 applies its payload limit
  // to nothing else.
  if (req.has_header("Transfer-Encoding"))
    return make_problem(411, "length-required",
                        "Transfer-Encoding (" +
                            shortened(req.get_header_value("Transfer-Encoding")) +
                            ") is not accepted; send the body with a Content-Length");
  if (!req.has_header("Content-Length"))
    return make_problem(411, "length-required", "a POST body needs a Content-Length header");
  const std::string length_text = req.get_header_value("Content-Length");
  std::uint64_t length = 0;
  const auto [end, ec] =
      std::from_chars(length_text.data(), length_text.data() + length_text.size(), length);
  if (req.get_header_value_count("Content-Length") != 1 || length_text.empty() ||
      ec != std::errc() || end != length_text.data() + length_text.size())
    return make_problem(
        400, "bad-request",
        "Content-Length must be one decimal number, not '" + shortened(length_text) + "'");
  if (req.has_header("Content-Encoding")) {
    api::Problem p =
        make_problem(415, "unsupported-media-type",
                     "Content-Encoding '" + shortened(req.get_header_value("Content-Encoding")) +
                         "' is not accepted; send the STL bytes as they are");
    p.field = "Content-Encoding";
    return p;
  }
  const std::string type = media_type(req.get_header_value("Content-Type"));
  // curl --data-binary labels the body application/x-www-form-urlencoded unless told
  // otherwise. The bytes arrive unchanged and are never form-decoded, so the plain
  // `curl --data-binary @part.stl URL` a user types is accepted as raw STL.
  if (type != "model/stl" && type != "application/octet-stream" &&
      type != "application/x-www-form-urlencoded") {
    api::Problem p =
        make_problem(415, "unsupported-media-type",
                     "Content-Type must be model/stl or application/octet-stream, not '" +
                         shortened(req.get_header_value("Content-Type")) + "'");
    p.field = "Content-Type";
    return p;
  }
  if (length > config.max_body_bytes) {
    api::Problem p = make_problem(413, "payload-too-large",
                                  "the body is " + std::to_string(length) +
                                      " bytes; this server accepts at most " +
                                      std::to_string(config.max_body_bytes));
    p.extensions["max_body_bytes"] = config.max_body_bytes;
    return p;
  }

  // Parameters, before the body is uploaded.
  try {
    if (route->kind == RouteKind::Submit || route->path == std::string_view("/v1/refine"))
      api::parse_refine_params(raw_params(req), limits);
    else if (route->path == std::string_view("/v1/slice"))
      api::parse_slice_params(raw_params(req), limits);
    else
      api::parse_info_params(raw_params(req));
  } catch (const Error& e) {
    return api::problem_from_error(e);
  }

  // A full house is told at once. The handler takes the slot for real after the upload.
  if (route->kind == RouteKind::Submit) {
    if (stopping || jobs->queued() >= jobs->config().max_queued) {
      if (stopping) return busy_problem(true);
      api::Problem p = make_problem(503, "queue-full",
                                    "all " + std::to_string(jobs->config().max_queued) +
                                        " job queue places are taken; retry later");
      p.extensions["max_queued"] = jobs->config().max_queued;
      return p;
    }
    return std::nullopt;
  }
  if (stopping || slots.available() == 0) return busy_problem(stopping);
  return std::nullopt;
}

api::Problem Daemon::Impl::busy_problem(bool is_stopping) const {
  if (is_stopping) return api::make_problem(503, "shutting-down", "the server is shutting down");
  api::Problem p = api::make_problem(
      503, "busy",
      "all " + std::to_string(slots.capacity()) + " compute slots are taken; retry later");
  p.extensions["compute_slots"] = slots.capacity();
  return p;
}

api::Problem Daemon::Impl::memory_busy_problem(std::uint64_t predicted) const {
  api::Problem p = api::make_problem(
      503, "busy",
      "the memory budget is taken by the requests running now (this one needs about " +
          std::to_string((predicted + (1 << 20) - 1) >> 20) + " MiB); retry later");
  p.extensions["reason"] = "memory";
  p.extensions["memory_budget_bytes"] = memory.capacity();
  return p;
}

httplib::Headers Daemon::Impl::problem_headers(const api::Problem& problem) const {
  httplib::Headers h;
  if (problem.status == 503) h.emplace("Retry-After", std::to_string(config.retry_after_seconds));
  if (problem.status == 401) h.emplace("WWW-Authenticate", "Bearer");
  if (problem.status == 405 && problem.extensions.contains("allow"))
    h.emplace("Allow", problem.extensions["allow"].get<std::string>());
  return h;
}

void Daemon::Impl::respond(Response& res, const api::Problem& problem) const {
  for (const auto& [name, value] : problem_headers(problem)) res.set_header(name, value);
  send_problem(res, problem);
}

void Daemon::Impl::record(const std::string& method, const std::string& path, int status,
                          std::size_t bytes, double seconds, const std::string& id,
                          const std::string& remote) {
  const std::string route = route_label(path);
  metrics.request(route, method, status, seconds);
  if (!config.access_log) return;
  nlohmann::ordered_json line;
  line["time"] = iso8601_now();
  line["request_id"] = id;
  line["remote"] = remote;
  line["method"] = method;
  line["path"] = shortened(path);
  line["route"] = route;
  line["status"] = status;
  line["bytes"] = bytes;
  line["ms"] = std::round(seconds * 1e4) / 10;
  log_line(line.dump(-1, ' ', true, nlohmann::json::error_handler_t::replace));
}

std::string Daemon::Impl::front_answer(const Request* req, const api::Problem& problem) {
  const std::string id = req ? request_id(*req) : request_id(std::string());
  httplib::Headers headers = problem_headers(problem);
  headers.emplace("X-Request-Id", id);
  const std::string body = api::problem_body(problem);
  const bool head_only = req && req->method == "HEAD";
  record(req ? req->method : "-", req ? req->path : "-", problem.status,
         head_only ? 0 : body.size(), 0.0, id, req ? req->remote_addr : "");
  return raw_answer(problem.status, api::kProblemContentType, body, headers, head_only);
}

std::string Daemon::Impl::refusal(const RequestHead* head, int status, std::string_view slug,
                                  std::string detail) {
  api::Problem problem = api::make_problem(status, std::string(slug), std::move(detail));
  if (!head) return front_answer(nullptr, problem);
  const Request req = to_request(*head);
  return front_answer(&req, problem);
}

Verdict Daemon::Impl::decide(const RequestHead& head) {
  const Request req = to_request(head);
  Verdict verdict;
  // Probes are answered here, on the event loop: they never wait behind a worker.
  const bool probe = (req.path == "/healthz" || req.path == "/readyz") &&
                     (req.method == "GET" || req.method == "HEAD");
  std::optional<api::Problem> problem = precheck(req);
  if (probe && !problem) {
    std::string body = "{\"status\":\"ok\"}\n";
    if (req.path == "/readyz") {
      auto [ready, busy] = readiness();
      if (busy) {
        verdict.kind = Verdict::Kind::Answer;
        verdict.response = front_answer(&req, *busy);
        return verdict;
      }
      body = std::move(ready);
    }
    const std::string id = request_id(req);
    const bool head_only = req.method == "HEAD";
    record(req.method, req.path, 200, head_only ? 0 : body.size(), 0.0, id, req.remote_addr);
    verdict.kind = Verdict::Kind::Answer;
    verdict.response = raw_answer(200, kJsonContentType, body, {{"X-Request-Id", id}}, head_only);
    return verdict;
  }
  if (problem) {
    verdict.kind = Verdict::Kind::Answer;
    verdict.response = front_answer(&req, *problem);
    return verdict;
  }
  const Route* route = find_route(req.path);
  if (route && has_body(*route)) {
    verdict.kind = Verdict::Kind::ReadBody;
    // precheck validated it: one decimal number, under the cap
    const std::string length = req.get_header_value("Content-Length");
    std::from_chars(length.data(), length.data() + length.size(), verdict.body_bytes);
    if (route->kind == RouteKind::Compute || route->kind == RouteKind::Submit) {
      // The body is memory from now on (a job's until it is on disk): reserved before it is
      // read.
      if (verdict.body_bytes > memory.capacity()) {
        api::Problem p =
            api::make_problem(413, "payload-too-large",
                              "the body is " + std::to_string(verdict.body_bytes) +
                                  " bytes; this server's memory budget gives one request at most " +
                                  std::to_string(memory.capacity()));
        p.extensions["memory_budget_bytes"] = memory.capacity();
        verdict.kind = Verdict::Kind::Answer;
        verdict.response = front_answer(&req, p);
        return verdict;
      }
      std::optional<MemoryBudget::Reservation> held = memory.try_reserve(verdict.body_bytes);
      if (!held) {
        verdict.kind = Verdict::Kind::Answer;
        verdict.response = front_answer(&req, memory_busy_problem(verdict.body_bytes));
        return verdict;
      }
      verdict.hold = std::make_shared<MemoryBudget::Reservation>(std::move(*held));
    }
  }
  return verdict;
}

void Daemon::Impl::serve(ReadRequest& request) {
  ConnectionStream stream(request, std::chrono::milliseconds(config.write_timeout));
  http.serve(stream);
}

void Daemon::Impl::compute(const Request& req, std::string_view raw_body, Response& res,
                           const Route& route) {
  if (config.test_hook) config.test_hook(route.path);
  if (config.test_faults) {
    const std::string fault = req.get_header_value("X-Stlrefine-Test-Fault");
    if (fault == "throw") throw std::runtime_error("test fault secret-4711 in " + req.path);
    // What a failed allocation throws. Not a real huge allocation: under AddressSanitizer
    // (the asan preset) operator new reports and aborts instead of throwing.
    if (fault == "oom") throw std::bad_alloc();
  }
  std::shared_ptr<RequestWatch::Ticket> ticket;
  try {
    // Parsed again (cheap): the pre-routing check only validated.
    const auto body =
        std::span(reinterpret_cast<const std::uint8_t*>(raw_body.data()), raw_body.size());
    const std::string_view path = route.path;
    std::optional<api::RefineRequest> refine_request;
    std::optional<api::SliceRequest> slice_request;
    std::optional<api::InfoRequest> info_request;
    if (path == "/v1/refine")
      refine_request = api::parse_refine_params(raw_params(req), limits);
    else if (path == "/v1/slice")
      slice_request = api::parse_slice_params(raw_params(req), limits);
    else
      info_request = api::parse_info_params(raw_params(req));

    std::optional<ComputeSlots::Lease> lease = slots.try_acquire();
    if (!lease || stopping) return respond(res, busy_problem(stopping));

    // Memory, before any work: the prediction must fit what one request may have (422) and
    // next to the running requests (503). decide() reserved the body; grow that.
    const ReadRequest* connection = FrontEnd::current();
    std::shared_ptr<MemoryBudget::Reservation> reservation =
        connection ? std::static_pointer_cast<MemoryBudget::Reservation>(connection->hold)
                   : nullptr;
    if (!reservation) {
      std::optional<MemoryBudget::Reservation> r = memory.try_reserve(0);
      reservation = std::make_shared<MemoryBudget::Reservation>(std::move(*r));
    }
    const api::StlShape shape = api::stl_shape(body);
    api::MemoryEstimate predicted;
    if (refine_request) {
      // The face budget first: it is the request's own limit, with its own 422.
      api::refuse_over_face_budget(shape.faces, refine_request->refine);
      predicted = api::estimate_refine_memory(body, shape, *refine_request);
    } else if (slice_request) {
      predicted = api::estimate_slice_memory(body, shape, *slice_request);
    } else {
      predicted = api::estimate_info_memory(shape);
    }
    if (predicted.peak_bytes > memory.capacity())
      return respond(res, api::memory_budget_problem(predicted, memory.capacity()));
    if (!reservation->grow_to(predicted.peak_bytes))
      return respond(res, memory_busy_problem(predicted.peak_bytes));
    // Once computed, the reservation shrinks to the body and the answer, which stay in
    // memory until the answer is sent and the connection closed.
    auto keep_answer = [&](std::uint64_t answer_bytes) {
      reservation->shrink_to(raw_body.size() + answer_bytes);
    };

    // Cancelled when the client hangs up, when the deadline passes (or on a second SIGTERM).
    ticket = watch.watch(connection ? connection->fd : -1, config.request_deadline);
    const std::atomic<bool>* cancel = &ticket->cancel;

    // Large answers are handed over by a provider, not copied into res.body: a refined STL
    // can be a GiB.
    auto provide = [&res](std::string bytes, const char* type) {
      auto data = std::make_shared<std::string>(std::move(bytes));
      res.set_content_provider(
          data->size(), type,
          [data](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
            return sink.write(data->data() + offset, length);
          });
    };
    if (refine_request) {
      const auto started = std::chrono::steady_clock::now();
      api::RefineOutcome out = api::run_refine(body, *refine_request, {}, cancel);
      metrics.refinement(
          refine_request->refine.scheme, "done",
          std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(),
          out.report["input"].value("faces", 0ull), out.report["output"].value("faces", 0ull));
      // The report header is compact ASCII JSON (no CR/LF can reach a header).
      const std::string report = out.report.dump(-1, ' ', true);
      if (out.contours) {
        // Refine + slice: one zip with the refined STL, the contours and the report.
        const slicer::SliceFormat format = refine_request->slice->format;
        std::string zip = api::make_zip({{"refined.stl", out.stl, false},
                                         {std::string("slices") + slicer::file_extension(format),
                                          *out.contours, format != slicer::SliceFormat::CliBinary},
                                         {"report.json", report, true}});
        lease.reset();
        keep_answer(zip.size());
        res.set_header(kReportHeader, report);
        res.set_header("Content-Disposition", "attachment; filename=\"refined.zip\"");
        provide(std::move(zip), kZipContentType);
      } else {
        lease.reset();
        keep_answer(out.stl.size());
        res.set_header(kReportHeader, report);
        provide(std::move(out.stl), kStlContentType);
      }
    } else if (slice_request) {
      api::SliceOutcome out = api::run_slice(body, *slice_request, {}, cancel);
      lease.reset();
      keep_answer(out.contours.size());
      res.set_header(kReportHeader, out.report.dump(-1, ' ', true));
      provide(std::move(out.contours), slicer::media_type(slice_request->slice.format));
    } else {
      const nlohmann::ordered_json report = api::run_info(body, *info_request);
      lease.reset();
      keep_answer(0);
      res.set_content(report.dump(2, ' ', true) + "\n", kJsonContentType);
    }
    res.status = 200;
  } catch (const Error& e) {
    res.headers.erase(kReportHeader);
    res.headers.erase("Content-Disposition");
    if (e.code() == ErrorCode::Cancelled && ticket &&
        ticket->reason() == RequestWatch::Reason::Deadline)
      return respond(res, deadline_problem(config.request_deadline));
    respond(res, api::problem_from_error(e));
  }
}

api::Problem Daemon::Impl::library_problem(int status, const Request& req) const {
  switch (status) {
    case 404:
      return api::make_problem(404, "not-found", "no route " + shortened(req.path));
    case 413:
      return api::make_problem(
          413, "payload-too-large",
          "the body is larger than " + std::to_string(config.max_body_bytes) + " bytes");
    case 414:
      return api::make_problem(414, "uri-too-long", "the request line is too long");
    case 500:
      return api::make_problem(500, "internal", "an internal error occurred");
    default:
      return api::make_problem(status, "bad-request", "the request could not be parsed");
  }
}

bool Daemon::Impl::authorized(const Request& req) const {
  if (config.api_keys.empty()) return true;
  const Route* route = find_route(req.path);
  // The page is public: the API calls it makes carry the key the user types in.
  if (route &&
      (route->kind == RouteKind::Page || std::string_view(route->path) == "/healthz" ||
       std::string_view(route->path) == "/readyz" || std::string_view(route->path) == "/metrics"))
    return true;
  const std::string header = req.get_header_value("Authorization");
  constexpr std::string_view kBearer = "Bearer ";
  if (header.size() <= kBearer.size() || header.compare(0, kBearer.size(), kBearer) != 0)
    return false;
  const std::string_view given = std::string_view(header).substr(kBearer.size());
  bool ok = false;
  for (const std::string& key : config.api_keys) ok |= same_secret(given, key);  // no early exit
  return ok;
}

void Daemon::Impl::submit_job(const Request& req, std::string_view body, Response& res) {
  if (config.test_hook) config.test_hook("/v1/jobs");
  try {
    api::RefineRequest request = api::parse_refine_params(raw_params(req), limits);
    // A job that could never get its memory is refused now, not when its turn comes.
    const auto bytes = std::span(reinterpret_cast<const std::uint8_t*>(body.data()), body.size());
    const api::MemoryEstimate predicted = api::estimate_refine_memory(
        bytes, api::stl_shape(bytes), request, api::ResultSink::JobFiles);
    if (predicted.peak_bytes > memory.capacity())
      return respond(res, api::memory_budget_problem(predicted, memory.capacity()));
    const std::size_t q = req.target.find('?');
    std::string query = q == std::string::npos ? "" : req.target.substr(q + 1);
    std::optional<JobView> job =
        stopping ? std::nullopt : jobs->submit(std::move(request), std::move(query), body);
    if (!job) {
      api::Problem p =
          stopping ? busy_problem(true)
                   : api::make_problem(503, "queue-full", "the job queue is full; retry later");
      return respond(res, p);
    }
    res.status = 202;
    res.set_header("Location", "/v1/jobs/" + job->id);
    res.set_content(job_json(*job).dump(2) + "\n", kJsonContentType);
  } catch (const Error& e) {
    respond(res, api::problem_from_error(e));
  }
}

void Daemon::Impl::job_item(const Request& req, Response& res) {
  // /v1/jobs/{id} or /v1/jobs/{id}/{file}
  const std::string rest = req.path.substr(std::string_view("/v1/jobs/").size());
  const std::size_t slash = rest.find('/');
  const std::string id = rest.substr(0, slash);
  const std::string file = slash == std::string::npos ? "" : rest.substr(slash + 1);
  if (slash != std::string::npos && !job_file_name(file))
    return respond(res, api::make_problem(404, "not-found", "no route " + shortened(req.path)));
  if (!file.empty() && req.method == "DELETE") {
    api::Problem p = api::make_problem(
        405, "method-not-allowed", "DELETE is not allowed on a job's files (allowed: GET, HEAD)");
    p.extensions["allow"] = "GET, HEAD";
    return respond(res, p);
  }
  JobView job;
  const JobStore::Lookup found =
      req.method == "DELETE" ? jobs->cancel(id, &job) : jobs->find(id, &job);
  if (found == JobStore::Lookup::Unknown)
    return respond(res, api::make_problem(404, "unknown-job", "no job " + shortened(id)));
  if (found == JobStore::Lookup::Expired && (req.method != "DELETE" && !file.empty())) {
    return respond(res, api::make_problem(410, "expired",
                                          "the results of job " + id +
                                              " were removed after the retention period"));
  }
  if (file.empty()) {
    if (found == JobStore::Lookup::Expired && req.method != "DELETE") res.status = 410;
    res.set_content(job_json(job).dump(2) + "\n", kJsonContentType);
    return;
  }
  if (job.state != JobState::Done) {
    api::Problem p = api::make_problem(409, "not-done",
                                       "job " + id + " is " + to_string(job.state) + ", not done");
    p.extensions["state"] = to_string(job.state);
    return respond(res, p);
  }
  if (std::find(job.results.begin(), job.results.end(), file) == job.results.end())
    return respond(res, api::make_problem(404, "no-such-result", "job " + id + " has no " + file));
  // Stream the file: results can be large. It was written by rename, so it is complete.
  auto in = std::make_shared<std::ifstream>(jobs->result_path(id, file), std::ios::binary);
  std::error_code ec;
  const auto size = std::filesystem::file_size(jobs->result_path(id, file), ec);
  if (!*in || ec)
    return respond(res,
                   api::make_problem(410, "expired", "the results of job " + id + " are gone"));
  const char* type = file == "result.stl"      ? kStlContentType
                     : file == "report.json"   ? kJsonContentType
                     : file == "contours.json" ? slicer::media_type(slicer::SliceFormat::Json)
                     : file == "contours.svg"  ? slicer::media_type(slicer::SliceFormat::Svg)
                                               : "application/octet-stream";
  res.set_header("Content-Disposition", "attachment; filename=\"" + file + "\"");
  res.set_content_provider(static_cast<std::size_t>(size), type,
                           [in](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
                             std::vector<char> buffer(std::min<std::size_t>(length, 1 << 20));
                             in->seekg(static_cast<std::streamoff>(offset));
                             in->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
                             const std::streamsize got = in->gcount();
                             return got > 0 &&
                                    sink.write(buffer.data(), static_cast<std::size_t>(got));
                           });
}

// The embedded page (web/assets.h). Cache-Control no-cache with a strong ETag: a browser
// revalidates and gets 304, and never keeps a page from an older daemon.
void Daemon::Impl::page(const Request& req, Response& res, std::string_view name) const {
  if (web::assets().empty())
    return respond(res,
                   api::make_problem(404, "page-not-built", std::string(web::missing_reason())));
  const web::Asset* asset = web::find_asset(name);
  if (!asset)
    return respond(res, api::make_problem(404, "not-found", "no route " + shortened(req.path)));
  res.set_header("ETag", std::string(asset->etag));
  res.set_header("Cache-Control", "no-cache");
  res.set_header("X-Content-Type-Options", "nosniff");
  if (name == "index.html") {
    res.set_header("Content-Security-Policy",
                   "default-src 'self'; img-src 'self' data: blob:; object-src 'none'; "
                   "base-uri 'none'; form-action 'none'; frame-ancestors 'none'");
    res.set_header("Referrer-Policy", "no-referrer");
  }
  const std::string match = req.get_header_value("If-None-Match");
  if (!match.empty() && (match == "*" || match.find(asset->etag) != std::string::npos)) {
    res.status = 304;
    // The library writes "Content-Length: 0" on an empty answer; a 304 may only carry the
    // length the 200 would have had (RFC 9110 8.6).
    res.set_header("Content-Length", std::to_string(asset->bytes.size()));
    return;
  }
  res.set_content_provider(
      asset->bytes.size(), std::string(asset->content_type),
      [asset](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
        return sink.write(asset->bytes.data() + offset, length);
      });
}

std::pair<std::string, std::optional<api::Problem>> Daemon::Impl::readiness() const {
  if (stopping || slots.available() == 0) return {std::string(), busy_problem(stopping)};
  nlohmann::ordered_json j;
  j["status"] = "ready";
  j["compute_slots"] = slots.capacity();
  j["available"] = slots.available();
  return {j.dump() + "\n", std::nullopt};
}

void Daemon::Impl::install() {
  http.new_task_queue = [] { return new InlineTaskQueue; };
  http.on_accept = [this](socket_t sock) { front->adopt(sock); };
  http.set_keep_alive_max_count(1);
  // The library's default options add SO_REUSEPORT, with which a second daemon binds the
  // same port and silently takes half the connections. SO_REUSEADDR alone still allows a
  // quick restart.
  http.set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  http.set_read_timeout(config.read_timeout.count(), 0);
  http.set_write_timeout(config.write_timeout.count(), 0);
  http.set_payload_max_length(config.max_body_bytes);

  // decide() ran the same checks on the event loop; they run again here because the state
  // may have changed while the body arrived (every slot taken, shutting down).
  http.set_pre_routing_handler([this](const Request& req, Response& res) {
    mark_request_start();
    if (std::optional<api::Problem> problem = precheck(req)) {
      respond(res, *problem);
      return HandlerResponse::Handled;
    }
    return HandlerResponse::Unhandled;
  });

  // The body was read by the front end (exactly Content-Length bytes): take it from there
  // rather than through the library's reader, which would copy it (and form-decode an
  // application/x-www-form-urlencoded body, curl's default label).
  auto body_of = []() -> std::string_view {
    const ReadRequest* request = FrontEnd::current();
    return request ? std::string_view(request->body) : std::string_view();
  };
  for (const Route& route : kRoutes) {
    if (route.kind == RouteKind::Compute) {
      http.Post(route.path, [this, &route, body_of](const Request& req, Response& res,
                                                    const httplib::ContentReader&) {
        compute(req, body_of(), res, route);
      });
    }
  }
  http.Post("/v1/jobs",
            [this, body_of](const Request& req, Response& res, const httplib::ContentReader&) {
              submit_job(req, body_of(), res);
            });
  http.Get(R"(/v1/jobs/[^/]+(/[^/]+)?)",
           [this](const Request& req, Response& res) { job_item(req, res); });
  http.Delete(R"(/v1/jobs/[^/]+(/[^/]+)?)",
              [this](const Request& req, Response& res) { job_item(req, res); });
  http.Get("/v1/openapi.json", [](const Request&, Response& res) {
    res.set_content(openapi_document(), kJsonContentType);
  });
  http.Get("/metrics", [this](const Request&, Response& res) {
    Metrics::Gauges g;
    g.compute_slots = slots.capacity();
    g.compute_slots_free = slots.available();
    g.memory_budget_bytes = memory.budget();
    g.memory_reserved_bytes = memory.reserved();
    if (jobs) {
      g.jobs_queued = jobs->queued();
      g.jobs_running = jobs->running();
    }
    res.set_content(metrics.render(g), "text/plain; version=0.0.4");
  });
  http.Get("/", [this](const Request& req, Response& res) { page(req, res, "index.html"); });
  http.Get(R"(/assets/([^/]+))",
           [this](const Request& req, Response& res) { page(req, res, req.matches[1].str()); });
  http.Get("/healthz", [this](const Request&, Response& res) {
    if (config.test_hook) config.test_hook("/healthz");
    res.set_content("{\"status\":\"ok\"}\n", kJsonContentType);
  });
  http.Get("/readyz", [this](const Request&, Response& res) {
    if (config.test_hook) config.test_hook("/readyz");
    auto [ready, busy] = readiness();
    if (busy) return respond(res, *busy);
    res.set_content(ready, kJsonContentType);
  });

  // Every answer >= 400 passes here, ours included: only fill in empty bodies (httplib's
  // own 400 / 404 / 413 / 414 / 416 / 500).
  http.set_error_handler(
      httplib::Server::HandlerWithResponse([this](const Request& req, Response& res) {
        try {
          if (!res.body.empty() || res.content_length_ != 0) return HandlerResponse::Unhandled;
          respond(res, library_problem(res.status, req));
          return HandlerResponse::Handled;
        } catch (...) {  // not inside httplib's try either
          return HandlerResponse::Unhandled;
        }
      }));

  http.set_exception_handler([](const Request& req, Response& res, std::exception_ptr ep) {
    std::string what = "unknown exception";
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    log_line("stlrefined: internal error on " + req.method + " " + shortened(req.path) + ": " +
             what);
    // Whatever the handler had set (a report header, a provider) goes: the client gets
    // only the generic problem.
    res.headers.clear();
    res.content_provider_ = nullptr;
    res.content_length_ = 0;
    send_problem(res, api::make_problem(500, "internal", "an internal error occurred"));
  });

  // Every answer carries a request id (the client's, when it sent a plain one), also in the
  // access log, so a user's report can be matched to the server's log line.
  http.set_post_routing_handler([](const Request& req, Response& res) {
    if (!res.has_header("X-Request-Id")) res.set_header("X-Request-Id", request_id(req));
  });
  http.set_logger([this](const Request& req, const Response& res) {
    const std::size_t bytes = res.body.empty() ? res.content_length_ : res.body.size();
    record(req.method, req.path, res.status, bytes, request_seconds(),
           res.get_header_value("X-Request-Id"), req.remote_addr);
  });
}

Daemon::Daemon(DaemonConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {}

Daemon::~Daemon() {
  cancel_running();
  stop();
}

int Daemon::bind(const std::string& host, int port) {
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

void Daemon::run() {
  impl_->running = true;
  impl_->front->start();
  if (!impl_->stopping) impl_->http.listen_after_bind();
  // Requests already read are answered; bodies still arriving are refused.
  impl_->front->stop(impl_->front_answer(nullptr, impl_->busy_problem(true)));
  impl_->running = false;
  if (impl_->jobs) impl_->jobs->shutdown(impl_->config.shutdown_grace);
}

void Daemon::stop() {
  impl_->stopping = true;
  // run() may be between its stopping check and the library's accept loop: wait for the
  // loop to start, or stop() would find nothing to stop.
  while (impl_->running && !impl_->http.is_running())
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  impl_->http.stop();
}

void Daemon::cancel_running() {
  impl_->watch.cancel_all();
  if (impl_->jobs) impl_->jobs->cancel_running();
}

JobStore* Daemon::jobs() {
  return impl_->jobs.get();
}

std::vector<RouteInfo> served_routes() {
  std::vector<RouteInfo> out;
  for (const Route& r : kRoutes) {
    if (r.kind == RouteKind::JobItem) {
      out.push_back({"/v1/jobs/{id}", r.allow});
      out.push_back({"/v1/jobs/{id}/{file}", "GET, HEAD"});
    } else if (r.path == std::string_view("/assets/")) {
      out.push_back({"/assets/{file}", r.allow});
    } else {
      out.push_back({r.path, r.allow});
    }
  }
  return out;
}

ComputeSlots& Daemon::compute_slots() {
  return impl_->slots;
}

MemoryBudget& Daemon::memory_budget() {
  return impl_->memory;
}

const DaemonConfig& Daemon::config() const {
  return impl_->config;
}

std::string listen_url(const std::string& host, int port) {
  const bool ipv6 = host.find(':') != std::string::npos;
  return "http://" + (ipv6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

}  // namespace stlrefine::server
