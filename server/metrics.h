// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>

namespace stlrefine::server {

//! Counters and histograms for GET /metrics (Prometheus text format 0.0.4).
//! Every label value comes from a fixed set, whatever the callers pass, so no client can
//! grow the page (a series per random method or path would be unauthenticated memory):
//! routes are route_label()'s, methods metric_method()'s, statuses metric_status()'s,
//! schemes metric_scheme()'s and outcomes metric_outcome()'s; anything else is "other".
class Metrics {
 public:
  //! One answered request: route label ("/v1/jobs/{id}"; a raw path is labelled with
  //! route_label), method, status.
  void request(const std::string& route, const std::string& method, int status, double seconds);
  //! One finished refinement (synchronous or job): its duration and triangle counts.
  void refinement(const std::string& scheme, const std::string& outcome, double seconds,
                  std::uint64_t faces_in, std::uint64_t faces_out);

  //! Gauges are read at scrape time by the caller and passed in.
  //! Queue mode (--queue): the shared queue as this replica last saw it, and its own counts.
  struct QueueGauges {
    bool up = false;
    std::uint64_t depth = 0, pending = 0, reclaims = 0, attempts = 0;
  };
  struct Gauges {
    std::optional<QueueGauges> queue;
    std::size_t jobs_queued = 0, jobs_running = 0;
    std::size_t compute_slots = 0, compute_slots_free = 0;
    std::uint64_t memory_budget_bytes = 0, memory_reserved_bytes = 0;
  };
  std::string render(const Gauges& gauges) const;

 private:
  static constexpr std::array<double, 10> kBuckets = {0.01, 0.05, 0.1, 0.5, 1, 5, 10, 30, 60, 300};
  struct Histogram {
    std::array<std::uint64_t, kBuckets.size()> le{};
    std::uint64_t count = 0;
    double sum = 0;
  };
  mutable std::mutex mutex_;
  std::map<std::tuple<std::string, std::string, std::string>, std::uint64_t> requests_;
  std::map<std::string, Histogram> request_seconds_;                 // by route
  std::map<std::pair<std::string, std::string>, Histogram> refine_;  // scheme, outcome
  std::uint64_t faces_in_ = 0, faces_out_ = 0;
};

//! The route label of a request path: itself for fixed routes, "/v1/jobs/{id}" and
//! "/v1/jobs/{id}/{file}" for job URLs, "other" for anything unknown (bounded cardinality).
std::string route_label(const std::string& path);

//! The method label: GET, HEAD, POST, DELETE or OPTIONS as they are (methods are
//! case-sensitive), "other" for anything else.
std::string metric_method(const std::string& method);
//! The status label: the number for 100..599, "other" for anything else.
std::string metric_status(int status);
//! The scheme label: one of scheme_names(), "other" for anything else.
std::string metric_scheme(const std::string& scheme);
//! The outcome label: queued, running, done, failed or cancelled, "other" for anything else.
std::string metric_outcome(const std::string& outcome);

}  // namespace stlrefine::server
