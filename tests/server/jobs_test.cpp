// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Asynchronous jobs, metrics, request ids, API keys and the OpenAPI document, against the
// daemon in process on an ephemeral loopback port.

#include <gtest/gtest.h>
#include <httplib.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>

#include "api/params.h"
#include "in_process_daemon.h"
#include "server/daemon.h"
#include "test_stl.h"

namespace stlrefine::server {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using Json = nlohmann::json;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("stlrefine-jobs-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

DaemonConfig jobs_config(const fs::path& dir) {
  DaemonConfig config;
  config.compute_slots = 2;
  config.http_threads = 8;
  config.max_faces = 2'000'000;
  config.jobs.data_dir = dir;
  config.jobs.max_queued = 2;
  config.shutdown_grace = 5s;
  return config;
}

const std::string& octahedron() {
  static const std::string bytes = test::binary_stl(test::octahedron_triangles());
  return bytes;
}

httplib::Result post(httplib::Client& c, const std::string& target, const std::string& body,
                     const httplib::Headers& headers = {}) {
  return c.Post(target.c_str(), headers, body, "model/stl");
}

Json wait_for_state(httplib::Client& c, const std::string& location,
                    const std::set<std::string>& states, std::chrono::seconds timeout = 30s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  Json job;
  while (std::chrono::steady_clock::now() < deadline) {
    auto r = c.Get(location.c_str());
    if (r && (r->status == 200 || r->status == 410)) {
      job = Json::parse(r->body);
      if (states.count(job["state"].get<std::string>())) return job;
    }
    std::this_thread::sleep_for(20ms);
  }
  ADD_FAILURE() << "job " << location << " did not reach the state; last: " << job.dump();
  return job;
}

TEST(Jobs, SubmitPollAndDownloadGiveTheSynchronousBytes) {
  const fs::path dir = fresh_dir("submit");
  test::InProcessDaemon d(jobs_config(dir));
  httplib::Client c = d.client();
  const std::string query = "scheme=butterfly&levels=2&slice=0.25&slice_format=json";
  auto sync = post(c, "/v1/refine?scheme=butterfly&levels=2", octahedron());
  ASSERT_TRUE(sync);
  ASSERT_EQ(sync->status, 200);

  auto submitted = post(c, "/v1/jobs?" + query, octahedron());
  ASSERT_TRUE(submitted);
  ASSERT_EQ(submitted->status, 202) << submitted->body;
  const std::string location = submitted->get_header_value("Location");
  ASSERT_EQ(location.rfind("/v1/jobs/", 0), 0u);
  EXPECT_FALSE(submitted->get_header_value("X-Request-Id").empty());
  const Json queued = Json::parse(submitted->body);
  EXPECT_EQ(queued["parameters"], query);

  const Json done = wait_for_state(c, location, {"done", "failed"});
  ASSERT_EQ(done["state"], "done") << done.dump();
  EXPECT_EQ(done["progress"], 1.0);
  EXPECT_EQ(done["report"]["output"]["faces"], 8 * 16);
  EXPECT_TRUE(done["timings"].contains("run_seconds"));
  EXPECT_EQ(done["links"]["result"], location + "/result.stl");
  EXPECT_EQ(done["links"]["contours"], location + "/contours.json");

  auto stl = c.Get((location + "/result.stl").c_str());
  ASSERT_TRUE(stl);
  EXPECT_EQ(stl->status, 200);
  EXPECT_TRUE(stl->body == sync->body) << "job and synchronous refine differ";
  auto contours = c.Get((location + "/contours.json").c_str());
  ASSERT_TRUE(contours);
  EXPECT_EQ(contours->status, 200);
  EXPECT_FALSE(Json::parse(contours->body)["layers"].empty());
  auto report = c.Get((location + "/report.json").c_str());
  ASSERT_TRUE(report);
  EXPECT_EQ(Json::parse(report->body)["scheme"], "butterfly");
  auto svg = c.Get((location + "/contours.svg").c_str());
  ASSERT_TRUE(svg);
  EXPECT_EQ(svg->status, 404);  // asked for json contours only
  auto bogus = c.Get((location + "/../../etc/passwd").c_str());
  ASSERT_TRUE(bogus);
  EXPECT_EQ(bogus->status, 404);
  // No half-written files are ever left next to the results.
  for (const auto& e : fs::directory_iterator(dir / location.substr(9)))
    EXPECT_NE(e.path().filename().string().front(), '.') << e.path();
}

TEST(Jobs, QueuedJobsAnswer409AndCancelAndTheQueueIsBounded) {
  const fs::path dir = fresh_dir("queue");
  test::InProcessDaemon d(jobs_config(dir));
  httplib::Client c = d.client();
  // Hold every compute slot so jobs stay queued.
  auto a = d.daemon().compute_slots().try_acquire();
  auto b = d.daemon().compute_slots().try_acquire();
  ASSERT_TRUE(a && b);
  std::vector<std::string> locations;
  for (int i = 0; i < 2; ++i) {
    auto r = post(c, "/v1/jobs?scheme=lsf&levels=1", octahedron());
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 202);
    locations.push_back(r->get_header_value("Location"));
  }
  // Two are waiting (the runners each took one and wait for a slot) or queued: either way
  // nothing is done yet, so results are 409.
  auto early = c.Get((locations[0] + "/result.stl").c_str());
  ASSERT_TRUE(early);
  EXPECT_EQ(early->status, 409);
  EXPECT_EQ(Json::parse(early->body)["type"], "urn:stlrefine:problem:not-done");
  // Fill the queue: max_queued = 2 places beyond what the runners hold.
  int accepted = 0, refused = 0;
  for (int i = 0; i < 4; ++i) {
    auto r = post(c, "/v1/jobs?scheme=lsf&levels=1", octahedron());
    ASSERT_TRUE(r);
    if (r->status == 202) {
      ++accepted;
      locations.push_back(r->get_header_value("Location"));
    } else {
      ++refused;
      EXPECT_EQ(r->status, 503);
      EXPECT_FALSE(r->get_header_value("Retry-After").empty());
      EXPECT_EQ(Json::parse(r->body)["type"], "urn:stlrefine:problem:queue-full");
    }
  }
  EXPECT_GE(refused, 1);
  EXPECT_LE(accepted, 2);

  // Cancel the first; it never runs.
  auto del = c.Delete(locations[0].c_str());
  ASSERT_TRUE(del);
  EXPECT_EQ(del->status, 200);
  const Json cancelled = wait_for_state(c, locations[0], {"cancelled"}, 5s);
  EXPECT_EQ(cancelled["state"], "cancelled");
  a.reset();
  b.reset();
  for (std::size_t i = 1; i < locations.size(); ++i)
    EXPECT_EQ(wait_for_state(c, locations[i], {"done", "failed"})["state"], "done");
  auto after = c.Get((locations[0] + "/result.stl").c_str());
  ASSERT_TRUE(after);
  EXPECT_EQ(after->status, 409);  // cancelled, never done
}

TEST(Jobs, RunningJobIsCancelledWithinASecond) {
  const fs::path dir = fresh_dir("cancel");
  DaemonConfig config = jobs_config(dir);
  config.max_faces = 20'000'000;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  std::ifstream in(fs::path(STLREFINE_EXAMPLES_DIR) / "fandisk.stl", std::ios::binary);
  const std::string fandisk((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // 12.9k faces to 3.3M in four levels: a few seconds of work, cancelled in the middle.
  auto r = post(c, "/v1/jobs?scheme=butterfly&levels=4", fandisk);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string location = r->get_header_value("Location");
  const Json running = wait_for_state(c, location, {"running", "done"});
  ASSERT_EQ(running["state"], "running");
  std::this_thread::sleep_for(200ms);
  const auto t0 = std::chrono::steady_clock::now();
  auto del = c.Delete(location.c_str());
  ASSERT_TRUE(del);
  EXPECT_EQ(del->status, 200);
  const Json job = wait_for_state(c, location, {"cancelled", "done", "failed"}, 10s);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(job["state"], "cancelled") << job.dump();
  EXPECT_LT(seconds, 1.0);
  for (int i = 0; i < 100 && d.daemon().compute_slots().available() < 2; ++i)
    std::this_thread::sleep_for(10ms);
  EXPECT_EQ(d.daemon().compute_slots().available(), 2u);  // the slot is free again
  EXPECT_FALSE(fs::exists(dir / location.substr(9) / "result.stl"));
}

TEST(Jobs, FinishedJobsSurviveARestartAndInterruptedOnesAreReportedFailed) {
  const fs::path dir = fresh_dir("restart");
  std::string location, stl;
  {
    test::InProcessDaemon d(jobs_config(dir));
    httplib::Client c = d.client();
    auto r = post(c, "/v1/jobs?scheme=butterfly&levels=1", octahedron());
    ASSERT_TRUE(r);
    location = r->get_header_value("Location");
    ASSERT_EQ(wait_for_state(c, location, {"done", "failed"})["state"], "done");
    stl = c.Get((location + "/result.stl").c_str())->body;
  }
  // A job that was running when the daemon died (as a crash leaves it).
  const std::string lost = "0123456789abcdef0123456789abcdef";
  fs::create_directories(dir / lost);
  std::ofstream(dir / lost / "job.json")
      << R"({"id":")" << lost << R"(","state":"running","scheme":"lsf","created_ms":1})";
  test::InProcessDaemon d(jobs_config(dir));
  httplib::Client c = d.client();
  auto again = c.Get((location + "/result.stl").c_str());
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 200);
  EXPECT_TRUE(again->body == stl);
  auto interrupted = c.Get(("/v1/jobs/" + lost).c_str());
  ASSERT_TRUE(interrupted);
  const Json job = Json::parse(interrupted->body);
  EXPECT_EQ(job["state"], "failed");
  EXPECT_EQ(job["problem"]["type"], "urn:stlrefine:problem:interrupted");
}

TEST(Jobs, ReplicasSharingADataDirectoryAnswerForEachOthersJobs) {
  const fs::path dir = fresh_dir("replicas");
  DaemonConfig config_a = jobs_config(dir), config_b = jobs_config(dir);
  config_a.jobs.instance = "replica-a";
  config_b.jobs.instance = "replica-b";
  config_a.max_faces = 20'000'000;
  test::InProcessDaemon a(config_a), b(config_b);
  httplib::Client ca = a.client(), cb = b.client();
  auto r = post(ca, "/v1/jobs?scheme=butterfly&levels=1", octahedron());
  ASSERT_TRUE(r);
  const std::string location = r->get_header_value("Location");
  ASSERT_EQ(wait_for_state(cb, location, {"done", "failed"})["state"], "done");  // polled on b
  auto from_b = cb.Get((location + "/result.stl").c_str());
  auto from_a = ca.Get((location + "/result.stl").c_str());
  ASSERT_TRUE(from_a && from_b);
  EXPECT_EQ(from_b->status, 200);
  EXPECT_TRUE(from_a->body == from_b->body);

  // A long job on a, cancelled through b: a's runner sees the note at its next level.
  std::ifstream in(fs::path(STLREFINE_EXAMPLES_DIR) / "fandisk.stl", std::ios::binary);
  const std::string fandisk((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto long_job = post(ca, "/v1/jobs?scheme=butterfly&levels=4", fandisk);
  ASSERT_TRUE(long_job);
  ASSERT_EQ(long_job->status, 202);
  const std::string long_location = long_job->get_header_value("Location");
  ASSERT_EQ(wait_for_state(cb, long_location, {"running", "done"})["state"], "running");
  auto del = cb.Delete(long_location.c_str());
  ASSERT_TRUE(del);
  EXPECT_EQ(del->status, 200);
  EXPECT_EQ(wait_for_state(cb, long_location, {"cancelled", "done", "failed"}, 10s)["state"],
            "cancelled");
}

TEST(Jobs, ExpiredResultsAnswer410AndUnknownIds404) {
  const fs::path dir = fresh_dir("expire");
  DaemonConfig config = jobs_config(dir);
  config.jobs.retention = 1s;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto r = post(c, "/v1/jobs?scheme=butterfly&levels=1", octahedron());
  ASSERT_TRUE(r);
  const std::string location = r->get_header_value("Location");
  ASSERT_EQ(wait_for_state(c, location, {"done"})["state"], "done");
  std::this_thread::sleep_for(1100ms);
  d.daemon().jobs()->expire_now();
  auto gone = c.Get((location + "/result.stl").c_str());
  ASSERT_TRUE(gone);
  EXPECT_EQ(gone->status, 410);
  auto status = c.Get(location.c_str());
  ASSERT_TRUE(status);
  EXPECT_EQ(status->status, 410);
  EXPECT_FALSE(fs::exists(dir / location.substr(9) / "result.stl"));
  for (const char* unknown : {"/v1/jobs/ffffffffffffffffffffffffffffffff", "/v1/jobs/..%2Fetc",
                              "/v1/jobs/abc/result.stl"}) {
    auto u = c.Get(unknown);
    ASSERT_TRUE(u);
    EXPECT_EQ(u->status, 404) << unknown;
  }
}

TEST(Jobs, ShutdownFailsQueuedJobsWithAReason) {
  const fs::path dir = fresh_dir("shutdown");
  std::string location;
  {
    test::InProcessDaemon d(jobs_config(dir));
    httplib::Client c = d.client();
    auto a = d.daemon().compute_slots().try_acquire();
    auto b = d.daemon().compute_slots().try_acquire();
    for (int i = 0; i < 3; ++i) {
      auto r = post(c, "/v1/jobs?scheme=butterfly&levels=1", octahedron());
      ASSERT_TRUE(r);
      if (r->status == 202) location = r->get_header_value("Location");
    }
    a.reset();  // the runners now hold none; stop() fails what is still queued
    b.reset();
    d.stop();
  }
  const Json job = Json::parse(std::ifstream(dir / location.substr(9) / "job.json"));
  EXPECT_TRUE(job["state"] == "failed" || job["state"] == "done") << job.dump();
  if (job["state"] == "failed") {
    EXPECT_EQ(job["problem"]["type"], "urn:stlrefine:problem:shutting-down");
  }
}

TEST(Server, EveryAnswerHasARequestIdAndMetricsCountRoutes) {
  DaemonConfig config;
  config.compute_slots = 1;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto h = c.Get("/healthz", {{"X-Request-Id", "my-trace-42"}});
  ASSERT_TRUE(h);
  EXPECT_EQ(h->get_header_value("X-Request-Id"), "my-trace-42");
  auto bad = c.Get("/healthz", {{"X-Request-Id", std::string(200, 'x')}});
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->get_header_value("X-Request-Id").size(), 16u);  // replaced, not echoed
  auto missing = c.Get("/nope");
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 404);
  EXPECT_FALSE(missing->get_header_value("X-Request-Id").empty());
  auto refine = post(c, "/v1/refine?scheme=butterfly&levels=1", octahedron());
  ASSERT_TRUE(refine);
  EXPECT_FALSE(refine->get_header_value("X-Request-Id").empty());
  auto jobs = post(c, "/v1/jobs", octahedron());
  ASSERT_TRUE(jobs);
  EXPECT_EQ(jobs->status, 404);  // jobs not enabled without a data directory
  auto m = c.Get("/metrics");
  ASSERT_TRUE(m);
  EXPECT_EQ(m->status, 200);
  EXPECT_NE(
      m->body.find(R"(stlrefine_http_requests_total{route="/healthz",method="GET",status="200"})"),
      std::string::npos)
      << m->body;
  EXPECT_NE(m->body.find(R"(route="other",method="GET",status="404")"), std::string::npos);
  EXPECT_NE(m->body.find(
                R"(stlrefine_refine_duration_seconds_count{scheme="butterfly",outcome="done"} 1)"),
            std::string::npos);
  EXPECT_NE(m->body.find("stlrefine_triangles_out_total 32"), std::string::npos);
}

TEST(Server, ApiKeysAreRequiredExceptForProbes) {
  DaemonConfig config;
  config.compute_slots = 1;
  config.api_keys = {"0123456789abcdef-key-one", "fedcba9876543210-key-two"};
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto none = post(c, "/v1/refine?levels=1", octahedron());
  ASSERT_TRUE(none);
  EXPECT_EQ(none->status, 401);
  EXPECT_EQ(none->get_header_value("WWW-Authenticate"), "Bearer");
  auto wrong = post(c, "/v1/refine?levels=1", octahedron(),
                    {{"Authorization", "Bearer 0123456789abcdef-key-onX"}});
  ASSERT_TRUE(wrong);
  EXPECT_EQ(wrong->status, 401);
  auto right = post(c, "/v1/refine?levels=1", octahedron(),
                    {{"Authorization", "Bearer fedcba9876543210-key-two"}});
  ASSERT_TRUE(right);
  EXPECT_EQ(right->status, 200);
  auto health = c.Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  DaemonConfig weak;
  weak.api_keys = {"short"};
  EXPECT_THROW(Daemon{weak}, std::invalid_argument);
}

TEST(OpenApi, DocumentsExactlyTheServedRoutesAndParameters) {
  const Json doc = Json::parse(openapi_document());
  EXPECT_EQ(doc["openapi"], "3.0.3");
  std::set<std::string> served, documented;
  for (const RouteInfo& r : served_routes()) {
    served.insert(r.path);
    ASSERT_TRUE(doc["paths"].contains(r.path)) << r.path;
    // Every served method is documented (HEAD is implied by GET in OpenAPI).
    for (const char* m : {"GET", "POST", "DELETE"}) {
      std::string lower = m;
      for (char& ch : lower) ch = static_cast<char>(std::tolower(ch));
      const bool serves = r.methods.find(m) != std::string::npos;
      EXPECT_EQ(serves, doc["paths"][r.path].contains(lower)) << r.path << " " << m;
    }
  }
  for (const auto& [path, item] : doc["paths"].items()) documented.insert(path);
  EXPECT_EQ(served, documented);

  // Parameters: exactly the names api/ accepts, each with a description.
  const api::RequestLimits daemon_limits;
  auto names_of = [&](const std::string& path) {
    std::set<std::string> names;
    for (const Json& p : doc["paths"][path]["post"]["parameters"]) {
      names.insert(p["name"].get<std::string>());
      EXPECT_FALSE(p.value("description", "").empty()) << path << " " << p["name"];
    }
    return names;
  };
  auto as_set = [](const auto& list) {
    std::set<std::string> s;
    for (std::string_view n : list) s.insert(std::string(n));
    return s;
  };
  // A job's own: callback_url; a raw body's name: the Content-Disposition header.
  std::set<std::string> job_names = as_set(api::refine_param_names(daemon_limits));
  job_names.insert("callback_url");
  job_names.insert("Content-Disposition");
  job_names.insert("filename");
  EXPECT_EQ(names_of("/v1/jobs"), job_names);
  std::set<std::string> refine_names = as_set(api::refine_param_names(daemon_limits));
  refine_names.insert("Content-Disposition");
  refine_names.insert("filename");
  std::set<std::string> slice_names = as_set(api::slice_param_names(daemon_limits));
  slice_names.insert("Content-Disposition");
  slice_names.insert("filename");
  EXPECT_EQ(names_of("/v1/refine"), refine_names);
  EXPECT_EQ(names_of("/v1/slice"), slice_names);
  EXPECT_EQ(names_of("/v1/info"), as_set(api::info_param_names()));
}

TEST(OpenApi, IsServed) {
  DaemonConfig config;
  config.compute_slots = 1;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto r = c.Get("/v1/openapi.json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->body, openapi_document());
}

}  // namespace
}  // namespace stlrefine::server
