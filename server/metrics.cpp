// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/metrics.h"

#include <algorithm>
#include <cstdio>
#include <iterator>
#include <sstream>
#include <string_view>

#include "core/schemes/registry.h"

namespace stlrefine::server {

namespace {

void observe(std::array<std::uint64_t, 10>& le, std::uint64_t& count, double& sum,
             const std::array<double, 10>& buckets, double value) {
  for (std::size_t i = 0; i < buckets.size(); ++i) le[i] += value <= buckets[i];
  ++count;
  sum += value;
}

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", v);
  return text;
}

// Label values come from fixed sets (see the metric_* functions); escape anyway.
std::string label(const std::string& v) {
  std::string out;
  for (char c : v) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out;
}

constexpr std::string_view kFixedRoutes[] = {
    "/",           "/healthz",   "/readyz",   "/metrics", "/v1/openapi.json",
    "/v1/version", "/v1/refine", "/v1/slice", "/v1/info", "/v1/jobs"};
// What route_label returns besides the fixed routes.
constexpr std::string_view kRouteTemplates[] = {"/v1/jobs/{id}", "/v1/jobs/{id}/{file}",
                                                "/assets/{file}", "other"};

template <class Range>
bool one_of(const Range& range, std::string_view value) {
  return std::find(std::begin(range), std::end(range), value) != std::end(range);
}

// A route label as passed in, or the label of a raw path: never a new value.
std::string bounded_route(const std::string& route) {
  if (one_of(kRouteTemplates, route)) return route;
  return route_label(route);
}

}  // namespace

std::string route_label(const std::string& path) {
  if (one_of(kFixedRoutes, path)) return path;
  const std::string prefix = "/v1/jobs/";
  if (path.rfind(prefix, 0) == 0) {
    const std::string rest = path.substr(prefix.size());
    return rest.find('/') == std::string::npos ? "/v1/jobs/{id}" : "/v1/jobs/{id}/{file}";
  }
  if (path.rfind("/assets/", 0) == 0) return "/assets/{file}";
  return "other";
}

std::string metric_method(const std::string& method) {
  static constexpr std::string_view kMethods[] = {"GET", "HEAD", "POST", "DELETE", "OPTIONS"};
  return one_of(kMethods, method) ? method : "other";
}

std::string metric_status(int status) {
  return status >= 100 && status <= 599 ? std::to_string(status) : "other";
}

std::string metric_scheme(const std::string& scheme) {
  return one_of(scheme_names(), scheme) ? scheme : "other";
}

std::string metric_outcome(const std::string& outcome) {
  static constexpr std::string_view kOutcomes[] = {"queued", "running", "done", "failed",
                                                   "cancelled"};
  return one_of(kOutcomes, outcome) ? outcome : "other";
}

void Metrics::request(const std::string& route, const std::string& method, int status,
                      double seconds) {
  const std::string route_value = bounded_route(route);
  std::lock_guard lock(mutex_);
  ++requests_[{route_value, metric_method(method), metric_status(status)}];
  Histogram& h = request_seconds_[route_value];
  observe(h.le, h.count, h.sum, kBuckets, seconds);
}

void Metrics::refinement(const std::string& scheme, const std::string& outcome, double seconds,
                         std::uint64_t faces_in, std::uint64_t faces_out) {
  std::lock_guard lock(mutex_);
  Histogram& h = refine_[{metric_scheme(scheme), metric_outcome(outcome)}];
  observe(h.le, h.count, h.sum, kBuckets, seconds);
  faces_in_ += faces_in;
  faces_out_ += faces_out;
}

std::string Metrics::render(const Gauges& g) const {
  std::lock_guard lock(mutex_);
  std::ostringstream out;
  out << "# HELP stlrefine_http_requests_total HTTP requests answered, by route, method and "
         "status.\n# TYPE stlrefine_http_requests_total counter\n";
  for (const auto& [key, n] : requests_) {
    const auto& [route, method, status] = key;
    out << "stlrefine_http_requests_total{route=\"" << label(route) << "\",method=\""
        << label(method) << "\",status=\"" << label(status) << "\"} " << n << "\n";
  }
  auto histogram = [&](const std::string& name, const std::string& labels, const Histogram& h) {
    for (std::size_t i = 0; i < kBuckets.size(); ++i)
      out << name << "_bucket{" << labels << ",le=\"" << number(kBuckets[i]) << "\"} " << h.le[i]
          << "\n";
    out << name << "_bucket{" << labels << ",le=\"+Inf\"} " << h.count << "\n";
    out << name << "_sum{" << labels << "} " << number(h.sum) << "\n";
    out << name << "_count{" << labels << "} " << h.count << "\n";
  };
  out << "# HELP stlrefine_http_request_duration_seconds Time from headers read to response "
         "written, by route.\n# TYPE stlrefine_http_request_duration_seconds histogram\n";
  for (const auto& [route, h] : request_seconds_)
    histogram("stlrefine_http_request_duration_seconds", "route=\"" + label(route) + "\"", h);
  out << "# HELP stlrefine_refine_duration_seconds Refinement time (synchronous and jobs), by "
         "scheme and outcome.\n# TYPE stlrefine_refine_duration_seconds histogram\n";
  for (const auto& [key, h] : refine_)
    histogram("stlrefine_refine_duration_seconds",
              "scheme=\"" + label(key.first) + "\",outcome=\"" + label(key.second) + "\"", h);
  out << "# HELP stlrefine_triangles_in_total Input triangles of finished refinements.\n"
         "# TYPE stlrefine_triangles_in_total counter\nstlrefine_triangles_in_total "
      << faces_in_ << "\n";
  out << "# HELP stlrefine_triangles_out_total Output triangles of finished refinements.\n"
         "# TYPE stlrefine_triangles_out_total counter\nstlrefine_triangles_out_total "
      << faces_out_ << "\n";
  out << "# HELP stlrefine_jobs_queued Jobs waiting for a compute slot.\n"
         "# TYPE stlrefine_jobs_queued gauge\nstlrefine_jobs_queued "
      << g.jobs_queued << "\n";
  out << "# HELP stlrefine_jobs_running Jobs running.\n"
         "# TYPE stlrefine_jobs_running gauge\nstlrefine_jobs_running "
      << g.jobs_running << "\n";
  if (g.queue) {
    // Queue mode: what autoscaling reads (depth and pending are every replica's; the same
    // on each replica), and this replica's own counts.
    const Metrics::QueueGauges& q = *g.queue;
    out << "# HELP stlrefine_queue_up Whether the last look at the job queue (Redis) "
           "succeeded.\n# TYPE stlrefine_queue_up gauge\nstlrefine_queue_up "
        << (q.up ? 1 : 0) << "\n";
    out << "# HELP stlrefine_queue_depth Jobs in the shared queue no runner has taken yet.\n"
           "# TYPE stlrefine_queue_depth gauge\nstlrefine_queue_depth "
        << q.depth << "\n";
    out << "# HELP stlrefine_queue_pending_entries Jobs taken by a runner and not finished "
           "(running, or whose runner died).\n# TYPE stlrefine_queue_pending_entries gauge\n"
           "stlrefine_queue_pending_entries "
        << q.pending << "\n";
    out << "# HELP stlrefine_queue_reclaims_total Jobs this replica took over from a silent "
           "runner.\n# TYPE stlrefine_queue_reclaims_total counter\n"
           "stlrefine_queue_reclaims_total "
        << q.reclaims << "\n";
    out << "# HELP stlrefine_queue_attempts_total Job runs this replica started (first runs "
           "and re-runs).\n# TYPE stlrefine_queue_attempts_total counter\n"
           "stlrefine_queue_attempts_total "
        << q.attempts << "\n";
  }
  out << "# HELP stlrefine_compute_slots Compute slots configured.\n"
         "# TYPE stlrefine_compute_slots gauge\nstlrefine_compute_slots "
      << g.compute_slots << "\n";
  out << "# HELP stlrefine_compute_slots_free Compute slots free.\n"
         "# TYPE stlrefine_compute_slots_free gauge\nstlrefine_compute_slots_free "
      << g.compute_slots_free << "\n";
  out << "# HELP stlrefine_memory_budget_bytes Memory the daemon may use (--memory-budget).\n"
         "# TYPE stlrefine_memory_budget_bytes gauge\nstlrefine_memory_budget_bytes "
      << g.memory_budget_bytes << "\n";
  out << "# HELP stlrefine_memory_reserved_bytes Predicted peak memory reserved by requests "
         "computing or answering now.\n"
         "# TYPE stlrefine_memory_reserved_bytes gauge\nstlrefine_memory_reserved_bytes "
      << g.memory_reserved_bytes << "\n";
  return out.str();
}

}  // namespace stlrefine::server
