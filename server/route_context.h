// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// What the route handlers share: the daemon's configuration and the resources requests take
// (compute slots, the memory budget, the job store), the checks a request passes before its
// body is read, and the problem answers they give. The daemon owns the resources; a test
// can make its own and call a handler with an HttpRequest and no socket.

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>

#include "api/params.h"
#include "api/plan.h"
#include "api/problem.h"
#include "server/compute_slots.h"
#include "server/daemon.h"
#include "server/http.h"
#include "server/jobs.h"
#include "server/memory_budget.h"
#include "server/metrics.h"
#include "server/request_watch.h"
#include "server/routes.h"

namespace stlrefine::server {

//! What the checks before the body found: the route and, for a route with a body, its
//! parameters resolved once (a refinement's plan without its body: parsed, validated, its
//! scheme made). The handler completes that with the body; nothing is parsed again.
struct CheckedRequest {
  const Route* route = nullptr;
  std::optional<api::RefinePlan> refine;   //!< /v1/refine, /v1/jobs
  std::optional<api::SliceRequest> slice;  //!< /v1/slice
  std::optional<api::InfoRequest> info;    //!< /v1/info
};

struct RouteContext {
  const DaemonConfig& config;
  const api::RequestLimits& limits;
  ComputeSlots& slots;
  MemoryBudget& memory;
  RequestWatch& watch;  //!< cancels computations (client gone, deadline, SIGTERM)
  Metrics& metrics;
  JobStore* jobs;                     //!< null when jobs are not enabled
  const std::atomic<bool>& stopping;  //!< stop() was called

  //! Every check that needs only the request line and headers, before the body is read
  //! (route, method, API key, framing, type, length, parameters, a full house), in that
  //! order; nullopt when the request may proceed, with what was found in `checked`.
  std::optional<api::Problem> precheck(const HttpRequest& req, CheckedRequest& checked) const;
  //! The one check that can change while a body arrives: a full house (every compute slot
  //! taken, the job queue full, shutting down) on a route with a body.
  std::optional<api::Problem> check_capacity(const Route& route) const;
  bool authorized(const HttpRequest& req) const;
  //! The tenant that owns the jobs this request may see (JobStore::tenant_of its API key);
  //! empty without API keys.
  std::string tenant(const HttpRequest& req) const;

  //! 503: shutting down, or every compute slot taken.
  api::Problem busy_problem(bool is_stopping) const;
  //! 503 busy for want of memory (a request fits alone, not next to the running ones).
  api::Problem memory_busy_problem(std::uint64_t predicted) const;
  //! Fields a problem's status calls for (Retry-After, Allow, WWW-Authenticate).
  Fields problem_headers(const api::Problem& problem) const;
  //! Answers the problem: its status, those fields, the problem+json body.
  void respond(HttpAnswer& res, const api::Problem& problem) const;
};

//! The problem as the answer's status and problem+json body (no extra fields).
void send_problem(HttpAnswer& res, const api::Problem& problem);

}  // namespace stlrefine::server
