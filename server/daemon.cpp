// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/daemon.h"

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "api/params.h"
#include "api/problem.h"
#include "server/build_info.h"
#include "server/compute_routes.h"
#include "server/cors.h"
#include "server/front_end.h"
#include "server/http.h"
#include "server/http_adapter.h"
#include "server/http_upload.h"
#include "server/job_parts.h"
#include "server/job_routes.h"
#include "server/metrics.h"
#include "server/page.h"
#include "server/redis_client.h"
#include "server/request_watch.h"
#include "server/route_context.h"
#include "server/routes.h"

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

std::string request_id_of(const HttpRequest& req) {
  return request_id(req.header("X-Request-Id"));
}

//! What decide() hands to the worker with a request (ReadRequest::hold, kept until the
//! answer is written): what the checks before the body found, and the body's memory
//! reservation (compute and job routes).
struct Accepted {
  CheckedRequest checked;
  std::shared_ptr<MemoryBudget::Reservation> reservation;
};

}  // namespace

struct Daemon::Impl : FrontEndDelegate {
  explicit Impl(DaemonConfig c);

  //! Hands the request to its route's handler (compute_routes.h, job_routes.h, page.h) or
  //! answers the plain routes. Large bodies go into res.large (a view kept alive by
  //! large.keep, a file, or bytes made as they are sent), small ones into res.body.
  void route(const HttpRequest& req, ReadRequest& read, HttpAnswer& res, bool& ranges);
  //! The answer the front end writes (http_adapter.h's frame_answer), with its
  //! X-Request-Id, recorded when it is written.
  Answer finish(const HttpRequest& req, HttpAnswer res, bool ranges,
                std::chrono::steady_clock::time_point accepted);
  //! /readyz: 200 with the slots, or the busy / shutting-down problem.
  std::pair<std::string, std::optional<api::Problem>> readiness() const;
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
  std::string front_answer(const HttpRequest* req, const api::Problem& problem);
  //! A CORS preflight (OPTIONS with Origin and Access-Control-Request-Method): 204 with the
  //! route's methods for an allowed origin, else 403; no API key needed (browsers send none).
  std::string preflight_answer(const HttpRequest& req);

  DaemonConfig config;
  CorsPolicy cors;
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
  //! What the handlers share of the above.
  RouteContext ctx{config, limits, slots, memory, watch, metrics, nullptr, stopping};
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
  if (!c.jobs.run_jobs && c.jobs.queue.empty())
    throw std::invalid_argument(
        "--role api needs --queue: without a shared queue its jobs would never run");
  if (!c.jobs.queue.empty()) {
    if (c.jobs.data_dir.empty())
      throw std::invalid_argument(
          "--queue needs --data-dir: a directory every replica shares (NFS, CephFS, a "
          "ReadWriteMany volume) for the jobs' inputs and results");
    parse_redis_address(c.jobs.queue);  // its own precise error
    if (c.jobs.lease.count() < 1 || c.jobs.lease.count() > 3600)
      throw std::invalid_argument("--lease-seconds must be in [1, 3600]");
    if (c.jobs.max_attempts < 1 || c.jobs.max_attempts > 100)
      throw std::invalid_argument("--max-attempts must be in [1, 100]");
  }
  for (const std::string& key : c.api_keys)
    if (key.size() < 16) throw std::invalid_argument("API keys must be at least 16 characters");
  return c;
}

}  // namespace

Daemon::Impl::Impl(DaemonConfig c)
    : config(checked(std::move(c))),
      cors(config.cors_origins),
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
    // Queue mode: a job taken from the queue is planned as POST /v1/jobs planned it
    // (server/job_routes.cpp; an Accept: model/3mf comes as mesh_format=3mf).
    jc.plan_job = [this](const std::string& query, const std::string& name,
                         std::string_view input) {
      api::RawParams raw = api::parse_query(query);
      std::erase_if(
          raw, [](const auto& p) { return p.first == "filename" || p.first == "callback_url"; });
      api::RefinePlan plan = api::plan_refine(api::parse_refine_fields(raw, limits));
      if (plan.request.slice) plan.request.slice->writer.label = download_stem(name);
      const auto bytes =
          std::span(reinterpret_cast<const std::uint8_t*>(input.data()), input.size());
      // A zip, or a 3MF of several objects to STL: a parts job (its content was checked
      // against the body limit at submit).
      const std::optional<std::vector<api::ArchivePart>> parts = job_parts(
          bytes, plan.request, job_archive_limits(std::numeric_limits<std::uint64_t>::max()));
      std::uint64_t result_bytes = 0;
      return parts ? plan_parts_job(plan, *parts, &result_bytes)
                   : api::plan_body(std::move(plan), bytes, api::ResultSink::JobFiles);
    };
    jobs = std::make_unique<JobStore>(jc, slots, [this](const JobView& job, double seconds) {
      const auto& r = job.report;
      const std::uint64_t in = r.contains("input") ? r["input"].value("faces", 0ull) : 0;
      const std::uint64_t out = r.contains("output") ? r["output"].value("faces", 0ull) : 0;
      metrics.refinement(job.scheme, to_string(job.state), seconds, in, out);
    });
  }
  ctx.jobs = jobs.get();
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

std::string Daemon::Impl::front_answer(const HttpRequest* req, const api::Problem& problem) {
  const std::string id = req ? request_id_of(*req) : request_id(std::string());
  Fields headers = ctx.problem_headers(problem);
  headers.emplace("X-Request-Id", id);
  if (req) headers.merge(cors.answer_fields(req->header("Origin")));
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
  const HttpRequest req = to_http_request(*head);
  return front_answer(&req, problem);
}

std::string Daemon::Impl::preflight_answer(const HttpRequest& req) {
  const Route* route = find_route(req.path);
  if (!route)
    return front_answer(&req, api::not_found("not-found", "no route " + shortened(req.path)));
  const std::string origin = req.header("Origin");
  std::optional<Fields> fields = cors.preflight_fields(origin, route->allow);
  if (!fields)
    return front_answer(
        &req, api::forbidden("cors-origin-not-allowed",
                             "the origin " + shortened(origin) +
                                 " may not call this API (the server allows: " +
                                 (cors.enabled() ? "--cors-origin values" : "none") + ")"));
  const std::string id = request_id_of(req);
  fields->emplace("X-Request-Id", id);
  fields->emplace("Allow", route->allow);
  record(req.method, req.path, api::http::kNoContent, 0, 0.0, id, req.remote_addr);
  return whole_answer(api::http::kNoContent, "text/plain", "", *fields, true);
}

Verdict Daemon::Impl::decide(const RequestHead& head) {
  const HttpRequest req = to_http_request(head);
  Verdict verdict;
  if (CorsPolicy::is_preflight(req)) {
    verdict.kind = Verdict::Kind::Answer;
    verdict.response = preflight_answer(req);
    return verdict;
  }
  // Probes are answered here, on the event loop: they never wait behind a worker.
  const bool probe = (req.path == "/healthz" || req.path == "/readyz") &&
                     (req.method == "GET" || req.method == "HEAD");
  auto accepted = std::make_shared<Accepted>();
  std::optional<api::Problem> problem = ctx.precheck(req, accepted->checked);
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
    const std::string id = request_id_of(req);
    const bool head_only = req.method == "HEAD";
    record(req.method, req.path, api::http::kOk, head_only ? 0 : body.size(), 0.0, id,
           req.remote_addr);
    verdict.kind = Verdict::Kind::Answer;
    Fields fields = cors.answer_fields(req.header("Origin"));
    fields.emplace("X-Request-Id", id);
    verdict.response = whole_answer(api::http::kOk, kJsonContentType, body, fields, head_only);
    return verdict;
  }
  if (problem) {
    verdict.kind = Verdict::Kind::Answer;
    verdict.response = front_answer(&req, *problem);
    return verdict;
  }
  verdict.hold = accepted;
  const Route* route = accepted->checked.route;
  if (has_body(*route, req.method)) {
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
      accepted->reservation = reservation;
      verdict.reserve_body = [this, reservation, req](std::uint64_t bytes) -> std::string {
        if (reservation->grow_to(bytes)) return {};
        return front_answer(&req, ctx.memory_busy_problem(bytes));
      };
    }
  }
  return verdict;
}

Answer Daemon::Impl::serve(ReadRequest& read) {
  const HttpRequest req = to_http_request(read.head, read.body);
  HttpAnswer res;
  bool ranges = false;
  try {
    route(req, read, res, ranges);
  } catch (const RedisUnavailable& e) {
    // Queue mode with Redis away: the job routes answer 503 (the others never ask Redis).
    log_line(std::string("stlrefined: ") + e.what());
    res = HttpAnswer();
    ranges = false;
    api::Problem p = api::service_unavailable(
        "queue-unavailable", "the job queue (Redis) cannot be reached; retry later");
    p.extensions["reason"] = "queue_unavailable";
    ctx.respond(res, p);
  } catch (const RedisError& e) {
    // A full Redis (maxmemory, noeviction) refuses writes with OOM: retry later, like a
    // full queue; any other error reply is ours (a 500 below).
    if (std::string_view(e.what()).find("OOM") == std::string_view::npos) {
      log_line("stlrefined: internal error on " + req.method + " " + shortened(req.path) + ": " +
               e.what());
      res = HttpAnswer();
      ranges = false;
      send_problem(res, api::internal_error());
    } else {
      log_line(std::string("stlrefined: ") + e.what());
      res = HttpAnswer();
      ranges = false;
      api::Problem p = api::service_unavailable(
          "queue-full", "the job queue (Redis) is out of memory; retry later");
      p.extensions["reason"] = "queue_out_of_memory";
      ctx.respond(res, p);
    }
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
    res = HttpAnswer();
    ranges = false;
    send_problem(res, api::internal_error());
  }
  return finish(req, std::move(res), ranges, read.accepted);
}

void Daemon::Impl::route(const HttpRequest& req, ReadRequest& read, HttpAnswer& res, bool& ranges) {
  // decide() ran every check on the event loop and resolved the parameters; what may have
  // changed while the body arrived (every slot taken, the job queue full, shutting down) is
  // checked again.
  Accepted& accepted = *std::static_pointer_cast<Accepted>(read.hold);
  const Route& r = *accepted.checked.route;
  if (has_body(r, req.method))
    if (std::optional<api::Problem> problem = ctx.check_capacity(r))
      return ctx.respond(res, *problem);
  switch (r.kind) {
    case RouteKind::Compute:
      return serve_compute(ctx, req, std::move(accepted.checked), read.fd, accepted.reservation,
                           res);
    case RouteKind::Submit:
      if (req.method != "POST") return serve_job_list(ctx, req, res);
      return serve_job_submit(ctx, req, std::move(*accepted.checked.refine), res);
    case RouteKind::JobItem:
      ranges = true;
      return serve_job_item(ctx, req, res);
    case RouteKind::Page: {
      ranges = true;
      if (req.path == "/") return serve_page(ctx, req, "index.html", res);
      const std::string name = req.path.substr(std::string_view("/assets/").size());
      if (name.find('/') != std::string::npos)
        return ctx.respond(res, api::not_found("not-found", "no route " + shortened(req.path)));
      return serve_page(ctx, req, name, res);
    }
    case RouteKind::Plain:
      break;
  }
  if (req.path == "/v1/openapi.json") return res.set_content(openapi_document(), kJsonContentType);
  if (req.path == "/v1/version") return res.set_content(version_document(), kJsonContentType);
  if (req.path == "/metrics") {
    Metrics::Gauges g;
    g.compute_slots = slots.capacity();
    g.compute_slots_free = slots.available();
    g.memory_budget_bytes = memory.budget();
    g.memory_reserved_bytes = memory.reserved();
    if (jobs) {
      g.jobs_queued = jobs->queued();
      g.jobs_running = jobs->running();
      if (const auto q = jobs->queue_stats())
        g.queue =
            Metrics::QueueGauges{q->reachable, q->depth, q->pending, q->reclaims, q->attempts};
    }
    return res.set_content(metrics.render(g) + process_metrics(), "text/plain; version=0.0.4");
  }
  // /healthz and /readyz: normally answered by decide() on the event loop.
  if (config.test_hook) config.test_hook(r.path);
  if (req.path == "/readyz") {
    auto [ready, busy] = readiness();
    if (busy) return ctx.respond(res, *busy);
    return res.set_content(ready, kJsonContentType);
  }
  res.set_content("{\"status\":\"ok\"}\n", kJsonContentType);
}

Answer Daemon::Impl::finish(const HttpRequest& req, HttpAnswer res, bool ranges,
                            std::chrono::steady_clock::time_point accepted) {
  const std::string id = request_id_of(req);
  res.set_header("X-Request-Id", id);
  for (auto& [name, value] : cors.answer_fields(req.header("Origin"))) res.set_header(name, value);
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

std::pair<std::string, std::optional<api::Problem>> Daemon::Impl::readiness() const {
  if (stopping || slots.available() == 0) return {std::string(), ctx.busy_problem(stopping)};
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
  impl_->front->stop(impl_->front_answer(nullptr, impl_->ctx.busy_problem(true)),
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
