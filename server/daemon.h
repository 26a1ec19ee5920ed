// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "server/compute_slots.h"
#include "server/jobs.h"
#include "server/memory_budget.h"

namespace stlrefine::server {

//! What the memory budget keeps for the idle daemon itself (about 10 MiB of RSS measured,
//! the rest for allocator slack, connection buffers and bodies still arriving).
inline constexpr std::uint64_t kDaemonReserve = std::uint64_t{64} << 20;

//! Everything `stlrefined` can be told. Defaults are the daemon's defaults.
struct DaemonConfig {
  //! HTTP worker threads; 0 = compute slots + 4, so health checks and fast 4xx/503
  //! answers never wait behind the compute requests.
  std::size_t http_threads = 0;
  //! Requests computing at once (refine and info); 0 = std::thread::hardware_concurrency.
  //! One more gets 503 with Retry-After at once.
  std::size_t compute_slots = 0;
  //! Largest request body in bytes (413 above); default 256 MiB.
  std::size_t max_body_bytes = std::size_t{256} << 20;
  //! Face cap of one refinement, [1, 2^31); a request's max_faces may only lower it.
  std::uint64_t max_faces = 20'000'000;
  //! Contour points one slice answer may hold (about 20 bytes each in JSON), checked before
  //! the contour pass; more is 422 budget-exceeded, field max_points.
  std::uint64_t max_slice_points = 20'000'000;
  //! A request head must arrive within read_timeout; a body must arrive, and an answer be
  //! read, at min_transfer_rate bytes/s or more over every read_timeout (body) and
  //! write_timeout (answer) window, else the connection is dropped (408 for a body).
  std::chrono::seconds read_timeout{10};
  std::chrono::seconds write_timeout{10};
  std::uint64_t min_transfer_rate = 64 * 1024;
  //! Connections open at once (reading, computing, answering), and per client address (0 =
  //! no per-address cap). Connections over a cap are only answered when they are /healthz
  //! or /readyz (or a refusal decided on the head); anything else gets 503.
  std::size_t max_connections = 1024;
  std::size_t max_connections_per_client = 256;
  //! Bytes the whole daemon may use (0 = half the RAM or the cgroup limit, see
  //! default_memory_budget). kDaemonReserve of it is kept for the idle daemon; each compute
  //! request and job reserves its predicted peak (api/memory_model.h) from the rest, body and
  //! answer included: a prediction above what one request may reserve is a 422 before any
  //! work, one that does not fit next to the running ones a 503 (jobs wait in the queue).
  std::uint64_t memory_budget = 0;
  //! A computation (refine, slice, info, job) running longer is cancelled: 504
  //! deadline-exceeded, a job ends failed. 0 = no deadline.
  std::chrono::milliseconds request_deadline{0};
  //! Nice increment of the threads that compute (HTTP workers, job runners and the TBB
  //! workers they start); the accept loop, the event loop and the request watch keep the
  //! process's priority, so /healthz and refusals are answered at once even when every
  //! core computes. 0 = all threads at one priority.
  int compute_nice = 10;
  //! Value of Retry-After on 503 answers.
  int retry_after_seconds = 2;
  //! One JSON line per request on stderr: time, request id, method, path, route, status,
  //! bytes sent, milliseconds.
  bool access_log = false;
  //! Asynchronous jobs (POST /v1/jobs ...) are served when jobs.data_dir is not empty.
  JobsConfig jobs;
  //! On shutdown, requests and jobs in flight may finish (and answers be written) for this
  //! long; then they are cancelled and unwritten answers abandoned.
  std::chrono::seconds shutdown_grace{30};
  //! When not empty, every route except /healthz, /readyz and /metrics needs
  //! `Authorization: Bearer <key>` with one of these keys (compared in constant time).
  std::vector<std::string> api_keys;
  //! Origins whose browser pages may call the API (CORS): "scheme://host[:port]" or "*".
  //! Empty: no CORS field is ever sent, and a preflight (OPTIONS) answers 403.
  std::vector<std::string> cors_origins;
  //! For tests only: called with the route ("/v1/refine", ...) at the start of each route
  //! handler. It may throw, to exercise the generic 500 path.
  std::function<void(std::string_view route)> test_hook;
  //! For tests only (stlrefined --test-faults): a compute request with the header
  //! `X-Stlrefine-Test-Fault: throw` throws from its handler, `oom` fails a real allocation
  //! there, to exercise the generic 500 path in the real process. Never set in production.
  bool test_faults = false;
};

//! The HTTP daemon: routes, hardening around cpp-httplib 0.11.4 (see daemon.cpp), and the
//! compute slots. cpp-httplib only binds and accepts (server/http_adapter.cpp).
//!
//! Routes: POST /v1/refine, POST /v1/slice, POST /v1/info, POST /v1/jobs, GET and DELETE
//! /v1/jobs/{id}, GET /v1/jobs/{id}/{file}, GET /v1/openapi.json, GET /metrics, GET /healthz,
//! GET /readyz. Every error is an RFC 9457 application/problem+json body; every answer has
//! an X-Request-Id.
class Daemon {
 public:
  //! \throw std::invalid_argument for a config out of range.
  explicit Daemon(DaemonConfig config);
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  //! Binds the listening socket; port 0 picks a free port. Returns the bound port.
  //! \throw std::runtime_error when the address cannot be bound.
  int bind(const std::string& host, int port);
  //! Serves until stop(). Requests in flight are answered before it returns; then queued
  //! jobs are failed and running ones get shutdown_grace to finish before being cancelled.
  //! \pre bind() succeeded
  void run();
  //! Stops accepting connections and makes run() return once the requests in flight are
  //! answered. Thread-safe and idempotent; /readyz answers 503 from now on.
  void stop();
  //! Asks running refinements to give up (they answer 503): a second SIGTERM.
  void cancel_running();

  ComputeSlots& compute_slots();
  MemoryBudget& memory_budget();
  //! Null when jobs are not enabled.
  JobStore* jobs();
  const DaemonConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

//! Every (path, methods) the daemon serves, for the OpenAPI test.
struct RouteInfo {
  std::string path;     //!< OpenAPI form: "/v1/jobs/{id}"
  std::string methods;  //!< "GET, HEAD"
};
std::vector<RouteInfo> served_routes();

//! The OpenAPI 3 document served at /v1/openapi.json.
const std::string& openapi_document();
//! True when the OpenAPI document has a description for this query parameter.
bool documented_parameter(const std::string& name);

//! The `listening on` URL for a bound host and port ("http://[::1]:8080" for IPv6).
std::string listen_url(const std::string& host, int port);

}  // namespace stlrefine::server
