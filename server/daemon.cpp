// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/daemon.h"

// httplib.h must see the same CPPHTTPLIB_*_SUPPORT macros Debian's libcpp-httplib.so was
// built with (Request has an extra member under OPENSSL): they come from the
// httplib::httplib target (pkg-config cflags), never from here.
#include <httplib.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <charconv>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "api/params.h"
#include "api/pipeline.h"
#include "api/problem.h"
#include "api/zip.h"
#include "core/error.h"
#include "slicer/writers.h"

// Hardening around cpp-httplib 0.11.4 (Debian 12), and why each piece is needed:
//
//  - The pre-routing handler runs after the headers are read and before the body is, so
//    every check that needs only the request line and headers happens there: route (404),
//    method (405), Transfer-Encoding or no Content-Length on POST (411: 0.11.4 reads such
//    bodies without applying the payload limit), any Content-Encoding (415: the library
//    would inflate gzip/brotli bodies with no limit on the inflated size), Content-Type
//    (415), Content-Length over the cap (413, without reading the body), parameters (400)
//    and a full house (503). The same checks answer `Expect: 100-continue`, so a client
//    that asks first never uploads a body that would be refused.
//  - A refused body is never read. keep_alive_max_count(1) closes every connection after
//    its response, so unread body bytes can never be parsed as the next request.
//  - set_payload_max_length stays as the library's own backstop (413 after skipping the
//    body); the error handler gives its 413, like every other library answer >= 400 with
//    an empty body (400 parse errors, 404, 414, ...), a problem+json body.
//  - The library's ThreadPool queues accepted connections without bound; BoundedTaskQueue
//    blocks the accept loop instead, so excess connections wait in the kernel's backlog.
//  - Compute requests take a ComputeSlots lease and get 503 + Retry-After at once when
//    none is free.
//  - httplib's default socket options set SO_REUSEPORT: a second daemon on the same port
//    would bind successfully and share the traffic. Ours set SO_REUSEADDR only.
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

//! httplib::TaskQueue with a bounded backlog: enqueue() blocks while `max_queued` accepted
//! connections already wait for a worker, which stalls the accept loop (the kernel's listen
//! backlog then holds further clients) instead of growing a list without limit.
class BoundedTaskQueue : public httplib::TaskQueue {
 public:
  BoundedTaskQueue(std::size_t threads, std::size_t max_queued) : max_queued_(max_queued) {
    for (std::size_t i = 0; i < threads; ++i) workers_.emplace_back([this] { work(); });
  }
  ~BoundedTaskQueue() override = default;

  void enqueue(std::function<void()> fn) override {
    std::unique_lock lock(mutex_);
    space_.wait(lock, [&] { return jobs_.size() < max_queued_ || shutdown_; });
    jobs_.push_back(std::move(fn));
    work_.notify_one();
  }

  void shutdown() override {
    {
      std::lock_guard lock(mutex_);
      shutdown_ = true;
    }
    work_.notify_all();
    space_.notify_all();
    for (std::thread& t : workers_) t.join();
  }

 private:
  void work() {
    for (;;) {
      std::function<void()> fn;
      {
        std::unique_lock lock(mutex_);
        work_.wait(lock, [&] { return !jobs_.empty() || shutdown_; });
        if (jobs_.empty()) return;  // shut down and drained: queued connections are served
        fn = std::move(jobs_.front());
        jobs_.pop_front();
      }
      space_.notify_one();
      try {
        fn();
      } catch (...) {
        // httplib catches handler exceptions itself; anything else must not kill the pool.
      }
    }
  }

  const std::size_t max_queued_;
  std::mutex mutex_;
  std::condition_variable work_, space_;
  std::deque<std::function<void()>> jobs_;
  std::vector<std::thread> workers_;
  bool shutdown_ = false;
};

struct Route {
  const char* path;
  const char* allow;  // the Allow header of a 405
  bool compute;       // POST with an STL body, takes a compute slot
};

constexpr Route kRoutes[] = {
    {"/v1/refine", "POST", true},     {"/v1/slice", "POST", true},     {"/v1/info", "POST", true},
    {"/healthz", "GET, HEAD", false}, {"/readyz", "GET, HEAD", false},
};

const Route* find_route(const std::string& path) {
  for (const Route& r : kRoutes)
    if (path == r.path) return &r;
  return nullptr;
}

bool method_allowed(const Route& route, const std::string& method) {
  return route.compute ? method == "POST" : (method == "GET" || method == "HEAD");
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
api::RawParams raw_params(const Request& req) {
  const std::string& target = req.target;
  const std::size_t q = target.find('?');
  api::RawParams params;
  if (q == std::string::npos) return params;
  httplib::Params parsed;
  httplib::detail::parse_query_text(target.substr(q + 1), parsed);
  return api::RawParams(parsed.begin(), parsed.end());
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

struct Daemon::Impl {
  explicit Impl(DaemonConfig c);

  void install();
  std::optional<api::Problem> precheck(const Request& req) const;
  api::Problem busy_problem(bool stopping) const;
  //! The body for an answer httplib made itself (status set, body empty).
  api::Problem library_problem(int status, const Request& req) const;
  void respond(Response& res, const api::Problem& problem) const;
  void compute(const Request& req, std::string_view body, Response& res, const Route& route);
  void readyz(Response& res) const;

  DaemonConfig config;
  api::RequestLimits limits;
  ComputeSlots slots;
  httplib::Server http;
  std::atomic<bool> running{false};   // run() is active
  std::atomic<bool> stopping{false};  // stop() was called
  std::atomic<bool> cancel{false};    // running refinements should give up
};

namespace {

DaemonConfig checked(DaemonConfig c) {
  if (c.compute_slots == 0) c.compute_slots = std::max(1u, std::thread::hardware_concurrency());
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
  return c;
}

}  // namespace

Daemon::Impl::Impl(DaemonConfig c)
    : config(checked(std::move(c))),
      limits{.max_faces = config.max_faces,
             .default_max_faces = 0,
             .max_slice_points = config.max_slice_points,
             .accept_threads = false},
      slots(config.compute_slots) {
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
  if (!route->compute) return std::nullopt;

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
    if (route->path == std::string_view("/v1/refine"))
      api::parse_refine_params(raw_params(req), limits);
    else if (route->path == std::string_view("/v1/slice"))
      api::parse_slice_params(raw_params(req), limits);
    else
      api::parse_info_params(raw_params(req));
  } catch (const Error& e) {
    return api::problem_from_error(e);
  }

  // A full house is told at once. The handler takes the slot for real after the upload.
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

void Daemon::Impl::respond(Response& res, const api::Problem& problem) const {
  if (problem.status == 503)
    res.set_header("Retry-After", std::to_string(config.retry_after_seconds));
  if (problem.status == 405 && problem.extensions.contains("allow"))
    res.set_header("Allow", problem.extensions["allow"].get<std::string>());
  send_problem(res, problem);
}

void Daemon::Impl::compute(const Request& req, std::string_view raw_body, Response& res,
                           const Route& route) {
  if (config.test_hook) config.test_hook(route.path);
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
      api::RefineOutcome out = api::run_refine(body, *refine_request, {}, &cancel);
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
        res.set_header(kReportHeader, report);
        res.set_header("Content-Disposition", "attachment; filename=\"refined.zip\"");
        provide(std::move(zip), kZipContentType);
      } else {
        lease.reset();
        res.set_header(kReportHeader, report);
        provide(std::move(out.stl), kStlContentType);
      }
    } else if (slice_request) {
      api::SliceOutcome out = api::run_slice(body, *slice_request, {}, &cancel);
      lease.reset();
      res.set_header(kReportHeader, out.report.dump(-1, ' ', true));
      provide(std::move(out.contours), slicer::media_type(slice_request->slice.format));
    } else {
      const nlohmann::ordered_json report = api::run_info(body, *info_request);
      lease.reset();
      res.set_content(report.dump(2, ' ', true) + "\n", kJsonContentType);
    }
    res.status = 200;
  } catch (const Error& e) {
    res.headers.erase(kReportHeader);
    res.headers.erase("Content-Disposition");
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

void Daemon::Impl::readyz(Response& res) const {
  if (stopping || slots.available() == 0) return respond(res, busy_problem(stopping));
  nlohmann::ordered_json j;
  j["status"] = "ready";
  j["compute_slots"] = slots.capacity();
  j["available"] = slots.available();
  res.set_content(j.dump() + "\n", kJsonContentType);
}

void Daemon::Impl::install() {
  http.new_task_queue = [threads = config.http_threads] {
    return new BoundedTaskQueue(threads, 4 * threads);
  };
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

  http.set_expect_100_continue_handler([this](const Request& req, Response& res) {
    try {
      if (std::optional<api::Problem> problem = precheck(req)) {
        respond(res, *problem);
        // 0.11.4 writes this answer without a Content-Length of its own.
        res.set_header("Content-Length", std::to_string(res.body.size()));
        return res.status;
      }
      return 100;
    } catch (...) {  // not inside httplib's try: an escape would terminate the process
      respond(res, api::make_problem(500, "internal", "an internal error occurred"));
      return 500;
    }
  });

  http.set_pre_routing_handler([this](const Request& req, Response& res) {
    if (std::optional<api::Problem> problem = precheck(req)) {
      respond(res, *problem);
      return HandlerResponse::Handled;
    }
    return HandlerResponse::Unhandled;
  });

  for (const Route& route : kRoutes) {
    if (route.compute) {
      // A content-reader route gets the body bytes as sent (payload limit still applied).
      // httplib's default reader would form-decode an application/x-www-form-urlencoded
      // body (curl's default label) and refuse it above 8 KiB.
      http.Post(route.path, [this, &route](const Request& req, Response& res,
                                           const httplib::ContentReader& reader) {
        // Content-Length was validated by the pre-routing check (one number, under the cap).
        const std::string length_text = req.get_header_value("Content-Length");
        std::uint64_t length = 0;
        std::from_chars(length_text.data(), length_text.data() + length_text.size(), length);
        std::string body;
        body.reserve(
            static_cast<std::size_t>(std::min<std::uint64_t>(length, config.max_body_bytes)));
        reader([&](const char* data, std::size_t n) {
          body.append(data, n);
          return true;
        });
        compute(req, body, res, route);
      });
    }
  }
  http.Get("/healthz", [this](const Request&, Response& res) {
    if (config.test_hook) config.test_hook("/healthz");
    res.set_content("{\"status\":\"ok\"}\n", kJsonContentType);
  });
  http.Get("/readyz", [this](const Request&, Response& res) {
    if (config.test_hook) config.test_hook("/readyz");
    readyz(res);
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

  if (config.access_log) {
    http.set_logger([](const Request& req, const Response& res) {
      const std::size_t bytes = res.body.empty() ? res.content_length_ : res.body.size();
      log_line(req.method + " " + shortened(req.path) + " " + std::to_string(res.status) + " " +
               std::to_string(bytes));
    });
  }
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
    return bound;
  }
  if (!impl_->http.bind_to_port(host, port))
    throw std::runtime_error("cannot bind " + host + ":" + std::to_string(port));
  return port;
}

void Daemon::run() {
  impl_->running = true;
  if (!impl_->stopping) impl_->http.listen_after_bind();
  impl_->running = false;
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
  impl_->cancel = true;
}

ComputeSlots& Daemon::compute_slots() {
  return impl_->slots;
}

const DaemonConfig& Daemon::config() const {
  return impl_->config;
}

std::string listen_url(const std::string& host, int port) {
  const bool ipv6 = host.find(':') != std::string::npos;
  return "http://" + (ipv6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

}  // namespace stlrefine::server
