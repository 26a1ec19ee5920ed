// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include "subprocess.h"  // proc_cpu_seconds

// Drives a running stlrefined with many concurrent clients on loopback, probes /healthz and
// samples the daemon's RSS and descriptors meanwhile: the load test (tests/server) and the
// soak program (bench/reliability) share it.

#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "http_test_client.h"

namespace stlrefine::test {

//! One request a client may send.
struct LoadRequest {
  std::string target;  //!< "/v1/refine?levels=2"
  std::string body;    //!< the STL
  //! Checks a 200 answer (e.g. its size); empty = accept every 200.
  std::function<bool(const RawResponse&)> check;
};

struct LoadOptions {
  int port = 0;
  pid_t pid = 0;  //!< the daemon, for /proc/<pid>
  int clients = 64;
  std::chrono::milliseconds duration{20000};
  //! Client k's n-th request is requests[(k + n) % size]: a fixed mix.
  std::vector<LoadRequest> requests;
  //! After a 503 a client waits Retry-After times a random factor in [0.5, 1.5] (jitter,
  //! so 64 clients do not come back at once), or `backoff` without the header.
  std::chrono::milliseconds backoff{1000};
  //! Nice increment of the client threads: they stand for other machines, so on loopback
  //! they should not take the daemon's cores (the /healthz prober keeps its priority).
  int client_nice = 10;
  std::chrono::milliseconds probe_period{20};    //!< GET /healthz
  std::chrono::milliseconds sample_period{100};  //!< RSS and descriptors
  std::chrono::seconds request_timeout{60};
  //! Called about every `report_period` with the report so far (the soak prints it).
  std::chrono::milliseconds report_period{0};
};

struct LoadSample {
  double seconds = 0;  //!< since the start
  long long rss_bytes = 0;
  std::size_t fds = 0;
};

struct LoadReport {
  double seconds = 0;
  std::uint64_t requests = 0;  //!< answered or failed
  std::uint64_t ok = 0;        //!< 200 that passed its check
  std::uint64_t bad_body = 0;  //!< 200 that failed its check
  std::uint64_t busy = 0;      //!< 503
  std::uint64_t busy_without_retry_after = 0;
  std::uint64_t socket_errors = 0;  //!< no complete answer (connect, reset, truncation, timeout)
  std::map<int, std::uint64_t> by_status;
  std::map<std::string, std::uint64_t> busy_kinds;  //!< problem type (and reason) of 503s
  std::vector<std::string> error_examples;          //!< the first few socket errors
  std::vector<double> ok_ms, busy_ms;               //!< latencies by outcome
  std::vector<double> healthz_ms;
  std::uint64_t healthz_failures = 0;
  std::vector<LoadSample> samples;
  long long max_rss_bytes = 0;
  double daemon_cpu_seconds = 0;  //!< user + system time of the daemon during the run
};

//! Runs the load; returns when `duration` is over and every client has its last answer.
LoadReport run_load(const LoadOptions& options,
                    const std::function<void(const LoadReport&)>& progress = {});

//! The p-th percentile (0..100) of the samples, nearest rank; 0 when empty.
double percentile(std::vector<double> samples, double p);

//! /proc/<pid>/status "VmRSS" / "VmHWM" in bytes (-1 when unreadable).
long long proc_status_bytes(pid_t pid, const std::string& key);
//! Entries of /proc/<pid>/fd.
std::size_t proc_open_fds(pid_t pid);

}  // namespace stlrefine::test
