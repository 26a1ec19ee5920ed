// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The job routes: POST /v1/jobs (queue a refinement, 202 with its Location), GET / HEAD /
// DELETE /v1/jobs/{id} (its state; cancel) and GET / HEAD /v1/jobs/{id}/{file} (a result,
// sent from its file). The store and its runners are jobs.h.

#include "api/plan.h"
#include "server/http.h"
#include "server/route_context.h"

namespace stlrefine::server {

//! POST /v1/jobs with its body read; `parameters`: the plan RouteContext::precheck made
//! before the body, completed here with it and handed to the job store (whose runner uses
//! it). \pre ctx.jobs
void serve_job_submit(const RouteContext& ctx, const HttpRequest& req, api::RefinePlan parameters,
                      HttpAnswer& res);
//! GET /v1/jobs: the caller's jobs, newest first, `limit` (1..100, 20) at a time from
//! `cursor` (the `next` link of the page before), `state` filter. \pre ctx.jobs
void serve_job_list(const RouteContext& ctx, const HttpRequest& req, HttpAnswer& res);
//! GET /v1/jobs/{id}/events for a job `req`'s caller may see: server-sent events, one
//! `progress` event per change of state, progress or stage (the job's JSON), keep-alive
//! comments, and a final `end` event with the job's JSON when it has ended (or `timeout`
//! at the server's request deadline). \pre ctx.jobs
void serve_job_events(const RouteContext& ctx, const HttpRequest& req, const std::string& id,
                      HttpAnswer& res);
//! /v1/jobs/{id} and /v1/jobs/{id}/{file}. \pre ctx.jobs
void serve_job_item(const RouteContext& ctx, const HttpRequest& req, HttpAnswer& res);

}  // namespace stlrefine::server
