// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The load test (issue 8, item 4): 64 clients refine fandisk (12,946 faces) against a real
// stlrefined on loopback for 20 s, three requests in four at 2 levels and one at 3, with
// two compute slots and a 256 MiB memory budget, so both the slots and the memory run out.
// Every answer must be complete (0 socket errors), overload must be answered only with 503
// (+ Retry-After), every 200 must be the whole refined part, /healthz (probed every 20 ms
// meanwhile) must answer within 20 ms at the 99th percentile, and the daemon's RSS must
// stay within the budget. Afterwards its descriptors and memory reservations are back.
//
// Its own binary and ctest label: ctest -L load (RUN_SERIAL: nothing else runs beside it).
// The figures go to stdout as [load] lines. The soak variant is
// bench/reliability/soak.cpp.

#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

#include "http_test_client.h"
#include "load_driver.h"
#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

constexpr long long kBudget = 256ll << 20;
constexpr std::uint64_t kFandiskFaces = 12946;

std::function<bool(const RawResponse&)> refined_faces(std::uint64_t faces) {
  return [faces](const RawResponse& r) {
    return r.body.size() == 84 + 50 * faces && r.header("content-type") == "model/stl";
  };
}

// Share of all cores' time that was idle (idle + iowait in /proc/stat) over `span`.
double cpu_idle_fraction(std::chrono::milliseconds span) {
  auto read = [](double& idle, double& total) {
    std::ifstream in("/proc/stat");
    std::string cpu;
    in >> cpu;
    double v[8] = {};
    for (double& x : v) in >> x;
    idle = v[3] + v[4];
    total = 0;
    for (double x : v) total += x;
  };
  double idle0, total0, idle1, total1;
  read(idle0, total0);
  std::this_thread::sleep_for(span);
  read(idle1, total1);
  return total1 > total0 ? (idle1 - idle0) / (total1 - total0) : 1.0;
}

double mib(long long bytes) {
  return double(bytes) / (1 << 20);
}

TEST(Load, SixtyFourClientsGetCompleteAnswersOr503WithinTheMemoryBudget) {
  std::signal(SIGPIPE, SIG_IGN);
  const std::string fandisk = read_file(fs::path(STLREFINE_EXAMPLES_DIR) / "fandisk.stl");
  ASSERT_EQ(fandisk.size(), 84 + 50 * kFandiskFaces);
  Child daemon({STLREFINED, "--port", "0", "--compute-slots", "2", "--threads", "8",
                "--memory-budget", std::to_string(kBudget), "--data-dir", "", "--max-connections",
                "512", "--request-deadline", "120"});
  std::smatch m;
  const std::string line = daemon.read_line(10s);
  ASSERT_TRUE(
      std::regex_match(line, m, std::regex(R"(^listening on http://127\.0\.0\.1:([0-9]+)$)")))
      << line << daemon.stderr_text();
  const int port = std::stoi(m[1]);
  std::printf("[load] stlrefined pid %d on port %d\n", int(daemon.pid()), port);
  std::fflush(stdout);
  // One request first: code pages and the thread pool, so the baseline is the warm daemon.
  const auto first =
      parse_responses(exchange(port, post_text("/v1/refine?levels=2", "model/stl", fandisk), 60s));
  ASSERT_EQ(first.size(), 1u);
  ASSERT_EQ(first[0].status, 200);
  std::this_thread::sleep_for(300ms);
  const std::size_t fds_before = proc_open_fds(daemon.pid());

  // Is the machine ours? Other work keeping the cores busy (a shared development machine)
  // delays every thread's wakeups by tens of milliseconds, the daemon's event loop's too.
  const double idle_share = cpu_idle_fraction(1s);
  std::printf("[load] cores idle before the run: %.0f %%\n", 100 * idle_share);
  // The machine's own noise: the same probes against the idle daemon first.
  LoadOptions idle;
  idle.port = port;
  idle.pid = daemon.pid();
  idle.clients = 0;
  idle.duration = 3s;
  const LoadReport quiet = run_load(idle);
  std::printf("[load] idle /healthz: %zu probes, p50 %.2f ms, p99 %.2f ms, max %.2f ms\n",
              quiet.healthz_ms.size(), percentile(quiet.healthz_ms, 50),
              percentile(quiet.healthz_ms, 99), percentile(quiet.healthz_ms, 100));

  LoadOptions options;
  options.port = port;
  options.pid = daemon.pid();
  options.clients = 64;
  options.duration = 20s;
  const LoadRequest two{"/v1/refine?levels=2", fandisk, refined_faces(kFandiskFaces * 16)};
  const LoadRequest three{"/v1/refine?levels=3", fandisk, refined_faces(kFandiskFaces * 64)};
  options.requests = {two, two, two, three};
  const LoadReport r = run_load(options);

  const double p50 = percentile(r.healthz_ms, 50), p99 = percentile(r.healthz_ms, 99);
  std::printf(
      "[load] %.1f s, %d clients: %llu requests, %llu x 200, %llu x 503 (%.1f %%), "
      "%llu socket errors; 200 latency p50 %.0f ms p99 %.0f ms; 503 p50 %.1f ms\n",
      r.seconds, options.clients, static_cast<unsigned long long>(r.requests),
      static_cast<unsigned long long>(r.ok), static_cast<unsigned long long>(r.busy),
      100.0 * double(r.busy) / double(std::max<std::uint64_t>(1, r.requests)),
      static_cast<unsigned long long>(r.socket_errors), percentile(r.ok_ms, 50),
      percentile(r.ok_ms, 99), percentile(r.busy_ms, 50));
  for (const auto& [kind, n] : r.busy_kinds)
    std::printf("[load] 503 %s: %llu\n", kind.c_str(), static_cast<unsigned long long>(n));
  std::printf("[load] /healthz: %zu probes, p50 %.2f ms, p99 %.2f ms, max %.2f ms, %llu failed\n",
              r.healthz_ms.size(), p50, p99, percentile(r.healthz_ms, 100),
              static_cast<unsigned long long>(r.healthz_failures));
  std::printf(
      "[load] daemon: peak RSS %.1f MiB of a %.0f MiB budget, CPU %.1f s in %.1f s "
      "(%.2f cores); descriptors %zu before\n",
      mib(r.max_rss_bytes), mib(kBudget), r.daemon_cpu_seconds, r.seconds,
      r.daemon_cpu_seconds / r.seconds, fds_before);
  std::ifstream loadavg("/proc/loadavg");
  std::string load;
  std::getline(loadavg, load);
  std::printf("[load] load average after: %s\n", load.c_str());

  EXPECT_EQ(r.socket_errors, 0u);
  for (const std::string& e : r.error_examples) ADD_FAILURE() << e;
  for (const auto& [status, n] : r.by_status)
    EXPECT_TRUE(status == 200 || status == 503) << n << " answers with status " << status;
  EXPECT_EQ(r.bad_body, 0u);
  EXPECT_EQ(r.busy_without_retry_after, 0u);
  for (const auto& [kind, n] : r.busy_kinds)
    EXPECT_TRUE(kind.rfind("urn:stlrefine:problem:busy", 0) == 0 ||
                kind.rfind("urn:stlrefine:problem:overloaded", 0) == 0)
        << kind;
  // Saturated: more asked than two slots could take, and real work done.
  EXPECT_GT(r.busy, 0u);
  EXPECT_GE(r.ok, 10u);
  // The 20 ms bound holds the daemon to account when the cores are its own; when other work
  // already kept them busy, the figure is reported (and recorded) but not judged.
  if (idle_share >= 0.5)
    EXPECT_LT(p99, 20.0) << "ms at the 99th percentile of " << r.healthz_ms.size() << " probes";
  else
    std::printf("[load] /healthz bound not judged: only %.0f %% of the cores were idle before\n",
                100 * idle_share);
  EXPECT_EQ(r.healthz_failures, 0u);
  EXPECT_LE(r.max_rss_bytes, kBudget) << "peak RSS " << mib(r.max_rss_bytes) << " MiB";

  // Afterwards: every descriptor and every reservation is given back.
  std::size_t fds = proc_open_fds(daemon.pid());
  for (int i = 0; i < 100 && fds > fds_before; ++i) {
    std::this_thread::sleep_for(50ms);
    fds = proc_open_fds(daemon.pid());
  }
  EXPECT_LE(fds, fds_before);
  const auto metrics = parse_responses(exchange(port, "GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n"));
  ASSERT_EQ(metrics.size(), 1u);
  EXPECT_NE(metrics[0].body.find("\nstlrefine_memory_reserved_bytes 0\n"), std::string::npos)
      << metrics[0].body;
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(30s), 0) << daemon.stderr_text();
}

}  // namespace
}  // namespace stlrefine::test
