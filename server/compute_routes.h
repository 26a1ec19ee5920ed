// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The compute routes: POST /v1/refine, /v1/slice and /v1/info, answered while the client
// waits. Each is planned (api/plan.h), admitted (admission.h: a compute slot, the face
// budget, the memory budget), run with a cancel flag (the client hanging up, the deadline),
// and answered: the refined binary STL made piece by piece as it is sent, a refine + slice
// zip, contours, or the info report.

#include <memory>

#include "server/http.h"
#include "server/memory_budget.h"
#include "server/route_context.h"
#include "server/routes.h"

namespace stlrefine::server {

//! Answers `req` (its body read) on the compute route `checked.route`, whose parameters
//! RouteContext::precheck resolved. `fd`: the client's socket, watched for a hang-up (-1:
//! none); `reservation`: the body's memory (null: one is made), grown to the plan's predicted
//! peak before any work and shrunk to the answer once computed.
void serve_compute(const RouteContext& ctx, const HttpRequest& req, CheckedRequest checked, int fd,
                   std::shared_ptr<MemoryBudget::Reservation> reservation, HttpAnswer& res);

}  // namespace stlrefine::server
