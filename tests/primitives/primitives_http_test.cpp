// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The post-pass's parameters (primitives, primitive_tol, max_deviation) and its report
// figures end to end: POST /v1/refine and /v1/jobs of a daemon in process (a bad value is a
// problem+json (400) naming the field; the report header carries `primitives` and `deviation`),
// and the stlrefine CLI's --primitives / --max-deviation with --report.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/server/in_process_daemon.h"
#include "tests/server/subprocess.h"

namespace stlrefine::test {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

std::string gearwheel() {
  std::ifstream in(std::string(STLREFINE_TEST_DATA_DIR) + "/gearwheel.stl", std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A daemon with a job store (so /v1/jobs exists) in a fresh directory.
server::DaemonConfig config_with_jobs(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("primitives_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  server::DaemonConfig config;
  config.jobs.data_dir = dir;
  return config;
}

TEST(PrimitivesHttp, BadValuesAreProblemsNamingTheField) {
  const server::DaemonConfig config = config_with_jobs("bad");
  InProcessDaemon d(config);
  httplib::Client client = d.client();
  const std::string stl = gearwheel();
  ASSERT_FALSE(stl.empty());
  const std::pair<const char*, const char*> cases[] = {
      {"primitives=maybe", "primitives"},     {"primitive_tol=0", "primitive_tol"},
      {"primitive_tol=0.5", "primitive_tol"}, {"max_deviation=-1", "max_deviation"},
      {"max_deviation=abc", "max_deviation"}, {"max_deviation=1e7", "max_deviation"}};
  for (const char* route : {"/v1/refine", "/v1/jobs"})
    for (const auto& [query, field] : cases) {
      SCOPED_TRACE(std::string(route) + "?" + query);
      auto r = client.Post(std::string(route) + "?" + query, stl, "model/stl");
      ASSERT_TRUE(r);
      EXPECT_EQ(r->status, 400) << r->body;
      EXPECT_EQ(r->get_header_value("Content-Type"), "application/problem+json");
      EXPECT_EQ(Json::parse(r->body).value("field", ""), field) << r->body;
    }
  d.stop();
  fs::remove_all(config.jobs.data_dir);
}

TEST(PrimitivesHttp, ReportHeaderCarriesTheFigures) {
  InProcessDaemon d(server::DaemonConfig{});
  httplib::Client client = d.client();
  auto r = client.Post("/v1/refine?levels=1&max_deviation=auto&primitives=auto", gearwheel(),
                       "model/stl");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  const Json report = Json::parse(r->get_header_value("X-Stlrefine-Report"));
  EXPECT_EQ(report.at("primitives").at("mode"), "auto");
  EXPECT_GT(report.at("primitives").at("regions_found").get<int>(), 0);
  const Json& dev = report.at("deviation");
  EXPECT_EQ(dev.at("bound"), "auto");
  EXPECT_LE(dev.at("max_distance_from_input").get<double>(),
            dev.at("max_bound").get<double>() * (1 + 1e-9));
  for (const char* key : {"worst_normal_change_deg", "faces_turned_over_60_deg", "pulled_back"})
    EXPECT_TRUE(dev.contains(key)) << key;
  EXPECT_TRUE(report.contains("fold_fallbacks"));

  auto off = client.Post("/v1/refine?levels=1&primitives=off&max_deviation=0.001", gearwheel(),
                         "model/stl");
  ASSERT_TRUE(off);
  ASSERT_EQ(off->status, 200) << off->body;
  const Json off_report = Json::parse(off->get_header_value("X-Stlrefine-Report"));
  EXPECT_EQ(off_report.at("primitives").at("mode"), "off");
  EXPECT_EQ(off_report.at("deviation").at("bound"), 0.001);
  EXPECT_LE(off_report.at("deviation").at("max_distance_from_input").get<double>(),
            0.001 * (1 + 1e-9));
}

TEST(PrimitivesHttp, CliOptionsAndReport) {
  const fs::path dir = fs::temp_directory_path() / ("primitives_cli_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string input = std::string(STLREFINE_TEST_DATA_DIR) + "/gearwheel.stl";
  const ProcessResult ok =
      run_process({STLREFINE_CLI, "refine", input, "-o", (dir / "out.stl").string(), "--levels",
                   "1", "--max-deviation", "0.002", "--report", (dir / "r.json").string()});
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  std::ifstream in(dir / "r.json");
  const Json report = Json::parse(in);
  EXPECT_EQ(report.at("deviation").at("bound"), 0.002);
  EXPECT_LE(report.at("deviation").at("max_distance_from_input").get<double>(), 0.002 * (1 + 1e-9));
  const ProcessResult bad = run_process({STLREFINE_CLI, "refine", input, "-o",
                                         (dir / "bad.stl").string(), "--primitives", "sometimes"});
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
  EXPECT_NE(bad.err.find("primitives"), std::string::npos) << bad.err;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace stlrefine::test
