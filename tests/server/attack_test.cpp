// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The attack suite of issue 16, against the real stlrefined binary on loopback: one test per
// reproduction in the issue (Range over-read, guessable ids and other tenants' jobs,
// truncating shutdown, slow uploads and readers, per-address floods, unbounded metrics, the
// empty request line). Each of them failed on the daemon before the fix.

#include <gtest/gtest.h>
#include <httplib.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "http_test_client.h"
#include "in_process_daemon.h"
#include "server/daemon.h"
#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using Json = nlohmann::json;

// Starts stlrefined on a free port; returns the port from its one stdout line.
int start(Child& child) {
  const int port = listening_port(child, 20s);
  if (port == 0) ADD_FAILURE() << "no `listening on` line\n" << child.stderr_text();
  return port;
}

// Without --data-dir in `flags`, jobs are off (no directory in the working directory).
std::vector<std::string> daemon_argv(std::vector<std::string> flags) {
  std::vector<std::string> argv = {STLREFINED, "--host", "127.0.0.1", "--port", "0"};
  if (std::find(flags.begin(), flags.end(), "--data-dir") == flags.end())
    flags.insert(flags.end(), {"--data-dir", ""});
  argv.insert(argv.end(), flags.begin(), flags.end());
  return argv;
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("stlrefine-attack-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

const std::string& fandisk() {
  static const std::string bytes = read_file(fs::path(STLREFINE_EXAMPLES_DIR) / "fandisk.stl");
  return bytes;
}

std::string get_text(std::string_view target, std::string_view extra = {}) {
  return "GET " + std::string(target) + " HTTP/1.1\r\nHost: x\r\n" + std::string(extra) + "\r\n";
}

RawResponse one_response(int port, const std::string& request,
                         std::chrono::milliseconds timeout = 20s) {
  const std::vector<RawResponse> all = parse_responses(test::exchange(port, request, timeout));
  if (all.size() != 1) {
    ADD_FAILURE() << all.size() << " responses to " << request.substr(0, 80);
    return {};
  }
  return all[0];
}

// ---------------------------------------------------------------------------------------
// 1. Range: no route returns a byte outside its body, in any form of the header.

const std::vector<std::string> kRanges = {"bytes=0-1048575",
                                          "bytes=0-200000",
                                          "bytes=0-1,5-9",
                                          "bytes=-500",
                                          "bytes=100-",
                                          "bytes=0-18446744073709551615",
                                          "bytes=18446744073709551615-",
                                          "bytes=0-99999999999999999999999",
                                          "bytes=-0",
                                          "bytes=5-2",
                                          "bytes=3-3",
                                          "items=0-10",
                                          "bytes=-18446744073709551616",
                                          "bytes= 0-9",
                                          "BYTES=0-9",
                                          "bytes=1-1,1-1,1-1"};

// `whole` is the body without Range. A 200 is the whole body, a 206 the slice its
// Content-Range names (inside the body), a 416 says the length: never anything more.
void expect_inside(const RawResponse& r, const std::string& whole, const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_TRUE(r.status == 200 || r.status == 206 || r.status == 416) << r.status;
  EXPECT_LE(r.body.size(), std::max<std::size_t>(whole.size(), 1024));
  if (r.status == 200) {
    EXPECT_EQ(r.body, whole);
    EXPECT_FALSE(r.has_header("content-range"));
  } else if (r.status == 206) {
    std::smatch m;
    const std::string range = r.header("content-range");
    ASSERT_TRUE(std::regex_match(range, m, std::regex(R"(bytes (\d+)-(\d+)/(\d+))"))) << range;
    const std::uint64_t first = std::stoull(m[1]), last = std::stoull(m[2]);
    EXPECT_EQ(std::stoull(m[3]), whole.size());
    ASSERT_LE(first, last);
    ASSERT_LT(last, whole.size());
    EXPECT_EQ(r.body, whole.substr(first, last - first + 1));
  } else {
    EXPECT_EQ(r.header("content-range"), "bytes */" + std::to_string(whole.size()));
    EXPECT_EQ(r.header("content-type"), "application/problem+json");
  }
}

TEST(Attack, RangeNeverReadsPastTheBodyOnAnyRoute) {
  const fs::path dir = fresh_dir("range");
  Child child(daemon_argv({"--data-dir", dir.string(), "--compute-slots", "1"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  const std::string tetra = binary_stl(octahedron_triangles());

  // Compute answers: 200 with the whole body whatever the Range says.
  for (const std::string& target :
       {std::string("/v1/refine?levels=0"), std::string("/v1/refine?levels=1"),
        std::string("/v1/slice?layer_height=0.25&format=json"), std::string("/v1/info")}) {
    for (const std::string& range : kRanges) {
      const RawResponse r =
          one_response(port, post_text(target, "model/stl", tetra, "Range: " + range + "\r\n"));
      SCOPED_TRACE(target + " " + range);
      EXPECT_EQ(r.status, 200) << r.body.substr(0, 300);
      EXPECT_FALSE(r.has_header("content-range"));
      EXPECT_EQ(std::to_string(r.body.size()), r.header("content-length"));
      if (target.starts_with("/v1/refine")) {
        EXPECT_EQ(r.body.size(), target.ends_with("=0") ? 84u + 50u * 8 : 84u + 50u * 32);
      }
    }
  }

  // A job's files and JSON, the page, its assets, the API document, metrics, probes.
  httplib::Client client("127.0.0.1", port);
  auto submitted = client.Post("/v1/jobs?levels=2", tetra, "model/stl");
  ASSERT_TRUE(submitted);
  ASSERT_EQ(submitted->status, 202) << submitted->body;
  const std::string location = submitted->get_header_value("Location");
  for (int i = 0; i < 200; ++i) {
    auto job = client.Get(location.c_str());
    if (job && Json::parse(job->body).value("state", "") == "done") break;
    std::this_thread::sleep_for(50ms);
  }
  std::vector<std::string> targets = {location + "/result.stl",
                                      location + "/report.json",
                                      "/",
                                      "/v1/openapi.json",
                                      "/healthz",
                                      "/readyz"};
  // An asset name from the page, when the page was built.
  const RawResponse page = one_response(port, get_text("/"));
  std::smatch asset;
  if (std::regex_search(page.body, asset, std::regex(R"((/assets/[A-Za-z0-9_.-]+))")))
    targets.push_back(asset[1]);
  for (const std::string& target : targets) {
    const RawResponse plain = one_response(port, get_text(target));
    if (target == "/" && plain.status == 404) continue;  // built without the page (no npm)
    ASSERT_EQ(plain.status, 200) << target;
    for (const std::string& range : kRanges) {
      const RawResponse r = one_response(port, get_text(target, "Range: " + range + "\r\n"));
      expect_inside(r, plain.body, target + " " + range);
    }
  }
  // The forms the issue names, on a download: exact answers.
  const std::string stl = one_response(port, get_text(location + "/result.stl")).body;
  ASSERT_EQ(stl.size(), 84u + 50u * 128);
  RawResponse r = one_response(port, get_text(location + "/result.stl", "Range: bytes=-500\r\n"));
  EXPECT_EQ(r.status, 206);
  EXPECT_EQ(r.body, stl.substr(stl.size() - 500));
  r = one_response(port, get_text(location + "/result.stl", "Range: bytes=100-\r\n"));
  EXPECT_EQ(r.status, 206);
  EXPECT_EQ(r.body, stl.substr(100));
  r = one_response(port, get_text(location + "/result.stl", "Range: bytes=0-1048575\r\n"));
  EXPECT_EQ(r.status, 206);
  EXPECT_EQ(r.body, stl);
  r = one_response(port, get_text(location + "/result.stl", "Range: bytes=1048576-\r\n"));
  EXPECT_EQ(r.status, 416);
  EXPECT_EQ(r.header("content-range"), "bytes */" + std::to_string(stl.size()));
  r = one_response(port, get_text(location + "/result.stl", "Range: bytes=0-1,5-9\r\n"));
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.body, stl);
  // HEAD tells the length and sends nothing.
  const std::string head_answer =
      test::exchange(port, "HEAD " + location + "/result.stl HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_NE(head_answer.find("Content-Length: " + std::to_string(stl.size())), std::string::npos);
  EXPECT_TRUE(head_answer.ends_with("\r\n\r\n")) << head_answer;
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------
// 2. Job ids from the OS, and jobs owned by the key that made them.

TEST(Attack, JobIdsAreUnguessableAndOtherTenantsCannotSeeOrTouchAJob) {
  const fs::path dir = fresh_dir("tenants");
  fs::create_directories(dir);
  const std::string key_a = "tenant-a-0123456789abcdef", key_b = "tenant-b-0123456789abcdef";
  {
    std::ofstream keys(dir / "keys");
    keys << key_a << "\n" << key_b << "\n";
  }
  Child child(daemon_argv({"--data-dir", (dir / "data").string(), "--api-key-file",
                           (dir / "keys").string(), "--compute-slots", "1", "--job-queue", "64"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  httplib::Client a("127.0.0.1", port), b("127.0.0.1", port);
  a.set_bearer_token_auth(key_a);
  b.set_bearer_token_auth(key_b);
  const std::string tetra = binary_stl(octahedron_triangles());

  std::set<std::string> ids;
  for (int i = 0; i < 20; ++i) {
    auto r = a.Post("/v1/jobs?levels=1", tetra, "model/stl");
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 202) << r->body;
    const std::string id = Json::parse(r->body).value("id", "");
    // 128 bits, URL-safe: at least 22 characters of the base64url alphabet.
    EXPECT_TRUE(std::regex_match(id, std::regex("[A-Za-z0-9_-]{22,64}"))) << id;
    ids.insert(id);
  }
  EXPECT_EQ(ids.size(), 20u);
  const std::string id = *ids.begin();
  const std::string job = "/v1/jobs/" + id;
  for (int i = 0; i < 200; ++i) {
    auto r = a.Get(job.c_str());
    ASSERT_TRUE(r);
    if (Json::parse(r->body).value("state", "") == "done") break;
    std::this_thread::sleep_for(50ms);
  }
  // The owner sees it; the other key gets exactly what an unknown id gets.
  auto own = a.Get((job + "/result.stl").c_str());
  ASSERT_TRUE(own);
  EXPECT_EQ(own->status, 200);
  const std::string unknown = "/v1/jobs/AAAAAAAAAAAAAAAAAAAAAA";
  for (const std::string& suffix :
       {std::string(), std::string("/result.stl"), std::string("/report.json")}) {
    auto theirs = b.Get((job + suffix).c_str());
    auto none = b.Get((unknown + suffix).c_str());
    ASSERT_TRUE(theirs && none);
    EXPECT_EQ(theirs->status, 404) << suffix;
    EXPECT_EQ(none->status, 404);
    EXPECT_EQ(Json::parse(theirs->body).value("type", ""),
              Json::parse(none->body).value("type", ""));
  }
  auto deleted = b.Delete(job.c_str());
  ASSERT_TRUE(deleted);
  EXPECT_EQ(deleted->status, 404);
  auto still = a.Get((job + "/result.stl").c_str());
  ASSERT_TRUE(still);
  EXPECT_EQ(still->status, 200) << "another tenant's DELETE must not touch the job";
  // No key in clear on disk.
  for (const auto& entry : fs::recursive_directory_iterator(dir / "data")) {
    if (!entry.is_regular_file() || entry.path().filename() != "job.json") continue;
    const std::string text = read_file(entry.path());
    EXPECT_EQ(text.find(key_a), std::string::npos) << entry.path();
    EXPECT_EQ(text.find("tenant-a"), std::string::npos) << entry.path();
  }
  child.signal(SIGTERM);
  EXPECT_EQ(child.wait(20s), 0);
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------
// 7. A full disk: 507 with a problem body before the 202, nothing left behind.

TEST(Attack, AJobThatTheDiskCannotHoldIs507BeforeItIsAccepted) {
  const fs::path dir = fresh_dir("disk");
  std::atomic<std::uint64_t> free_bytes{std::uint64_t{1} << 40};
  server::DaemonConfig config;
  config.compute_slots = 1;
  config.jobs.data_dir = dir;
  config.jobs.free_bytes = [&] { return free_bytes.load(); };
  InProcessDaemon d(config);
  httplib::Client client = d.client();
  auto accepted = client.Post("/v1/jobs?levels=1", fandisk(), "model/stl");
  ASSERT_TRUE(accepted);
  EXPECT_EQ(accepted->status, 202);
  free_bytes = 10 << 20;  // 10 MiB: less than the margin and a 4-level result
  auto refused = client.Post("/v1/jobs?levels=4", fandisk(), "model/stl");
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 507) << refused->body;
  EXPECT_EQ(refused->get_header_value("Content-Type"), "application/problem+json");
  EXPECT_TRUE(refused->has_header("Retry-After"));
  const Json problem = Json::parse(refused->body);
  EXPECT_EQ(problem.value("status", 0), 507);
  EXPECT_GT(problem.value("needed_bytes", std::uint64_t{0}), std::uint64_t{10} << 20)
      << refused->body;
  // Exactly one job directory: the accepted one.
  std::size_t dirs = 0;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_directory()) ++dirs;
  EXPECT_EQ(dirs, 1u);
  d.stop();
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------
// 8. A cancel that is answered as accepted wins, or says it came too late.

TEST(Attack, ACancelWinsOrSaysItCameTooLate) {
  const fs::path dir = fresh_dir("cancel");
  Child child(
      daemon_argv({"--data-dir", dir.string(), "--compute-slots", "2", "--job-queue", "64"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  httplib::Client client("127.0.0.1", port);
  const std::string tetra = binary_stl(octahedron_triangles());
  std::mt19937 rng(8);
  int cancelled = 0, too_late = 0;
  for (int i = 0; i < 40; ++i) {
    auto submitted = client.Post("/v1/jobs?levels=5", tetra, "model/stl");
    ASSERT_TRUE(submitted);
    ASSERT_EQ(submitted->status, 202);
    const std::string job = submitted->get_header_value("Location");
    std::this_thread::sleep_for(std::chrono::microseconds(rng() % 20000));
    auto deleted = client.Delete(job.c_str());
    ASSERT_TRUE(deleted);
    ASSERT_TRUE(deleted->status == 200 || deleted->status == 202) << deleted->body;
    const std::string said = Json::parse(deleted->body).value("cancel", "");
    std::string state;
    for (int k = 0; k < 200; ++k) {
      state = Json::parse(client.Get(job.c_str())->body).value("state", "");
      if (state != "queued" && state != "running") break;
      std::this_thread::sleep_for(10ms);
    }
    if (said == "cancelled") {
      ++cancelled;
      EXPECT_EQ(state, "cancelled") << "a cancel answered as accepted lost to the runner";
    } else {
      ASSERT_EQ(said, "too_late") << deleted->body;
      ++too_late;
      EXPECT_EQ(state, "done");
      auto result = client.Get((job + "/result.stl").c_str());
      ASSERT_TRUE(result);
      EXPECT_EQ(result->status, 410);
    }
  }
  EXPECT_GT(cancelled, 0);
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------
// 3. SIGTERM never truncates an answer.

TEST(Attack, SigtermLetsARefineInFlightArriveWhole) {
  Child child(daemon_argv({"--compute-slots", "1", "--access-log", "--shutdown-grace", "30"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  // fandisk, butterfly 3 levels: ~40 MB of STL, a second or more of compute.
  RawConnection c(port);
  ASSERT_TRUE(c.send(post_text("/v1/refine?levels=3", "model/stl", fandisk())));
  std::this_thread::sleep_for(300ms);  // computing now
  child.signal(SIGTERM);
  const std::vector<RawResponse> answers = parse_responses(c.read_all(60s));
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_EQ(answers[0].status, 200);
  EXPECT_EQ(std::to_string(answers[0].body.size()), answers[0].header("content-length"));
  EXPECT_EQ(answers[0].body.size(), 84u + 50u * 12946u * 64u);
  EXPECT_EQ(child.wait(30s), 0) << child.stderr_text();
}

TEST(Attack, SigtermLetsAJobDownloadFinishAndLogsAnAbandonedOneAsAborted) {
  const fs::path dir = fresh_dir("sigterm-download");
  Child child(daemon_argv({"--data-dir", dir.string(), "--compute-slots", "1", "--access-log",
                           "--shutdown-grace", "3", "--write-timeout", "60"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  httplib::Client client("127.0.0.1", port);
  auto submitted = client.Post("/v1/jobs?levels=3", fandisk(), "model/stl");
  ASSERT_TRUE(submitted);
  ASSERT_EQ(submitted->status, 202);
  const std::string location = submitted->get_header_value("Location");
  for (int i = 0; i < 600; ++i) {
    auto job = client.Get(location.c_str());
    if (job && Json::parse(job->body).value("state", "") == "done") break;
    std::this_thread::sleep_for(50ms);
  }
  const std::uint64_t expected = 84u + 50u * 12946u * 64u;
  // One download that reads at once, one that does not read at all.
  RawConnection reader(port), stalled(port);
  ASSERT_TRUE(reader.send(get_text(location + "/result.stl")));
  ASSERT_TRUE(stalled.send(get_text(location + "/result.stl")));
  const std::string first = reader.read_until("\r\n\r\n", 5s);
  ASSERT_NE(first.find("200 OK"), std::string::npos);
  // The stalled download has begun too (its head read, its 41 MB body never): a request not
  // yet read when SIGTERM comes is answered 503, which is another test's case (under ASan
  // the daemon was that slow).
  ASSERT_NE(stalled.read_until("\r\n\r\n", 5s).find("200 OK"), std::string::npos);
  child.signal(SIGTERM);
  std::string rest = reader.read_all(60s);
  const std::vector<RawResponse> answers = parse_responses(first + rest);
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_EQ(answers[0].body.size(), expected);
  EXPECT_EQ(child.wait(30s), 0) << child.stderr_text();
  // The stalled download was abandoned at the end of the grace: logged as aborted, never 200.
  const std::string log = child.stderr_text();
  std::size_t full = 0, aborted = 0;
  for (std::size_t at = log.find("/result.stl\""); at != std::string::npos;
       at = log.find("/result.stl\"", at + 1)) {
    const std::size_t end = log.find('\n', at);
    const std::string line = log.substr(log.rfind('\n', at) + 1, end - log.rfind('\n', at) - 1);
    if (line.find("\"aborted\":\"shutdown\"") != std::string::npos) {
      ++aborted;
      EXPECT_NE(line.find("\"status\":499"), std::string::npos) << line;
    } else if (line.find("\"status\":200") != std::string::npos) {
      ++full;
      EXPECT_NE(line.find("\"bytes\":" + std::to_string(expected)), std::string::npos) << line;
    }
  }
  EXPECT_EQ(full, 1u) << log;
  EXPECT_EQ(aborted, 1u) << log;
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------
// 4. Memory admission that holds: the worst adaptive request of every host stays inside
// --memory-budget (the issue's case: 647 KB fandisk, sqrt3-interp adaptive_tol=1e-9
// max_level=6 peaked at 7.1 GiB).

std::uint64_t peak_rss_bytes(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  return 0;
}

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define STLREFINE_UNDER_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define STLREFINE_UNDER_ASAN 1
#endif

// One request per test (each takes 2-6 s alone; five in one test passed ctest's 60 s under
// CI's parallel load).
class WorstAdaptiveRequestOfEveryHost : public ::testing::TestWithParam<const char*> {};

TEST_P(WorstAdaptiveRequestOfEveryHost, StaysInsideTheMemoryBudget) {
#ifdef STLREFINE_UNDER_ASAN
  // ASan's shadow memory and quarantine are RSS the budget does not model (the load test is
  // left out of the asan preset for the same reason); the Release run is the check.
  GTEST_SKIP() << "peak RSS bounds are the Release build's";
#endif
  constexpr std::uint64_t kBudget = std::uint64_t{640} << 20;
  Child child(daemon_argv({"--compute-slots", "1", "--memory-budget", "640M"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  {
    const std::string query = GetParam();
    const double cpu_before = proc_cpu_seconds(child.pid());
    const RawResponse r =
        one_response(port, post_text("/v1/refine?" + query, "model/stl", fandisk()), 120s);
    // The daemon's CPU time, not the wall clock: the bound is on the work a hostile request
    // buys, and a wall bound failed at 50.3 s on a loaded machine (load 10) for ~15 s of work.
    // one_response's 120 s is the hang guard.
    const double cpu_seconds = proc_cpu_seconds(child.pid()) - cpu_before;
    SCOPED_TRACE(query);
    // Refused (422: never fits; 503: not now) or done, but within the budget either way.
    EXPECT_TRUE(r.status == 422 || r.status == 503 || r.status == 200) << r.status;
    if (r.status != 200) {
      EXPECT_EQ(r.header("content-type"), "application/problem+json");
      EXPECT_NE(r.body.find("\"field\""), std::string::npos) << r.body;
    }
    EXPECT_GT(cpu_seconds, 0.0) << "/proc/<pid>/stat unreadable";
    EXPECT_LT(cpu_seconds, 40.0);
    EXPECT_LT(peak_rss_bytes(child.pid()), kBudget) << r.body.substr(0, 400);
  }
  EXPECT_EQ(one_response(port, get_text("/healthz")).status, 200);
}

INSTANTIATE_TEST_SUITE_P(Attack, WorstAdaptiveRequestOfEveryHost,
                         ::testing::Values("scheme=sqrt3-interp&adaptive_tol=1e-9&max_level=6",
                                           "scheme=sqrt3&adaptive_tol=1e-9&max_level=6",
                                           "scheme=butterfly&adaptive_tol=1e-9&max_level=8",
                                           "scheme=lsf&adaptive_tol=1e-9&max_level=8",
                                           "scheme=butterfly&adaptive_angle=0.01&max_level=8"));

// ---------------------------------------------------------------------------------------
// 5. Slow uploads and slow readers pin neither the budget nor the workers.

TEST(Attack, FiftySlowUploadsLeaveInfoAndHealthzAnswering) {
  Child child(daemon_argv({"--compute-slots", "1", "--threads", "3", "--memory-budget", "1G",
                           "--max-body-mib", "256", "--read-timeout", "3"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  // 50 sockets declare 256 MiB bodies (12.5 GiB in all, 12x the budget) and trickle.
  std::vector<std::unique_ptr<RawConnection>> slow;
  for (int i = 0; i < 50; ++i) {
    slow.push_back(std::make_unique<RawConnection>(port));
    ASSERT_TRUE(
        slow.back()->send("POST /v1/refine HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\n"
                          "Content-Length: 268435456\r\n\r\nsolid"));
  }
  const std::string tetra = binary_stl(octahedron_triangles());
  std::vector<std::string> answers(slow.size());
  const auto until = std::chrono::steady_clock::now() + 8s;
  int info_ok = 0, health_ok = 0, rounds = 0;
  while (std::chrono::steady_clock::now() < until) {
    for (std::size_t i = 0; i < slow.size(); ++i) {
      answers[i] += slow[i]->read_until("\r\n\r\n", 2ms);
      // A byte a second per socket, as the attack did, until the socket is answered.
      if (answers[i].empty()) slow[i]->send("x");
    }
    ++rounds;
    if (one_response(port, post_text("/v1/info", "model/stl", tetra)).status == 200) ++info_ok;
    if (one_response(port, get_text("/healthz")).status == 200) ++health_ok;
    std::this_thread::sleep_for(1s);
  }
  EXPECT_EQ(info_ok, rounds);
  EXPECT_EQ(health_ok, rounds);
  // A byte a second is under the minimum rate: every slow socket got 408 within a window or
  // two (3 s each here), although bytes kept arriving.
  for (const std::string& answer : answers)
    EXPECT_TRUE(answer.starts_with("HTTP/1.1 408 ")) << "[" << answer << "]";
}

TEST(Attack, AThousandTricklingSocketsFromOneAddressDoNotStarveHealthz) {
  rlimit files{};
  ::getrlimit(RLIMIT_NOFILE, &files);
  files.rlim_cur = files.rlim_max;
  ::setrlimit(RLIMIT_NOFILE, &files);
  if (files.rlim_cur < 1300)
    GTEST_SKIP() << "needs 1300 descriptors, the hard limit is " << files.rlim_max;
  Child child(
      daemon_argv({"--compute-slots", "1", "--max-connections", "1024", "--read-timeout", "30"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  std::vector<std::unique_ptr<RawConnection>> flood;
  for (int i = 0; i < 1100; ++i) {
    flood.push_back(std::make_unique<RawConnection>(port));
    flood.back()->send("GET /v1/openapi.json HTTP/1.1\r\n");  // and never the end of the head
  }
  int ok = 0;
  for (int i = 0; i < 40; ++i) {
    for (std::size_t j = i % 7; j < flood.size(); j += 7) flood[j]->send("X");
    if (one_response(port, get_text("/healthz"), 5s).status == 200) ++ok;
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_EQ(ok, 40);
}

TEST(Attack, ClientsThatNeverReadTheirAnswerHoldNoWorker) {
  Child child(daemon_argv({"--compute-slots", "2", "--threads", "3", "--write-timeout", "4"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  // Six clients ask for ~40 MB answers and never read them. (No deviation pass: under ASan
  // it makes the six computations outlast the 20 s below; this test is about the answers.)
  std::vector<std::unique_ptr<RawConnection>> sinks;
  for (int i = 0; i < 6; ++i) {
    sinks.push_back(std::make_unique<RawConnection>(port));
    ASSERT_TRUE(sinks.back()->send(
        post_text("/v1/refine?levels=3&max_deviation=off", "model/stl", fandisk())));
  }
  std::this_thread::sleep_for(100ms);
  // The workers computed and handed the answers to the event loop: others are served.
  const std::string tetra = binary_stl(octahedron_triangles());
  int ok = 0;
  const auto until = std::chrono::steady_clock::now() + 20s;
  while (ok < 5 && std::chrono::steady_clock::now() < until) {
    const RawResponse r = one_response(port, post_text("/v1/info", "model/stl", tetra));
    if (r.status == 200) ++ok;
    std::this_thread::sleep_for(200ms);
  }
  EXPECT_EQ(ok, 5);
}

// ---------------------------------------------------------------------------------------
// 6. Metrics labels come from a fixed set.

TEST(Attack, RandomMethodsDoNotGrowMetrics) {
  Child child(daemon_argv({"--compute-slots", "1"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  const std::size_t before = one_response(port, get_text("/metrics")).body.size();
  std::mt19937 rng(16);
  std::uniform_int_distribution<int> letter('A', 'Z');
  for (int i = 0; i < 600; ++i) {
    std::string method;
    for (int k = 0; k < 12; ++k) method += static_cast<char>(letter(rng));
    test::exchange(port, method + " /healthz HTTP/1.1\r\nHost: x\r\n\r\n", 2s);
  }
  const std::string after = one_response(port, get_text("/metrics")).body;
  EXPECT_LT(after.size(), before + 4096) << after.substr(0, 2000);
}

// ---------------------------------------------------------------------------------------
// 8. The empty request line.

TEST(Attack, AnEmptyRequestLineIs400) {
  Child child(daemon_argv({"--compute-slots", "1"}));
  const int port = start(child);
  ASSERT_GT(port, 0);
  for (const std::string& text :
       {std::string("\r\n\r\n"), std::string("\r\nHost: x\r\n\r\n"), std::string(" \r\n\r\n")}) {
    const RawResponse r = one_response(port, text, 5s);
    EXPECT_EQ(r.status, 400) << text.size();
  }
  // One empty line before a request line is tolerated (RFC 9112 2.2).
  EXPECT_EQ(one_response(port, "\r\n" + get_text("/healthz")).status, 200);
}

}  // namespace
}  // namespace stlrefine::test
