// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/daemon.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <malloc.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>

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
#include "api/plan.h"
#include "api/problem.h"
#include "api/zip.h"
#include "core/error.h"
#include "core/io/stl.h"
#include "server/admission.h"
#include "server/front_end.h"
#include "server/http.h"
#include "server/http_adapter.h"
#include "server/metrics.h"
#include "server/request_watch.h"
#include "slicer/writers.h"
#include "web/assets.h"

// The hardening, and why each piece is needed:
//
//  - No library thread ever reads from a client. cpp-httplib 0.11.4 reads a connection's
//    head and body on a pool thread with a per-recv timeout and no limit on the head's size
//    or field count: a few hundred clients trickling bytes starve every other request, and a
//    100 MB header line is buffered whole. The library only binds and accepts here
//    (http_adapter.h's Listener); every accepted socket goes to the FrontEnd (front_end.h),
//    one epoll thread that reads heads (bounded size, field count and time: 431 / 408),
//    decides on them here (Impl::decide), reads accepted bodies at a minimum rate, and only
//    then gives the complete request, body included, to a worker as an HttpRequest
//    (http.h). /healthz and /readyz are answered on the event loop itself, so they never
//    wait for a worker.
//  - decide() runs every check that needs only the request line and headers before the
//    body is read: route (404), method (405), Transfer-Encoding or no Content-Length on
//    POST (411), any Content-Encoding (415: no inflating of gzip/brotli bodies with no limit
//    on the inflated size), Content-Type (415), Content-Length over the cap (413), a body on
//    a route that takes none (400), parameters (400) and a full house (503). An
//    `Expect: 100-continue` gets the refusal instead of 100, so a refused upload is never
//    sent. After any answer the front end drops what the client still sends and then
//    closes, so a client still uploading is not reset and reads its answer. Every
//    connection carries one request.
//  - Compute requests take a ComputeSlots lease and get 503 + Retry-After at once when
//    none is free. A RequestWatch cancels them when the client hangs up or their deadline
//    (--request-deadline) passes.
//  - Memory: decide() reserves a compute request's (or job's) body in the MemoryBudget
//    as it is read (503 when it does not fit now, 413 when it never can); the handler grows
//    that to the request's predicted peak (api/memory_model.h) before any work (422 naming the
//    parameter when one request may never have that much, 503 when it does not fit next to
//    the running ones) and shrinks it to the answer once computed; the rest is given back
//    when the connection closes.
//  - An exception out of a handler is a generic 500; its what() is logged on stderr only.

namespace stlrefine::server {

namespace {

using Request = HttpRequest;
using Response = HttpAnswer;

constexpr const char* kStlContentType = "model/stl";
constexpr const char* kJsonContentType = "application/json";
constexpr const char* kReportHeader = "X-Stlrefine-Report";
constexpr const char* kZipContentType = "application/zip";

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

// The key of "Authorization: Bearer KEY", or nothing.
std::optional<std::string_view> bearer_token(std::string_view header) {
  constexpr std::string_view kBearer = "Bearer ";
  if (header.size() <= kBearer.size() || !header.starts_with(kBearer)) return std::nullopt;
  return header.substr(kBearer.size());
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
  return request_id(req.header("X-Request-Id"));
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

// One write per line: worker threads log concurrently, and a line built with several <<
// would interleave with theirs.
void log_line(const std::string& line) {
  std::cerr << (line + "\n") << std::flush;
}

void send_problem(Response& res, const api::Problem& problem) {
  res.status = problem.status;
  res.set_content(api::problem_body(problem), api::kProblemContentType);
}

}  // namespace

struct Daemon::Impl : FrontEndDelegate {
  explicit Impl(DaemonConfig c);

  std::optional<api::Problem> precheck(const Request& req) const;
  api::Problem busy_problem(bool stopping) const;
  //! Headers a problem's status calls for (Retry-After, Allow, WWW-Authenticate).
  Fields problem_headers(const api::Problem& problem) const;
  void respond(Response& res, const api::Problem& problem) const;
  //! The handlers. Large bodies go into res.large (a view kept alive by large.keep, a file,
  //! or bytes made as they are sent), small ones into res.body.
  void route(const Request& req, ReadRequest& read, Response& res, bool& ranges);
  void compute(const Request& req, ReadRequest& read, Response& res, const Route& route);
  void submit_job(const Request& req, std::string_view body, Response& res);
  void job_item(const Request& req, Response& res);
  void page(const Request& req, Response& res, std::string_view name) const;
  //! The answer the front end writes (http_adapter.h's frame_answer), with its
  //! X-Request-Id, recorded when it is written.
  Answer finish(const Request& req, Response res, bool ranges,
                std::chrono::steady_clock::time_point accepted);
  //! /readyz: 200 with the slots, or the busy / shutting-down problem.
  std::pair<std::string, std::optional<api::Problem>> readiness() const;
  bool authorized(const Request& req) const;
  //! The tenant that owns the jobs this request may see (JobStore::tenant_of its API key);
  //! empty without API keys.
  std::string tenant(const Request& req) const;
  //! Metrics and the access log line of one answer; `aborted` names why an answer was not
  //! written in full (then logged with status 499, never as the status its head carried).
  void record(const std::string& method, const std::string& path, int status, std::size_t bytes,
              double seconds, const std::string& id, const std::string& remote,
              const char* aborted = nullptr);

  // FrontEndDelegate
  Verdict decide(const RequestHead& head) override;
  Answer serve(ReadRequest& request) override;
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
  Listener listener{[this](int fd) { front->adopt(fd); }};
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
  if (c.min_transfer_rate < 1) throw std::invalid_argument("min_transfer_rate must be >= 1");
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
  fo.max_connections_per_client = config.max_connections_per_client;
  fo.head_timeout = config.read_timeout;
  fo.body_window = config.read_timeout;
  fo.answer_window = config.write_timeout;
  fo.min_rate = config.min_transfer_rate;
  fo.worker_nice = config.compute_nice;
  front = std::make_unique<FrontEnd>(fo, *this);
}

std::optional<api::Problem> Daemon::Impl::precheck(const Request& req) const {
  const Route* route = find_route(req.path);
  if (!route) return api::not_found("not-found", "no route " + shortened(req.path));
  if (!method_allowed(*route, req.method)) {
    api::Problem p = api::method_not_allowed(
        "method-not-allowed",
        req.method + " is not allowed on " + route->path + " (allowed: " + route->allow + ")");
    p.extensions["allow"] = route->allow;
    return p;
  }
  if (!authorized(req)) {
    api::Problem p = api::unauthorized("unauthorized",
                                       "this server needs an API key: Authorization: Bearer <key>");
    p.extensions["www_authenticate"] = "Bearer";
    return p;
  }
  if ((route->kind == RouteKind::Submit || route->kind == RouteKind::JobItem) && !jobs)
    return api::not_found("jobs-disabled",
                          "jobs are not enabled on this server (start it with --data-dir DIR)");
  if (!has_body(*route)) {
    // The library reads a DELETE body (a chunked one without any limit) and leaves a GET
    // body unread; neither route takes one.
    // get_header_value returns a copy: keep it alive while the view is used.
    const std::string length_header = req.header("Content-Length");
    std::string_view length = length_header;
    while (length.size() > 1 && length.front() == '0') length.remove_prefix(1);
    if (req.has_header("Transfer-Encoding") || (!length.empty() && length != "0")) {
      api::Problem p = api::bad_request("bad-request",
                                        req.method + " " + route->path + " takes no request body");
      p.field = req.has_header("Transfer-Encoding") ? "Transfer-Encoding" : "Content-Length";
      return p;
    }
    return std::nullopt;
  }

  // Body framing. Only Content-Length bodies are accepted: 0.11.4 applies its payload limit
  // to nothing else.
  if (req.has_header("Transfer-Encoding"))
    return api::length_required("length-required",
                                "Transfer-Encoding (" + shortened(req.header("Transfer-Encoding")) +
                                    ") is not accepted; send the body with a Content-Length");
  if (!req.has_header("Content-Length"))
    return api::length_required("length-required", "a POST body needs a Content-Length header");
  const std::string length_text = req.header("Content-Length");
  std::uint64_t length = 0;
  const auto [end, ec] =
      std::from_chars(length_text.data(), length_text.data() + length_text.size(), length);
  if (req.header_count("Content-Length") != 1 || length_text.empty() || ec != std::errc() ||
      end != length_text.data() + length_text.size())
    return api::bad_request("bad-request", "Content-Length must be one decimal number, not '" +
                                               shortened(length_text) + "'");
  if (req.has_header("Content-Encoding")) {
    api::Problem p = api::unsupported_media_type(
        "unsupported-media-type", "Content-Encoding '" + shortened(req.header("Content-Encoding")) +
                                      "' is not accepted; send the STL bytes as they are");
    p.field = "Content-Encoding";
    return p;
  }
  const std::string type = media_type(req.header("Content-Type"));
  // curl --data-binary labels the body application/x-www-form-urlencoded unless told
  // otherwise. The bytes arrive unchanged and are never form-decoded, so the plain
  // `curl --data-binary @part.stl URL` a user types is accepted as raw STL.
  if (type != "model/stl" && type != "application/octet-stream" &&
      type != "application/x-www-form-urlencoded") {
    api::Problem p = api::unsupported_media_type(
        "unsupported-media-type",
        "Content-Type must be model/stl or application/octet-stream, not '" +
            shortened(req.header("Content-Type")) + "'");
    p.field = "Content-Type";
    return p;
  }
  if (length > config.max_body_bytes) {
    api::Problem p =
        api::content_too_large("payload-too-large", "the body is " + std::to_string(length) +
                                                        " bytes; this server accepts at most " +
                                                        std::to_string(config.max_body_bytes));
    p.extensions["max_body_bytes"] = config.max_body_bytes;
    return p;
  }

  // Parameters, before the body is uploaded.
  try {
    if (route->kind == RouteKind::Submit || route->path == std::string_view("/v1/refine"))
      api::parse_refine_params(req.parameters(), limits);
    else if (route->path == std::string_view("/v1/slice"))
      api::parse_slice_params(req.parameters(), limits);
    else
      api::parse_info_params(req.parameters());
  } catch (const Error& e) {
    return api::problem_from_error(e);
  }

  // A full house is told at once. The handler takes the slot for real after the upload.
  if (route->kind == RouteKind::Submit) {
    if (stopping || jobs->queued() >= jobs->config().max_queued) {
      if (stopping) return busy_problem(true);
      api::Problem p = api::service_unavailable("queue-full",
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
  if (is_stopping) return api::service_unavailable("shutting-down", "the server is shutting down");
  api::Problem p = api::service_unavailable(
      "busy", "all " + std::to_string(slots.capacity()) + " compute slots are taken; retry later");
  p.extensions["compute_slots"] = slots.capacity();
  return p;
}

api::Problem Daemon::Impl::memory_busy_problem(std::uint64_t predicted) const {
  api::Problem p = api::service_unavailable(
      "busy", "the memory budget is taken by the requests running now (this one needs about " +
                  std::to_string((predicted + (1 << 20) - 1) >> 20) + " MiB); retry later");
  p.extensions["reason"] = "memory";
  p.extensions["memory_budget_bytes"] = memory.capacity();
  return p;
}

Fields Daemon::Impl::problem_headers(const api::Problem& problem) const {
  Fields h;
  // 507: space comes back as finished jobs expire.
  if (problem.status == api::http::kServiceUnavailable ||
      problem.status == api::http::kInsufficientStorage)
    h.emplace("Retry-After", std::to_string(config.retry_after_seconds));
  if (problem.status == api::http::kUnauthorized) h.emplace("WWW-Authenticate", "Bearer");
  if (problem.status == api::http::kMethodNotAllowed && problem.extensions.contains("allow"))
    h.emplace("Allow", problem.extensions["allow"].get<std::string>());
  return h;
}

void Daemon::Impl::respond(Response& res, const api::Problem& problem) const {
  for (const auto& [name, value] : problem_headers(problem)) res.set_header(name, value);
  send_problem(res, problem);
}

void Daemon::Impl::record(const std::string& method, const std::string& path, int status,
                          std::size_t bytes, double seconds, const std::string& id,
                          const std::string& remote, const char* aborted) {
  const std::string route = route_label(path);
  // 499 (as nginx logs a client that went away): the head's status was sent, the answer
  // was not.
  const int logged = aborted ? api::http::kClientClosed : status;
  metrics.request(route, method, logged, seconds);
  if (!config.access_log) return;
  nlohmann::ordered_json line;
  line["time"] = iso8601_now();
  line["request_id"] = id;
  line["remote"] = remote;
  line["method"] = method;
  line["path"] = shortened(path);
  line["route"] = route;
  line["status"] = logged;
  if (aborted) {
    line["aborted"] = aborted;
    line["sent_status"] = status;
  }
  line["bytes"] = bytes;
  line["ms"] = std::round(seconds * 1e4) / 10;
  log_line(line.dump(-1, ' ', true, nlohmann::json::error_handler_t::replace));
}

std::string Daemon::Impl::front_answer(const Request* req, const api::Problem& problem) {
  const std::string id = req ? request_id(*req) : request_id(std::string());
  Fields headers = problem_headers(problem);
  headers.emplace("X-Request-Id", id);
  const std::string body = api::problem_body(problem);
  const bool head_only = req && req->method == "HEAD";
  record(req ? req->method : "-", req ? req->path : "-", problem.status,
         head_only ? 0 : body.size(), 0.0, id, req ? req->remote_addr : "");
  return whole_answer(problem.status, api::kProblemContentType, body, headers, head_only);
}

std::string Daemon::Impl::refusal(const RequestHead* head, int status, std::string_view slug,
                                  std::string detail) {
  api::Problem problem = api::make_problem(status, std::string(slug), std::move(detail));
  if (!head) return front_answer(nullptr, problem);
  const Request req = to_http_request(*head);
  return front_answer(&req, problem);
}

Verdict Daemon::Impl::decide(const RequestHead& head) {
  const Request req = to_http_request(head);
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
    record(req.method, req.path, api::http::kOk, head_only ? 0 : body.size(), 0.0, id,
           req.remote_addr);
    verdict.kind = Verdict::Kind::Answer;
    verdict.response =
        whole_answer(api::http::kOk, kJsonContentType, body, {{"X-Request-Id", id}}, head_only);
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
    const std::string length = req.header("Content-Length");
    std::from_chars(length.data(), length.data() + length.size(), verdict.body_bytes);
    if (route->kind == RouteKind::Compute || route->kind == RouteKind::Submit) {
      // The body is memory from now on (a job's until it is on disk).
      if (verdict.body_bytes > memory.capacity()) {
        api::Problem p = api::content_too_large(
            "payload-too-large",
            "the body is " + std::to_string(verdict.body_bytes) +
                " bytes; this server's memory budget gives one request at most " +
                std::to_string(memory.capacity()));
        p.extensions["memory_budget_bytes"] = memory.capacity();
        verdict.kind = Verdict::Kind::Answer;
        verdict.response = front_answer(&req, p);
        return verdict;
      }
      // Memory is reserved as the body arrives (the front end asks before its buffer grows),
      // so sockets that declare large bodies and trickle them cannot pin the budget.
      std::optional<MemoryBudget::Reservation> held = memory.try_reserve(0);
      auto reservation = std::make_shared<MemoryBudget::Reservation>(std::move(*held));
      verdict.hold = reservation;
      verdict.reserve_body = [this, reservation, req](std::uint64_t bytes) -> std::string {
        if (reservation->grow_to(bytes)) return {};
        return front_answer(&req, memory_busy_problem(bytes));
      };
    }
  }
  return verdict;
}

Answer Daemon::Impl::serve(ReadRequest& read) {
  const Request req = to_http_request(read.head, read.body);
  Response res;
  bool ranges = false;
  try {
    route(req, read, res, ranges);
  } catch (...) {
    std::string what = "unknown exception";
    try {
      throw;
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    log_line("stlrefined: internal error on " + req.method + " " + shortened(req.path) + ": " +
             what);
    // Whatever the handler had set (a report header, a body) goes: the client gets only the
    // generic problem.
    res = Response();
    ranges = false;
    send_problem(res, api::internal_error());
  }
  return finish(req, std::move(res), ranges, read.accepted);
}

void Daemon::Impl::route(const Request& req, ReadRequest& read, Response& res, bool& ranges) {
  // decide() ran the same checks on the event loop; they run again here because the state
  // may have changed while the body arrived (every slot taken, shutting down).
  if (std::optional<api::Problem> problem = precheck(req)) return respond(res, *problem);
  const Route& r = *find_route(req.path);  // precheck found it
  switch (r.kind) {
    case RouteKind::Compute:
      return compute(req, read, res, r);
    case RouteKind::Submit:
      return submit_job(req, read.body, res);
    case RouteKind::JobItem:
      ranges = true;
      return job_item(req, res);
    case RouteKind::Page: {
      ranges = true;
      if (req.path == "/") return page(req, res, "index.html");
      const std::string name = req.path.substr(std::string_view("/assets/").size());
      if (name.find('/') != std::string::npos)
        return respond(res, api::not_found("not-found", "no route " + shortened(req.path)));
      return page(req, res, name);
    }
    case RouteKind::Plain:
      break;
  }
  if (req.path == "/v1/openapi.json") return res.set_content(openapi_document(), kJsonContentType);
  if (req.path == "/metrics") {
    Metrics::Gauges g;
    g.compute_slots = slots.capacity();
    g.compute_slots_free = slots.available();
    g.memory_budget_bytes = memory.budget();
    g.memory_reserved_bytes = memory.reserved();
    if (jobs) {
      g.jobs_queued = jobs->queued();
      g.jobs_running = jobs->running();
    }
    return res.set_content(metrics.render(g), "text/plain; version=0.0.4");
  }
  // /healthz and /readyz: normally answered by decide() on the event loop.
  if (config.test_hook) config.test_hook(r.path);
  if (req.path == "/readyz") {
    auto [ready, busy] = readiness();
    if (busy) return respond(res, *busy);
    return res.set_content(ready, kJsonContentType);
  }
  res.set_content("{\"status\":\"ok\"}\n", kJsonContentType);
}

Answer Daemon::Impl::finish(const Request& req, Response res, bool ranges,
                            std::chrono::steady_clock::time_point accepted) {
  const std::string id = request_id(req);
  res.set_header("X-Request-Id", id);
  return frame_answer(
      req, std::move(res), ranges,
      [this, method = req.method, path = req.path, id, remote = req.remote_addr, accepted](
          int status, std::uint64_t body_bytes, const AnswerEnd& end) {
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - accepted).count();
        if (end.outcome == AnswerEnd::Outcome::Complete)
          return record(method, path, status, body_bytes, seconds, id, remote);
        record(method, path, status, body_bytes, seconds, id, remote, to_string(end.outcome));
      });
}

void Daemon::Impl::compute(const Request& req, ReadRequest& read, Response& res,
                           const Route& route) {
  const std::string_view raw_body = req.body;
  if (config.test_hook) config.test_hook(route.path);
  if (config.test_faults) {
    const std::string fault = req.header("X-Stlrefine-Test-Fault");
    if (fault == "throw") throw std::runtime_error("test fault secret-4711 in " + req.path);
    // What a failed allocation throws. Not a real huge allocation: under AddressSanitizer
    // (the asan preset) operator new reports and aborts instead of throwing.
    if (fault == "oom") throw std::bad_alloc();
  }
  std::shared_ptr<RequestWatch::Ticket> ticket;
  // What a computation freed goes back to the kernel before its reservation does: small
  // blocks (the adaptive hierarchies' chunks, stencil patches) otherwise stay in the
  // threads' malloc arenas, and a daemon that ran 577 MiB requests one after another under a
  // 640 MiB budget held 1.36 GB.
  struct TrimAfter {
    ~TrimAfter() { ::malloc_trim(0); }
  } trim_after;
  try {
    // Planned (parsed again, cheap: the pre-routing check only validated): the parameters,
    // the scheme, the body's shape and the predicted memory, once.
    const auto body =
        std::span(reinterpret_cast<const std::uint8_t*>(raw_body.data()), raw_body.size());
    const std::string_view path = route.path;
    std::optional<api::RefinePlan> refine_plan;
    std::optional<api::SlicePlan> slice_plan;
    std::optional<api::InfoPlan> info_plan;
    if (path == "/v1/refine")
      refine_plan = api::plan_refine(req.parameters(), limits, body);
    else if (path == "/v1/slice")
      slice_plan = api::plan_slice(req.parameters(), limits, body);
    else
      info_plan = api::plan_info(req.parameters(), body);

    std::optional<ComputeSlots::Lease> lease = slots.try_acquire();
    if (!lease || stopping) return respond(res, busy_problem(stopping));

    // Memory, before any work: the prediction must fit what one request may have (422) and
    // next to the running requests (503). decide() reserved the body; grow that.
    std::shared_ptr<MemoryBudget::Reservation> reservation =
        std::static_pointer_cast<MemoryBudget::Reservation>(read.hold);
    if (!reservation) {
      std::optional<MemoryBudget::Reservation> r = memory.try_reserve(0);
      reservation = std::make_shared<MemoryBudget::Reservation>(std::move(*r));
    }
    const ReserveFn reserve = [&reservation](std::uint64_t bytes) {
      return reservation->grow_to(bytes);
    };
    const BusyFn busy = [this](std::uint64_t bytes) { return memory_busy_problem(bytes); };
    const std::optional<api::Problem> refused =
        refine_plan ? admit(*refine_plan, memory.capacity(), reserve, busy)
                    : admit(slice_plan ? slice_plan->memory : info_plan->memory, memory.capacity(),
                            reserve, busy);
    if (refused) return respond(res, *refused);
    // Once computed, the reservation shrinks to the body and the answer, which stay in
    // memory until the answer is sent and the connection closed.
    auto keep_answer = [&](std::uint64_t answer_bytes) {
      reservation->shrink_to(raw_body.size() + answer_bytes);
    };

    // Cancelled when the client hangs up, when the deadline passes (or on a second SIGTERM).
    ticket = watch.watch(read.fd, config.request_deadline);
    const std::atomic<bool>* cancel = &ticket->cancel;

    // Large answers are handed to the front end as they are, not copied: a refined STL can
    // be a GiB.
    auto provide = [&res](std::string bytes, const char* type) {
      auto data = std::make_shared<const std::string>(std::move(bytes));
      res.large.body = *data;
      res.large.keep = std::move(data);
      res.set_header("Content-Type", type);
    };
    if (refine_plan) {
      const auto started = std::chrono::steady_clock::now();
      // The reservation grows with the refinement (an adaptive hierarchy's size is known
      // only as it is made); it stops the moment it would pass the budget.
      // Refine + slice answers one zip, made in memory; an STL answer is made from the
      // refined mesh as it is sent.
      api::RefinedMesh refined =
          refine_plan->request.slice
              ? api::RefinedMesh{api::run_refine(body, *refine_plan, {}, cancel, reserve), {}}
              : api::run_refine_to_mesh(body, *refine_plan, {}, cancel, reserve);
      api::RefineOutcome& out = refined.outcome;
      metrics.refinement(
          refine_plan->request.refine.scheme, "done",
          std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(),
          out.report["input"].value("faces", 0ull), out.report["output"].value("faces", 0ull));
      // The report header is compact ASCII JSON (no CR/LF can reach a header).
      const std::string report = out.report.dump(-1, ' ', true);
      if (out.contours) {
        // Refine + slice: one zip with the refined STL, the contours and the report.
        const slicer::SliceFormat format = refine_plan->request.slice->format;
        std::string zip = api::make_zip({{"refined.stl", out.stl, false},
                                         {std::string("slices") + slicer::file_extension(format),
                                          *out.contours, format != slicer::SliceFormat::CliBinary},
                                         {"report.json", report, true}});
        lease.reset();
        keep_answer(zip.size());
        res.set_header(kReportHeader, report);
        res.set_header("Content-Disposition", "attachment; filename=\"refined.zip\"");
        provide(std::move(zip), kZipContentType);
      } else if (refined.stream()) {
        // 84 + 50 n bytes, known now, made on the event loop piece by piece from the float
        // positions and corners (12 bytes a vertex and a face, not 50 a face): the mesh goes.
        auto stl = std::make_shared<const BinaryStl>(std::move(refined.mesh));
        lease.reset();
        keep_answer(stl->memory_bytes());
        res.set_header(kReportHeader, report);
        res.set_header("Content-Type", kStlContentType);
        res.large.made = [stl = stl.get()](std::uint64_t offset, std::span<char> bytes) {
          stl->read(offset, bytes);
        };
        res.large.made_length = stl->size();
        res.large.keep = std::move(stl);
      } else {
        lease.reset();
        keep_answer(out.stl.size());
        res.set_header(kReportHeader, report);
        provide(std::move(out.stl), kStlContentType);
      }
    } else if (slice_plan) {
      api::SliceOutcome out = api::run_slice(body, slice_plan->request, {}, cancel);
      lease.reset();
      keep_answer(out.contours.size());
      res.set_header(kReportHeader, out.report.dump(-1, ' ', true));
      provide(std::move(out.contours), slicer::media_type(slice_plan->request.slice.format));
    } else {
      const nlohmann::ordered_json report = api::run_info(body, info_plan->request);
      lease.reset();
      keep_answer(0);
      res.set_content(report.dump(2, ' ', true) + "\n", kJsonContentType);
    }
    res.status = api::http::kOk;
  } catch (const MemoryBudgetError& e) {
    res.headers.erase(kReportHeader);
    res.headers.erase("Content-Disposition");
    res.headers.erase("Content-Type");
    res.large = Answer();
    respond(res, memory_problem(e, memory.capacity(), [this](std::uint64_t bytes) {
              return memory_busy_problem(bytes);
            }));
  } catch (const Error& e) {
    res.headers.erase(kReportHeader);
    res.headers.erase("Content-Disposition");
    res.headers.erase("Content-Type");
    res.large = Answer();
    if (e.code() == ErrorCode::Cancelled && ticket &&
        ticket->reason() == RequestWatch::Reason::Deadline)
      return respond(res, deadline_problem(config.request_deadline));
    respond(res, api::problem_from_error(e));
  }
}

std::string Daemon::Impl::tenant(const Request& req) const {
  if (config.api_keys.empty() || !jobs) return {};
  // authorized() let it through: "Bearer <one of the keys>".
  const std::string header = req.header("Authorization");
  return jobs->tenant_of(bearer_token(header).value_or(std::string_view()));
}

bool Daemon::Impl::authorized(const Request& req) const {
  if (config.api_keys.empty()) return true;
  const Route* route = find_route(req.path);
  // The page is public: the API calls it makes carry the key the user types in.
  if (route &&
      (route->kind == RouteKind::Page || std::string_view(route->path) == "/healthz" ||
       std::string_view(route->path) == "/readyz" || std::string_view(route->path) == "/metrics"))
    return true;
  const std::string header = req.header("Authorization");
  const std::optional<std::string_view> given = bearer_token(header);
  if (!given) return false;
  bool ok = false;
  for (const std::string& key : config.api_keys) ok |= same_secret(*given, key);  // no early exit
  return ok;
}

void Daemon::Impl::submit_job(const Request& req, std::string_view body, Response& res) {
  if (config.test_hook) config.test_hook("/v1/jobs");
  try {
    // A job that could never get its memory is refused now, not when its turn comes.
    const auto bytes = std::span(reinterpret_cast<const std::uint8_t*>(body.data()), body.size());
    api::RefinePlan plan =
        api::plan_refine(req.parameters(), limits, bytes, api::ResultSink::JobFiles);
    const api::MemoryEstimate& predicted = plan.memory;
    if (predicted.peak_bytes > memory.capacity())
      return respond(res, api::memory_budget_problem(predicted, memory.capacity()));
    const std::size_t q = req.target.find('?');
    std::string query = q == std::string::npos ? "" : req.target.substr(q + 1);
    const std::uint64_t result_bytes = predicted_result_bytes(plan.request, predicted);
    const SubmitResult submitted = stopping
                                       ? SubmitResult::refused(SubmitResult::Status::ShuttingDown)
                                       : jobs->submit(std::move(plan.request), std::move(query),
                                                      body, tenant(req), result_bytes);
    if (submitted.status == SubmitResult::Status::NoSpace)
      return respond(res, no_space_problem(submitted));
    const std::optional<JobView>& job = submitted.job;
    if (!job) {
      api::Problem p =
          submitted.status == SubmitResult::Status::ShuttingDown
              ? busy_problem(true)
              : api::service_unavailable("queue-full", "the job queue is full; retry later");
      return respond(res, p);
    }
    res.status = api::http::kAccepted;
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
    return respond(res, api::not_found("not-found", "no route " + shortened(req.path)));
  if (!file.empty() && req.method == "DELETE") {
    api::Problem p = api::method_not_allowed(
        "method-not-allowed", "DELETE is not allowed on a job's files (allowed: GET, HEAD)");
    p.extensions["allow"] = "GET, HEAD";
    return respond(res, p);
  }
  JobView job;
  // Another tenant's job is Unknown, exactly as an id that was never issued.
  const std::string owner = tenant(req);
  const JobStore::Lookup found =
      req.method == "DELETE" ? jobs->cancel(id, owner, &job) : jobs->find(id, owner, &job);
  if (found == JobStore::Lookup::Unknown)
    return respond(res, api::not_found("unknown-job", "no job " + shortened(id)));
  if (req.method == "DELETE") {
    // A cancel either wins (the job ends cancelled, whatever the runner was doing) or says
    // it came too late: the job had finished, and DELETE removed its results.
    nlohmann::ordered_json j = job_json(job);
    if (found == JobStore::Lookup::TooLate) {
      j["cancel"] = "too_late";
      j["cancel_detail"] = "the job had already ended " + std::string(to_string(job.state)) +
                           "; its results were deleted";
    } else if (found == JobStore::Lookup::Expired) {
      j["cancel"] = "too_late";
      j["cancel_detail"] = "the job had already ended and its results were removed";
    } else {
      // A running job stops at its next cancellation check and then reads "cancelled".
      j["cancel"] = "cancelled";
    }
    res.set_content(j.dump(2) + "\n", kJsonContentType);
    return;
  }
  if (found == JobStore::Lookup::Expired && (req.method != "DELETE" && !file.empty())) {
    return respond(res, api::gone("expired", "the results of job " + id +
                                                 " were removed after the retention period"));
  }
  if (file.empty()) {
    if (found == JobStore::Lookup::Expired && req.method != "DELETE") res.status = api::http::kGone;
    res.set_content(job_json(job).dump(2) + "\n", kJsonContentType);
    return;
  }
  if (job.state != JobState::Done) {
    api::Problem p =
        api::conflict("not-done", "job " + id + " is " + to_string(job.state) + ", not done");
    p.extensions["state"] = to_string(job.state);
    return respond(res, p);
  }
  if (std::find(job.results.begin(), job.results.end(), file) == job.results.end())
    return respond(res, api::not_found("no-such-result", "job " + id + " has no " + file));
  // The front end sends the file from its descriptor: results can be large. It was written by
  // rename, so it is complete; the open descriptor keeps it readable if it expires meanwhile.
  const int fd = ::open(jobs->result_path(id, file).c_str(), O_RDONLY | O_CLOEXEC);
  struct stat st {};
  if (fd < 0 || ::fstat(fd, &st) != 0) {
    if (fd >= 0) ::close(fd);
    return respond(res, api::gone("expired", "the results of job " + id + " are gone"));
  }
  res.large.file = fd;
  res.large.file_length = static_cast<std::uint64_t>(st.st_size);
  const char* type = file == "result.stl"      ? kStlContentType
                     : file == "report.json"   ? kJsonContentType
                     : file == "contours.json" ? slicer::media_type(slicer::SliceFormat::Json)
                     : file == "contours.svg"  ? slicer::media_type(slicer::SliceFormat::Svg)
                                               : "application/octet-stream";
  res.set_header("Content-Type", type);
  res.set_header("Content-Disposition", "attachment; filename=\"" + file + "\"");
}

// The embedded page (web/assets.h). Cache-Control no-cache with a strong ETag: a browser
// revalidates and gets 304, and never keeps a page from an older daemon.
void Daemon::Impl::page(const Request& req, Response& res, std::string_view name) const {
  if (web::assets().empty())
    return respond(res, api::not_found("page-not-built", std::string(web::missing_reason())));
  const web::Asset* asset = web::find_asset(name);
  if (!asset) return respond(res, api::not_found("not-found", "no route " + shortened(req.path)));
  res.set_header("ETag", std::string(asset->etag));
  res.set_header("Cache-Control", "no-cache");
  res.set_header("X-Content-Type-Options", "nosniff");
  if (name == "index.html") {
    res.set_header("Content-Security-Policy",
                   "default-src 'self'; img-src 'self' data: blob:; object-src 'none'; "
                   "base-uri 'none'; form-action 'none'; frame-ancestors 'none'");
    res.set_header("Referrer-Policy", "no-referrer");
  }
  const std::string match = req.header("If-None-Match");
  if (!match.empty() && (match == "*" || match.find(asset->etag) != std::string::npos)) {
    res.status = api::http::kNotModified;
    // The library writes "Content-Length: 0" on an empty answer; a 304 may only carry the
    // length the 200 would have had (RFC 9110 8.6).
    res.set_header("Content-Length", std::to_string(asset->bytes.size()));
    return;
  }
  res.set_header("Content-Type", std::string(asset->content_type));
  res.large.body = asset->bytes;  // embedded in the binary
}

std::pair<std::string, std::optional<api::Problem>> Daemon::Impl::readiness() const {
  if (stopping || slots.available() == 0) return {std::string(), busy_problem(stopping)};
  nlohmann::ordered_json j;
  j["status"] = "ready";
  j["compute_slots"] = slots.capacity();
  j["available"] = slots.available();
  return {j.dump() + "\n", std::nullopt};
}

Daemon::Daemon(DaemonConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {}

Daemon::~Daemon() {
  cancel_running();
  stop();
}

int Daemon::bind(const std::string& host, int port) {
  return impl_->listener.bind(host, port);
}

void Daemon::run() {
  impl_->running = true;
  impl_->front->start();
  if (!impl_->stopping) impl_->listener.listen();
  // Running jobs get the same grace as the answers, at the same time.
  std::thread jobs_shutdown;
  if (impl_->jobs)
    jobs_shutdown = std::thread([this] { impl_->jobs->shutdown(impl_->config.shutdown_grace); });
  // Requests already read are computed and their answers written in full; bodies still
  // arriving are refused. What is still running when the grace ends is cancelled, and
  // answers still being written then are abandoned (logged as aborted).
  impl_->front->stop(impl_->front_answer(nullptr, impl_->busy_problem(true)),
                     impl_->config.shutdown_grace, [this] { impl_->watch.cancel_all(); });
  impl_->running = false;
  if (jobs_shutdown.joinable()) jobs_shutdown.join();
}

void Daemon::stop() {
  impl_->stopping = true;
  // run() may be between its stopping check and the library's accept loop: wait for the
  // loop to start, or stop() would find nothing to stop.
  while (impl_->running && !impl_->listener.is_running())
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  impl_->listener.stop();
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
