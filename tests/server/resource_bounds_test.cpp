// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Resource bounds (issue 8, item 5): the memory budget (422 for a request that can never
// fit, 503 or a waiting job when it does not fit next to running work) and the request
// deadline (504, jobs fail), against the daemon in process; the --memory-budget flag and its
// environment variable against the stlrefined binary. Memory "held by running work" is a
// reservation the test makes itself, so no row depends on how long a computation takes.

#include <gtest/gtest.h>
#include <httplib.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include "api/memory_model.h"
#include "api/params.h"
#include "in_process_daemon.h"
#include "server/daemon.h"
#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::server {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr std::uint64_t kMiB = std::uint64_t{1} << 20;

using test::read_file;

const std::string& fandisk() {
  static const std::string bytes = read_file(fs::path(STLREFINE_EXAMPLES_DIR) / "fandisk.stl");
  return bytes;
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("stlrefine-bounds-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

DaemonConfig config_with(std::uint64_t budget, const fs::path& jobs_dir = {}) {
  DaemonConfig config;
  config.compute_slots = 2;
  config.http_threads = 6;
  config.memory_budget = budget;
  config.jobs.data_dir = jobs_dir;
  return config;
}

httplib::Result post(httplib::Client& c, const std::string& target, const std::string& body) {
  return c.Post(target.c_str(), body, "model/stl");
}

Json problem_of(const httplib::Result& r, int status, const std::string& slug) {
  EXPECT_TRUE(r);
  if (!r) return {};
  EXPECT_EQ(r->status, status) << r->body;
  EXPECT_EQ(r->get_header_value("Content-Type"), "application/problem+json");
  const Json j = Json::parse(r->body);
  EXPECT_EQ(j.value("type", ""), "urn:stlrefine:problem:" + slug) << r->body;
  return j;
}

// The daemon's prediction for a refine query on fandisk.
std::uint64_t predicted_refine(const std::string& query,
                               api::ResultSink sink = api::ResultSink::Answer) {
  const auto bytes =
      std::span(reinterpret_cast<const std::uint8_t*>(fandisk().data()), fandisk().size());
  return api::estimate_refine_memory(
             bytes, api::stl_shape(bytes),
             api::parse_refine_params(api::parse_query(query), api::RequestLimits{}), sink)
      .peak_bytes;
}

// Reservations are given back when the connections close (after the answer is written).
bool wait_for_reserved(Daemon& d, std::uint64_t bytes, std::chrono::milliseconds timeout = 5s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (d.memory_budget().reserved() != bytes && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(5ms);
  return d.memory_budget().reserved() == bytes;
}

Json wait_for_job(httplib::Client& c, const std::string& location,
                  const std::function<bool(const Json&)>& done,
                  std::chrono::seconds timeout = 60s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  Json job;
  while (std::chrono::steady_clock::now() < deadline) {
    if (auto r = c.Get(location.c_str()); r && r->status == 200) {
      job = Json::parse(r->body);
      if (done(job)) return job;
    }
    std::this_thread::sleep_for(10ms);
  }
  ADD_FAILURE() << "job " << location << " never got there; last: " << job.dump();
  return job;
}

TEST(MemoryBudgetRoute, ARequestThatCanNeverFitIs422NamingTheParameter) {
  const fs::path dir = fresh_dir("never");
  test::InProcessDaemon d(config_with(256 * kMiB, dir));
  const std::uint64_t capacity = d.daemon().memory_budget().capacity();
  ASSERT_EQ(capacity, 256 * kMiB - kDaemonReserve);
  ASSERT_GT(predicted_refine("levels=4"), capacity);
  ASSERT_LT(predicted_refine("levels=2"), capacity);
  httplib::Client c = d.client();

  Json j = problem_of(post(c, "/v1/refine?levels=4", fandisk()), 422, "budget-exceeded");
  EXPECT_EQ(j.value("field", ""), "levels");
  EXPECT_EQ(j.value("title", ""), "Memory budget exceeded");
  EXPECT_EQ(j.value("reason", ""), "memory_budget");
  EXPECT_EQ(j.value("predicted_bytes", 0ull), predicted_refine("levels=4"));
  EXPECT_EQ(j.value("memory_budget_bytes", 0ull), capacity);
  // Nothing ran: no refinement was counted.
  auto metrics = c.Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_EQ(metrics->body.find("stlrefine_refine_duration_seconds_count"), std::string::npos)
      << metrics->body;

  // The adaptive mode reserves as its hierarchy grows (its worst case at max_level is not a
  // reason to refuse one that stays small) and stops at the level that would not fit,
  // naming its level cap.
  j = problem_of(post(c, "/v1/refine?scheme=butterfly&adaptive_tol=1e-9&max_level=8", fandisk()),
                 422, "budget-exceeded");
  EXPECT_EQ(j.value("field", ""), "max_level");
  EXPECT_EQ(j.value("reason", ""), "memory_budget");
  EXPECT_EQ(j.value("title", ""), "Memory budget exceeded");
  EXPECT_GT(j.value("predicted_bytes", 0ull), capacity);
  // A slice whose contours alone are too many for the budget names the layer height.
  j = problem_of(post(c, "/v1/slice?layer_height=0.0001", fandisk()), 422, "budget-exceeded");
  EXPECT_EQ(j.value("field", ""), "layer_height");
  // A job is refused at submission, not when its turn comes.
  j = problem_of(post(c, "/v1/jobs?levels=4", fandisk()), 422, "budget-exceeded");
  EXPECT_EQ(j.value("field", ""), "levels");
  // The face budget keeps its own 422 (and comes first).
  j = problem_of(post(c, "/v1/refine?levels=8", fandisk()), 422, "budget-exceeded");
  EXPECT_EQ(j.value("field", ""), "max_faces");

  // What fits is served, and every reservation is given back.
  auto ok = post(c, "/v1/refine?levels=2", fandisk());
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
  EXPECT_TRUE(wait_for_reserved(d.daemon(), 0));
  fs::remove_all(dir);
}

TEST(MemoryBudgetRoute, ARequestThatFitsOnlyAloneGets503WithRetryAfter) {
  test::InProcessDaemon d(config_with(512 * kMiB));
  MemoryBudget& budget = d.daemon().memory_budget();
  const std::uint64_t needed = predicted_refine("levels=2");
  ASSERT_LT(needed, budget.capacity());
  httplib::Client c = d.client();
  {
    // Running work holds all but a little less than the request needs.
    auto held = budget.try_reserve(budget.capacity() - needed + 1);
    ASSERT_TRUE(held);
    const Json j = problem_of(post(c, "/v1/refine?levels=2", fandisk()), 503, "busy");
    EXPECT_EQ(j.value("reason", ""), "memory");
    auto r = post(c, "/v1/refine?levels=2", fandisk());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->get_header_value("Retry-After"), "2");
    // With no room even for the body, the refusal comes before the upload.
    ASSERT_TRUE(wait_for_reserved(d.daemon(), held->bytes()));
    ASSERT_TRUE(held->grow_to(budget.capacity()));
    const Json before = problem_of(post(c, "/v1/refine?levels=2", fandisk()), 503, "busy");
    EXPECT_EQ(before.value("reason", ""), "memory");
    EXPECT_TRUE(wait_for_reserved(d.daemon(), budget.capacity()));
  }
  // The work ended: the same request is served.
  auto r = post(c, "/v1/refine?levels=2", fandisk());
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_TRUE(wait_for_reserved(d.daemon(), 0));
}

TEST(MemoryBudgetRoute, AJobWaitsForMemoryAndThenRuns) {
  const fs::path dir = fresh_dir("wait");
  test::InProcessDaemon d(config_with(512 * kMiB, dir));
  MemoryBudget& budget = d.daemon().memory_budget();
  httplib::Client c = d.client();
  // Room for the upload, not for the job.
  std::optional<MemoryBudget::Reservation> held =
      budget.try_reserve(budget.capacity() - fandisk().size());
  ASSERT_TRUE(held);
  ASSERT_LT(fandisk().size(), predicted_refine("levels=2", api::ResultSink::JobFiles));
  auto r = post(c, "/v1/jobs?levels=2", fandisk());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string location = r->get_header_value("Location");
  const Json waiting = wait_for_job(
      c, location, [](const Json& j) { return j.value("stage", "") == "waiting for memory"; });
  EXPECT_EQ(waiting.value("state", ""), "running");
  held.reset();
  const Json done = wait_for_job(c, location, [](const Json& j) {
    return j.value("state", "") != "running" && j.value("state", "") != "queued";
  });
  EXPECT_EQ(done.value("state", ""), "done") << done.dump();
  EXPECT_TRUE(wait_for_reserved(d.daemon(), 0));
  fs::remove_all(dir);
}

TEST(MemoryBudgetRoute, AJobUploadIsReservedToo) {
  const fs::path dir = fresh_dir("upload");
  test::InProcessDaemon d(config_with(256 * kMiB, dir));
  MemoryBudget& budget = d.daemon().memory_budget();
  httplib::Client c = d.client();
  {
    auto held = budget.try_reserve(budget.capacity() - fandisk().size() + 1);
    ASSERT_TRUE(held);
    const Json j = problem_of(post(c, "/v1/jobs?levels=1", fandisk()), 503, "busy");
    EXPECT_EQ(j.value("reason", ""), "memory");
  }
  auto r = post(c, "/v1/jobs?levels=1", fandisk());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202);
  const Json done = wait_for_job(c, r->get_header_value("Location"), [](const Json& j) {
    return j.value("state", "") != "running" && j.value("state", "") != "queued";
  });
  EXPECT_EQ(done.value("state", ""), "done");
  fs::remove_all(dir);
}

TEST(RequestDeadline, CancelsASynchronousRequestWith504) {
  DaemonConfig config = config_with(4096 * kMiB);
  config.request_deadline = 1ms;  // far below the seconds fandisk at 4 levels takes
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  const Json j = problem_of(post(c, "/v1/refine?levels=4", fandisk()), 504, "deadline-exceeded");
  EXPECT_EQ(j.value("reason", ""), "deadline_exceeded");
  EXPECT_EQ(j.value("deadline_seconds", 0.0), 0.001);
  EXPECT_NE(j.value("detail", "").find("deadline exceeded"), std::string::npos);
  // Its slot and memory are free again.
  EXPECT_TRUE(wait_for_reserved(d.daemon(), 0));
  for (int i = 0; i < 100 && d.daemon().compute_slots().available() < 2; ++i)
    std::this_thread::sleep_for(10ms);
  EXPECT_EQ(d.daemon().compute_slots().available(), 2u);
}

TEST(RequestDeadline, AJobEndsFailedWithDeadlineExceeded) {
  const fs::path dir = fresh_dir("deadline");
  DaemonConfig config = config_with(4096 * kMiB, dir);
  config.request_deadline = 1ms;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto r = post(c, "/v1/jobs?levels=4", fandisk());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const Json job = wait_for_job(c, r->get_header_value("Location"), [](const Json& j) {
    return j.value("state", "") != "running" && j.value("state", "") != "queued";
  });
  EXPECT_EQ(job.value("state", ""), "failed") << job.dump();
  ASSERT_TRUE(job.contains("problem"));
  EXPECT_EQ(job["problem"].value("type", ""), "urn:stlrefine:problem:deadline-exceeded");
  EXPECT_EQ(job["problem"].value("status", 0), 504);
  EXPECT_NE(job["problem"].value("detail", "").find("deadline exceeded"), std::string::npos);
  EXPECT_TRUE(wait_for_reserved(d.daemon(), 0));
  fs::remove_all(dir);
}

TEST(RequestDeadline, WorkWithinTheDeadlineIsUntouched) {
  DaemonConfig config = config_with(4096 * kMiB);
  config.request_deadline = 600s;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto r = post(c, "/v1/refine?levels=1", fandisk());
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
}

// --- the flag

int start(test::Child& child) {
  const std::string line = child.read_line(10s);
  std::smatch m;
  if (!std::regex_match(line, m, std::regex(R"(^listening on http://127\.0\.0\.1:([0-9]+)$)"))) {
    ADD_FAILURE() << "unexpected first line: '" << line << "'\n" << child.stderr_text();
    return 0;
  }
  return std::stoi(m[1]);
}

std::uint64_t metric(int port, const std::string& name) {
  httplib::Client c("127.0.0.1", port);
  auto r = c.Get("/metrics");
  if (!r) return 0;
  std::smatch m;
  if (!std::regex_search(r->body, m, std::regex("\n" + name + " ([0-9]+)\n"))) return 0;
  return std::stoull(m[1]);
}

TEST(MemoryBudgetFlag, TakesSuffixesAndTheEnvironment) {
  {
    test::Child child({STLREFINED, "--port", "0", "--memory-budget", "300M", "--data-dir", ""});
    const int port = start(child);
    EXPECT_EQ(metric(port, "stlrefine_memory_budget_bytes"), 300 * kMiB);
    child.signal(SIGTERM);
    EXPECT_EQ(child.wait(10s), 0);
  }
  {
    ::setenv("STLREFINED_MEMORY_BUDGET", "1.5G", 1);
    test::Child child({STLREFINED, "--port", "0", "--data-dir", ""});
    ::unsetenv("STLREFINED_MEMORY_BUDGET");
    const int port = start(child);
    EXPECT_EQ(metric(port, "stlrefine_memory_budget_bytes"), 1536 * kMiB);
    child.signal(SIGTERM);
    EXPECT_EQ(child.wait(10s), 0);
  }
  {
    test::Child child({STLREFINED, "--port", "0", "--data-dir", ""});
    const int port = start(child);
    EXPECT_EQ(metric(port, "stlrefine_memory_budget_bytes"), default_memory_budget());
    child.signal(SIGTERM);
    EXPECT_EQ(child.wait(10s), 0);
  }
  for (const char* bad : {"12X", "100M", "-1G", ""}) {
    const test::ProcessResult r =
        test::run_process({STLREFINED, "--port", "0", "--memory-budget", bad}, 10s);
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.err;
  }
  const test::ProcessResult r =
      test::run_process({STLREFINED, "--port", "0", "--request-deadline", "-1"}, 10s);
  EXPECT_EQ(r.exit_code, 2) << r.err;
}

}  // namespace
}  // namespace stlrefine::server
