// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefine_soak: the load test's soak variant (issue 8, item 4), run by hand. Starts
// stlrefined, has N clients refine a part for M minutes as tests/server/load_test.cpp does
// (same driver: Expect: 100-continue, Retry-After with jitter, /healthz probed every 20 ms,
// RSS and descriptors sampled every second), and prints one Markdown row per minute:
// requests, 200s, 503 share, latencies, /healthz p99, RSS and descriptors. At the end it
// compares the first and the last minute's RSS and descriptors (growth = a leak).
//
//   stlrefine_soak [--minutes 15] [--clients 64] [--slots 2] [--budget 256M]
//                  [--mesh examples/fandisk.stl] [--levels 2,2,2,3]

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "daemon_probe.h"
#include "load_driver.h"  // tests/server
#include "test_stl.h"     // tests/server

namespace {

using namespace stlrefine;
using namespace std::chrono_literals;

std::string load_averages() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a + " " + b + " " + c;
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

double mib(long long bytes) {
  return double(bytes) / (1 << 20);
}

template <class T>
std::vector<T> tail_from(const std::vector<T>& v, std::size_t from) {
  return std::vector<T>(v.begin() + static_cast<std::ptrdiff_t>(std::min(from, v.size())), v.end());
}

// Median RSS and the largest descriptor count of the samples in [t0, t1) seconds.
std::pair<double, std::size_t> window_memory(const std::vector<test::LoadSample>& samples,
                                             double t0, double t1) {
  std::vector<double> rss;
  std::size_t fds = 0;
  for (const auto& s : samples) {
    if (s.seconds < t0 || s.seconds >= t1) continue;
    rss.push_back(double(s.rss_bytes));
    fds = std::max(fds, s.fds);
  }
  return {test::percentile(rss, 50), fds};
}

}  // namespace

int main(int argc, char** argv) {
  double minutes = 15;
  int clients = 64;
  std::string slots = "2", budget = "256M";
  std::string mesh = std::string(STLREFINE_EXAMPLES_DIR) + "/fandisk.stl";
  std::string levels = "2,2,2,3";
  std::string daemon = STLREFINED;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--minutes") minutes = std::stod(argv[i + 1]);
    if (a == "--clients") clients = std::stoi(argv[i + 1]);
    if (a == "--slots") slots = argv[i + 1];
    if (a == "--budget") budget = argv[i + 1];
    if (a == "--mesh") mesh = argv[i + 1];
    if (a == "--levels") levels = argv[i + 1];
    if (a == "--daemon") daemon = argv[i + 1];
  }
  const std::string body = bench::read_input(mesh);
  if (body.size() < 84) {
    std::cerr << "cannot read " << mesh << "\n";
    return 1;
  }
  bench::DaemonProbe d(daemon, {"--compute-slots", slots, "--threads", "8", "--memory-budget",
                                budget, "--data-dir", "", "--max-connections", "512"});
  test::exchange(d.port(), test::post_text("/v1/refine?levels=1", "model/stl", body), 120s);
  std::this_thread::sleep_for(500ms);

  test::LoadOptions options;
  options.port = d.port();
  options.pid = d.pid();
  options.clients = clients;
  options.duration = std::chrono::milliseconds(static_cast<long long>(minutes * 60000));
  options.sample_period = 1s;
  options.report_period = 60s;
  std::stringstream list(levels);
  for (std::string l; std::getline(list, l, ',');)
    options.requests.push_back({"/v1/refine?levels=" + l, body, {}});

  std::cout << "## stlrefine_soak, " << utc_now() << "\n\n"
            << clients << " clients, " << slots << " compute slots, --memory-budget " << budget
            << ", " << mesh << " at levels " << levels << ", " << minutes
            << " minutes. Load average before: " << load_averages() << "\n\n"
            << "| minute | requests | 200 | 503 share | 200 p50 ms | 200 p99 ms | "
               "/healthz p99 ms | RSS MiB (median) | RSS MiB (max) | fds (max) | socket "
               "errors | load avg |\n"
            << "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n"
            << std::flush;
  std::size_t ok_from = 0, busy_from = 0, probes_from = 0, samples_from = 0;
  std::uint64_t requests_before = 0, ok_before = 0, busy_before = 0;
  int minute = 0;
  auto row = [&](const test::LoadReport& r) {
    ++minute;
    const auto ok_ms = tail_from(r.ok_ms, ok_from);
    const auto probes = tail_from(r.healthz_ms, probes_from);
    const auto samples = tail_from(r.samples, samples_from);
    const std::uint64_t requests = r.requests - requests_before;
    const std::uint64_t ok = r.ok - ok_before, busy = r.busy - busy_before;
    std::vector<double> rss;
    long long rss_max = 0;
    std::size_t fds = 0;
    for (const auto& s : samples) {
      rss.push_back(double(s.rss_bytes));
      rss_max = std::max(rss_max, s.rss_bytes);
      fds = std::max(fds, s.fds);
    }
    char line[512];
    std::snprintf(
        line, sizeof line,
        "| %d | %llu | %llu | %.1f %% | %.0f | %.0f | %.1f | %.1f | %.1f | %zu | %llu | "
        "%s |\n",
        minute, static_cast<unsigned long long>(requests), static_cast<unsigned long long>(ok),
        100.0 * double(busy) / double(std::max<std::uint64_t>(1, requests)),
        test::percentile(ok_ms, 50), test::percentile(ok_ms, 99), test::percentile(probes, 99),
        mib(static_cast<long long>(test::percentile(rss, 50))), mib(rss_max), fds,
        static_cast<unsigned long long>(r.socket_errors), load_averages().c_str());
    std::cout << line << std::flush;
    ok_from = r.ok_ms.size();
    busy_from = r.busy_ms.size();
    probes_from = r.healthz_ms.size();
    samples_from = r.samples.size();
    requests_before = r.requests;
    ok_before = r.ok;
    busy_before = r.busy;
  };
  const test::LoadReport r = test::run_load(options, row);
  (void)busy_from;

  const auto [rss_first, fds_first] = window_memory(r.samples, 0, 60);
  const auto [rss_last, fds_last] = window_memory(r.samples, r.seconds - 60, r.seconds + 1);
  std::this_thread::sleep_for(3s);  // lingering closes
  const std::size_t fds_after = d.open_fds();
  std::printf(
      "\nTotal: %llu requests in %.0f s, %llu x 200, %llu x 503 (%.1f %%), %llu socket errors, "
      "%llu other; 200 latency p50 %.0f ms, p99 %.0f ms; /healthz %zu probes, p50 %.2f ms, p99 "
      "%.1f ms, %llu failed; daemon CPU %.0f s (%.2f cores).\n",
      static_cast<unsigned long long>(r.requests), r.seconds, static_cast<unsigned long long>(r.ok),
      static_cast<unsigned long long>(r.busy),
      100.0 * double(r.busy) / double(std::max<std::uint64_t>(1, r.requests)),
      static_cast<unsigned long long>(r.socket_errors),
      static_cast<unsigned long long>(r.requests - r.ok - r.busy - r.socket_errors),
      test::percentile(r.ok_ms, 50), test::percentile(r.ok_ms, 99), r.healthz_ms.size(),
      test::percentile(r.healthz_ms, 50), test::percentile(r.healthz_ms, 99),
      static_cast<unsigned long long>(r.healthz_failures), r.daemon_cpu_seconds,
      r.daemon_cpu_seconds / r.seconds);
  std::printf(
      "Memory: median RSS %.1f MiB in the first minute, %.1f MiB in the last; peak %.1f MiB "
      "(VmHWM). Descriptors: at most %zu in the first minute, %zu in the last, %zu after the "
      "run. Load average after: %s\n",
      mib(static_cast<long long>(rss_first)), mib(static_cast<long long>(rss_last)),
      mib(r.max_rss_bytes), fds_first, fds_last, fds_after, load_averages().c_str());
  for (const auto& [kind, n] : r.busy_kinds)
    std::printf("503 %s: %llu\n", kind.c_str(), static_cast<unsigned long long>(n));
  for (const std::string& e : r.error_examples) std::printf("error: %s\n", e.c_str());
  return r.socket_errors == 0 ? 0 : 1;
}
