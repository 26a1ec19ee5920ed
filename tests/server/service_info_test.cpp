// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Issue 19 item 6: the API key in either header (Bearer or X-Api-Key, one tenant either
// way), GET /v1/version, and the build_info / process_* metrics, against the daemon in
// process on an ephemeral loopback port.

#include <gtest/gtest.h>
#include <httplib.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>

#include "core/schemes/registry.h"
#include "http_test_client.h"
#include "in_process_daemon.h"
#include "server/daemon.h"
#include "test_stl.h"
#include "test_zip.h"

namespace stlrefine::server {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr const char* kKeyOne = "0123456789abcdef-key-one";
constexpr const char* kKeyTwo = "fedcba9876543210-key-two";

const std::string& octahedron() {
  static const std::string bytes = test::binary_stl(test::octahedron_triangles());
  return bytes;
}

DaemonConfig keyed_config(const fs::path& dir) {
  DaemonConfig config;
  config.compute_slots = 1;
  config.api_keys = {kKeyOne, kKeyTwo};
  config.jobs.data_dir = dir;
  return config;
}

TEST(ApiKey, XApiKeyWorksLikeBearerAndNamesTheSameTenant) {
  const fs::path dir =
      fs::temp_directory_path() / ("stlrefine-apikey-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  {
    test::InProcessDaemon d(keyed_config(dir));
    httplib::Client c = d.client();
    auto sync = c.Post("/v1/refine?levels=1", {{"X-Api-Key", kKeyOne}}, octahedron(), "model/stl");
    ASSERT_TRUE(sync);
    EXPECT_EQ(sync->status, 200) << sync->body;

    auto wrong = c.Post("/v1/refine?levels=1", {{"X-Api-Key", "0123456789abcdef-key-onX"}},
                        octahedron(), "model/stl");
    ASSERT_TRUE(wrong);
    EXPECT_EQ(wrong->status, 401);
    EXPECT_NE(wrong->body.find("X-Api-Key"), std::string::npos) << wrong->body;

    // Two different keys in the two headers: refused, whichever is valid.
    auto both =
        c.Post("/v1/refine?levels=1",
               {{"Authorization", std::string("Bearer ") + kKeyOne}, {"X-Api-Key", kKeyTwo}},
               octahedron(), "model/stl");
    ASSERT_TRUE(both);
    EXPECT_EQ(both->status, 401);
    // The same key in both: fine.
    auto same =
        c.Post("/v1/refine?levels=1",
               {{"Authorization", std::string("Bearer ") + kKeyOne}, {"X-Api-Key", kKeyOne}},
               octahedron(), "model/stl");
    ASSERT_TRUE(same);
    EXPECT_EQ(same->status, 200);
    // The scheme name is case-insensitive.
    auto lower =
        c.Post("/v1/refine?levels=1", {{"Authorization", std::string("bearer ") + kKeyOne}},
               octahedron(), "model/stl");
    ASSERT_TRUE(lower);
    EXPECT_EQ(lower->status, 200);
    // A malformed Authorization does not fall back to X-Api-Key.
    auto basic = c.Post("/v1/refine?levels=1",
                        {{"Authorization", "Basic dXNlcjpwYXNz"}, {"X-Api-Key", kKeyOne}},
                        octahedron(), "model/stl");
    ASSERT_TRUE(basic);
    EXPECT_EQ(basic->status, 401);

    // A job submitted with Bearer is the same tenant's with X-Api-Key, another key's 404.
    auto submitted =
        c.Post("/v1/jobs?levels=1", {{"Authorization", std::string("Bearer ") + kKeyOne}},
               octahedron(), "model/stl");
    ASSERT_TRUE(submitted);
    ASSERT_EQ(submitted->status, 202) << submitted->body;
    const std::string location = submitted->get_header_value("Location");
    auto mine = c.Get(location.c_str(), {{"X-Api-Key", kKeyOne}});
    ASSERT_TRUE(mine);
    EXPECT_EQ(mine->status, 200) << mine->body;
    auto theirs = c.Get(location.c_str(), {{"X-Api-Key", kKeyTwo}});
    ASSERT_TRUE(theirs);
    EXPECT_EQ(theirs->status, 404) << theirs->body;
  }
  fs::remove_all(dir);
}

TEST(Version, AnswersTheBuildAndTheSchemes) {
  DaemonConfig config;
  config.compute_slots = 1;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto r = c.Get("/v1/version");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Type").rfind("application/json", 0), 0u);
  const Json v = Json::parse(r->body);
  EXPECT_EQ(v["name"], "stlrefine");
  EXPECT_TRUE(std::regex_match(v["version"].get<std::string>(), std::regex(R"(\d+\.\d+\.\d+)")))
      << v.dump();
  EXPECT_EQ(v["api"], "v1");
  EXPECT_FALSE(v["compiler"].get<std::string>().empty());
  const std::vector<std::string> served = v["schemes"].get<std::vector<std::string>>();
  const auto names = scheme_names();
  EXPECT_TRUE(std::equal(served.begin(), served.end(), names.begin(), names.end()));
}

TEST(Version, NeedsTheKeyWhenTheServerHasKeys) {
  const fs::path dir =
      fs::temp_directory_path() / ("stlrefine-version-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  {
    test::InProcessDaemon d(keyed_config(dir));
    httplib::Client c = d.client();
    auto none = c.Get("/v1/version");
    ASSERT_TRUE(none);
    EXPECT_EQ(none->status, 401);
    auto keyed = c.Get("/v1/version", {{"X-Api-Key", kKeyTwo}});
    ASSERT_TRUE(keyed);
    EXPECT_EQ(keyed->status, 200);
  }
  fs::remove_all(dir);
}

TEST(Cors, OffByDefault) {
  DaemonConfig config;
  config.compute_slots = 1;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto pre = c.Options("/v1/refine", {{"Origin", "https://portal.example"},
                                      {"Access-Control-Request-Method", "POST"}});
  ASSERT_TRUE(pre);
  EXPECT_EQ(pre->status, 403);
  EXPECT_NE(pre->body.find("cors-origin-not-allowed"), std::string::npos) << pre->body;
  EXPECT_FALSE(pre->has_header("Access-Control-Allow-Origin"));
  auto get = c.Get("/v1/version", {{"Origin", "https://portal.example"}});
  ASSERT_TRUE(get);
  EXPECT_EQ(get->status, 200);
  EXPECT_FALSE(get->has_header("Access-Control-Allow-Origin"));
  EXPECT_FALSE(get->has_header("Vary"));
  // OPTIONS without Origin is not a preflight: the route does not allow it.
  auto plain = c.Options("/v1/refine");
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->status, 405);
}

TEST(Cors, ConfiguredOriginsOnlyEvenOnErrorsAndWithoutAKeyForThePreflight) {
  const fs::path dir = fs::temp_directory_path() / ("stlrefine-cors-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  {
    DaemonConfig config = keyed_config(dir);
    config.cors_origins = {"https://portal.example", "http://localhost:5173"};
    test::InProcessDaemon d(config);
    httplib::Client c = d.client();
    const httplib::Headers allowed = {{"Origin", "https://portal.example"}};

    auto pre = c.Options("/v1/jobs/abc/result.stl",
                         {{"Origin", "http://localhost:5173"},
                          {"Access-Control-Request-Method", "GET"},
                          {"Access-Control-Request-Headers", "authorization, range"}});
    ASSERT_TRUE(pre);
    EXPECT_EQ(pre->status, 204) << pre->body;
    EXPECT_EQ(pre->get_header_value("Access-Control-Allow-Origin"), "http://localhost:5173");
    EXPECT_EQ(pre->get_header_value("Access-Control-Allow-Methods"), "GET, HEAD, DELETE");
    const std::string allow_headers = pre->get_header_value("Access-Control-Allow-Headers");
    EXPECT_NE(allow_headers.find("Authorization"), std::string::npos);
    EXPECT_NE(allow_headers.find("X-Api-Key"), std::string::npos);
    EXPECT_NE(allow_headers.find("Range"), std::string::npos);
    EXPECT_EQ(pre->get_header_value("Vary"), "Origin");
    EXPECT_FALSE(pre->has_header("Content-Length"));  // a 204 has none
    EXPECT_TRUE(pre->body.empty());

    auto other = c.Options("/v1/refine", {{"Origin", "https://evil.example"},
                                          {"Access-Control-Request-Method", "POST"}});
    ASSERT_TRUE(other);
    EXPECT_EQ(other->status, 403);
    EXPECT_FALSE(other->has_header("Access-Control-Allow-Origin"));
    EXPECT_EQ(other->get_header_value("Vary"), "Origin");
    auto nowhere = c.Options("/v2/nothing", {{"Origin", "https://portal.example"},
                                             {"Access-Control-Request-Method", "POST"}});
    ASSERT_TRUE(nowhere);
    EXPECT_EQ(nowhere->status, 404);

    // The real request: the page can read the answer and the fields it needs...
    httplib::Headers keyed = allowed;
    keyed.emplace("X-Api-Key", kKeyOne);
    auto ok = c.Post("/v1/refine?levels=1", keyed, octahedron(), "model/stl");
    ASSERT_TRUE(ok);
    EXPECT_EQ(ok->status, 200);
    EXPECT_EQ(ok->get_header_value("Access-Control-Allow-Origin"), "https://portal.example");
    EXPECT_NE(ok->get_header_value("Access-Control-Expose-Headers").find("X-Stlrefine-Report"),
              std::string::npos);
    // ...and its errors (a 401 from the event loop, before any handler).
    auto unauthorized = c.Post("/v1/refine?levels=1", allowed, octahedron(), "model/stl");
    ASSERT_TRUE(unauthorized);
    EXPECT_EQ(unauthorized->status, 401);
    EXPECT_EQ(unauthorized->get_header_value("Access-Control-Allow-Origin"),
              "https://portal.example");
    // Another origin's real request gets no grant.
    auto evil = c.Get("/healthz", {{"Origin", "https://evil.example"}});
    ASSERT_TRUE(evil);
    EXPECT_EQ(evil->status, 200);
    EXPECT_FALSE(evil->has_header("Access-Control-Allow-Origin"));
    auto probe = c.Get("/healthz", allowed);
    ASSERT_TRUE(probe);
    EXPECT_EQ(probe->get_header_value("Access-Control-Allow-Origin"), "https://portal.example");
  }
  fs::remove_all(dir);
}

TEST(Cors, RefusesWhatIsNotAnOrigin) {
  for (const char* bad : {"https://portal.example/", "https://portal.example/app", "portal.example",
                          "HTTPS://PORTAL.EXAMPLE", "null", ""}) {
    DaemonConfig config;
    config.cors_origins = {bad};
    EXPECT_THROW(Daemon{config}, std::invalid_argument) << bad;
  }
}

// The review's finding: a raw (not percent-encoded) non-UTF-8 byte in the target reached the
// job record and its JSON, and nlohmann's strict dump made a 500. Now replaced, never a 500.
TEST(HostileInput, NonUtf8BytesInTheTargetNeverMakeA500) {
  const fs::path dir = fs::temp_directory_path() / ("stlrefine-utf8-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  {
    DaemonConfig config;
    config.compute_slots = 1;
    config.jobs.data_dir = dir;
    test::InProcessDaemon d(config);
    for (const char* target : {"/v1/jobs?levels=1&filename=a\xff\xfe"
                               "b.stl",
                               "/v1/refine?levels=1&filename=a\xff\xfe"
                               "b.stl",
                               "/v1/jobs?levels=1&filename=%ff%fe.stl"}) {
      const std::string raw =
          test::exchange(d.port(), test::post_text(target, "model/stl", octahedron()));
      const std::vector<test::RawResponse> answers = test::parse_responses(raw);
      ASSERT_EQ(answers.size(), 1u) << target;
      EXPECT_NE(answers[0].status, 500) << target << "\n" << answers[0].body;
      if (answers[0].status == 202) {
        httplib::Client c = d.client();
        auto job = c.Get(answers[0].header("location").c_str());
        ASSERT_TRUE(job);
        EXPECT_EQ(job->status, 200) << job->body;
        auto list = c.Get("/v1/jobs");
        ASSERT_TRUE(list);
        EXPECT_EQ(list->status, 200) << list->body;
      }
    }
  }
  fs::remove_all(dir);
}

// Issue 19 item 6: the report without reading a header. report=zip answers a zip with the
// result and report.json, on /v1/refine and /v1/slice; the CLI keeps its --report FILE.
TEST(ReportZip, TheResultAndItsReportInOneZip) {
  DaemonConfig config;
  config.compute_slots = 1;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto refined =
      c.Post("/v1/refine?levels=1&report=zip&filename=part.stl", octahedron(), "model/stl");
  ASSERT_TRUE(refined);
  ASSERT_EQ(refined->status, 200) << refined->body;
  EXPECT_EQ(refined->get_header_value("Content-Type"), "application/zip");
  EXPECT_NE(refined->get_header_value("Content-Disposition").find("part_refined.zip"),
            std::string::npos);
  const auto entries = test::unzip(refined->body);
  ASSERT_EQ(entries.size(), 2u);
  ASSERT_TRUE(entries.count("refined.stl"));
  EXPECT_EQ(test::read_binary_stl(entries.at("refined.stl")).size(), 32u);  // 8 faces x 4
  const Json report = Json::parse(entries.at("report.json"));
  EXPECT_EQ(report["output"]["faces"], 32);
  EXPECT_EQ(Json::parse(refined->get_header_value("X-Stlrefine-Report")), report);

  auto sliced =
      c.Post("/v1/slice?layer_height=0.5&slice_format=svg&report=zip", octahedron(), "model/stl");
  ASSERT_TRUE(sliced);
  ASSERT_EQ(sliced->status, 200) << sliced->body;
  EXPECT_EQ(sliced->get_header_value("Content-Type"), "application/zip");
  const auto slices = test::unzip(sliced->body);
  ASSERT_TRUE(slices.count("slices.svg"));
  EXPECT_NE(slices.at("slices.svg").find("<svg"), std::string::npos);
  EXPECT_EQ(Json::parse(slices.at("report.json"))["slice"]["layers"], 4);

  auto bad = c.Post("/v1/refine?report=inline", octahedron(), "model/stl");
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 400);
  EXPECT_EQ(Json::parse(bad->body)["field"], "report");
}

// The value of a sample line "name value" or "name{labels} value" on the page, or -1.
double sample(const std::string& page, const std::string& name) {
  const std::regex line("(^|\n)" + name + R"((\{[^}]*\})? ([-+0-9.eE]+)\n)");
  std::smatch m;
  if (!std::regex_search(page, m, line)) return -1;
  return std::stod(m[3].str());
}

TEST(Metrics, CarryBuildInfoAndTheProcessMetrics) {
  DaemonConfig config;
  config.compute_slots = 1;
  test::InProcessDaemon d(config);
  httplib::Client c = d.client();
  auto r = c.Get("/metrics");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const std::string& page = r->body;
  EXPECT_NE(page.find("# TYPE stlrefine_build_info gauge\nstlrefine_build_info{version=\""),
            std::string::npos)
      << page;
  EXPECT_EQ(sample(page, "stlrefine_build_info"), 1);
  const double rss = sample(page, "process_resident_memory_bytes");
  EXPECT_GT(rss, 1 << 20);  // this test process holds more than a MiB
  EXPECT_GE(sample(page, "process_virtual_memory_bytes"), rss);
  EXPECT_GE(sample(page, "process_cpu_seconds_total"), 0);
  const double start = sample(page, "process_start_time_seconds");
  const double now = static_cast<double>(std::time(nullptr));
  EXPECT_GT(start, now - 24 * 3600);  // this process started today
  EXPECT_LE(start, now + 1);
  const double fds = sample(page, "process_open_fds");
  EXPECT_GE(fds, 3);
  EXPECT_GE(sample(page, "process_max_fds"), fds);
  EXPECT_NE(page.find("# TYPE process_cpu_seconds_total counter"), std::string::npos);
}

}  // namespace
}  // namespace stlrefine::server
