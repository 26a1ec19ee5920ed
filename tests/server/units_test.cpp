// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Units (issue 19 item 1): a part exported in metres (the 44 x 14 x 47 mm housing as
// 0.044 x 0.014 x 0.047) is flagged with units=auto and converted with units=m; a slice
// without a layer is a 422 naming the layer height and the part's height, never an empty
// 200; through the API, the CLI and the daemon.

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "api/params.h"
#include "api/pipeline.h"
#include "core/error.h"
#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

// An axis-aligned box [0, x] x [0, y] x [0, z], 12 outward facets.
std::vector<Triangle> box(float x, float y, float z) {
  const auto c = [&](int i) {
    return Corner{(i & 1) ? x : 0.0f, (i & 2) ? y : 0.0f, (i & 4) ? z : 0.0f};
  };
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  std::vector<Triangle> out;
  for (const auto& q : quads) {
    out.push_back({c(q[0]), c(q[1]), c(q[2])});
    out.push_back({c(q[0]), c(q[2]), c(q[3])});
  }
  return out;
}

std::span<const std::uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

const std::string& housing_in_metres() {
  static const std::string stl = binary_stl(box(0.044f, 0.014f, 0.047f));
  return stl;
}

TEST(Units, ParsedOnEveryRequestKind) {
  EXPECT_EQ(api::parse_refine_params({{"units", "m"}}, {}).units.units, api::LengthUnit::Metre);
  EXPECT_EQ(api::parse_slice_params({{"units", "in"}}, {}).units.units, api::LengthUnit::Inch);
  EXPECT_EQ(api::parse_info_params({{"units", "cm"}, {"scale", "2"}}).units.scale, 2.0);
  EXPECT_EQ(api::parse_info_params({}).units.units, api::LengthUnit::Auto);
  for (const auto& [name, value] :
       std::vector<std::pair<std::string, std::string>>{{"units", "furlong"},
                                                        {"units", ""},
                                                        {"scale", "0"},
                                                        {"scale", "-1"},
                                                        {"scale", "nan"}}) {
    try {
      api::parse_slice_params({{name, value}}, {});
      ADD_FAILURE() << name << "=" << value << " accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
      EXPECT_EQ(e.field(), name);
    }
  }
}

TEST(Units, AutoFlagsAMetresPartWithoutConvertingIt) {
  const nlohmann::ordered_json report = api::run_info(bytes_of(housing_in_metres()), {});
  const auto& units = report["input"]["units"];
  EXPECT_EQ(units["units"], "mm");
  EXPECT_EQ(units["assumed"], true);
  EXPECT_EQ(units["factor_to_mm"], 1.0);
  EXPECT_NEAR(units["size_mm"][2].get<double>(), 0.047, 1e-6);
  ASSERT_EQ(report["warnings"].size(), 1u) << report.dump();
  EXPECT_EQ(report["warnings"][0]["code"], "suspicious_units");
  const std::string message = report["warnings"][0]["message"];
  EXPECT_NE(message.find("units=m"), std::string::npos) << message;
  EXPECT_NE(message.find("44 x 14 x 47 mm"), std::string::npos) << message;
}

TEST(Units, MetresAreConvertedToMillimetres) {
  api::InfoRequest request;
  request.units.units = api::LengthUnit::Metre;
  const nlohmann::ordered_json report = api::run_info(bytes_of(housing_in_metres()), request);
  EXPECT_EQ(report["input"]["units"]["units"], "m");
  EXPECT_EQ(report["input"]["units"]["assumed"], false);
  EXPECT_EQ(report["input"]["units"]["factor_to_mm"], 1000.0);
  EXPECT_NEAR(report["input"]["units"]["size_mm"][0].get<double>(), 44.0, 1e-3);
  EXPECT_TRUE(report["warnings"].empty()) << report.dump();
  EXPECT_NEAR(report["mesh"]["bbox"]["max"][2].get<double>(), 47.0, 1e-3);
  // A plausible part read as mm: no warning; inches and scale multiply.
  request.units.units = api::LengthUnit::Inch;
  request.units.scale = 2;
  const nlohmann::ordered_json inches = api::run_info(bytes_of(binary_stl(box(1, 2, 3))), request);
  EXPECT_NEAR(inches["mesh"]["bbox"]["max"][2].get<double>(), 3 * 25.4 * 2, 1e-9);
  EXPECT_TRUE(inches["warnings"].empty());
  // Too large in mm (a part in micrometres) is flagged too.
  const nlohmann::ordered_json huge =
      api::run_info(bytes_of(binary_stl(box(44000, 14000, 47000))), {});
  ASSERT_EQ(huge["warnings"].size(), 1u);
  EXPECT_NE(huge["warnings"][0]["message"].get<std::string>().find("over 2 m"), std::string::npos);
}

TEST(Units, ASliceWithoutALayerIsAnErrorNamingTheLayerHeight) {
  api::SliceRequest request;  // layer_height 0.1 mm: the part read as mm is 0.047 tall
  try {
    api::run_slice(bytes_of(housing_in_metres()), request);
    ADD_FAILURE() << "a slice without a layer succeeded";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::NothingToMake);
    EXPECT_EQ(e.field(), "layer_height");
    EXPECT_NE(std::string(e.what()).find("0.047 mm tall"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("units="), std::string::npos) << e.what();
  }
  request.units.units = api::LengthUnit::Metre;
  const api::SliceOutcome out = api::run_slice(bytes_of(housing_in_metres()), request);
  EXPECT_EQ(out.report["slice"]["layers"], 470);  // 47 mm / 0.1 mm
  // After a refinement the layer height is `slice`: the error names it so.
  api::RefineRequest refine = api::parse_refine_params({{"slice", "0.1"}, {"levels", "0"}}, {});
  try {
    api::run_refine(bytes_of(housing_in_metres()), refine);
    ADD_FAILURE() << "a refine + slice without a layer succeeded";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::NothingToMake);
    EXPECT_EQ(e.field(), "slice");
  }
}

TEST(Units, RefinedOutputIsInMillimetres) {
  const api::RefineRequest request =
      api::parse_refine_params({{"units", "m"}, {"levels", "1"}, {"scheme", "loop"}}, {});
  const api::RefineOutcome out = api::run_refine(bytes_of(housing_in_metres()), request);
  float top = 0;
  for (const Triangle& t : read_binary_stl(out.stl))
    for (const Corner& c : t) top = std::max(top, c[2]);
  EXPECT_GT(top, 40.0f);  // loop shrinks the box a little, but it is in mm now
  EXPECT_LE(top, 47.0f);
  EXPECT_EQ(out.report["input"]["units"]["factor_to_mm"], 1000.0);
}

class UnitsBinaryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stlrefine_units_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    std::ofstream(path("housing.stl"), std::ios::binary) << housing_in_metres();
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(UnitsBinaryTest, Cli) {
  // Flagged, not converted: the report's warning; a slice of it fails naming --layer-height.
  ProcessResult r = run_process({STLREFINE_CLI, "info", path("housing.stl")}, 60s);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("suspicious_units"), std::string::npos) << r.out;
  r = run_process(
      {STLREFINE_CLI, "slice", path("housing.stl"), "-o", path("a.cli"), "--format", "cli"}, 60s);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("--layer-height"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("a.cli")));
  r = run_process({STLREFINE_CLI, "slice", path("housing.stl"), "-o", path("b.cli"), "--format",
                   "cli", "--units", "m"},
                  60s);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string cli = read_file(path("b.cli"));
  EXPECT_NE(cli.find("$$UNITS/1"), std::string::npos);
  EXPECT_NE(cli.find("$$LAYERS/470"), std::string::npos) << cli.substr(0, 300);
}

TEST_F(UnitsBinaryTest, Daemon) {
  if (!fs::exists("/usr/bin/curl")) GTEST_SKIP() << "curl is not installed";
  Child daemon({STLREFINED, "--port", "0"});
  const int port = listening_port(daemon);
  ASSERT_GT(port, 0) << daemon.stderr_text();
  const std::string url = "http://127.0.0.1:" + std::to_string(port);
  // Appended, not "@" + path: GCC 12's -Wrestrict misfires on it.
  const std::string upload = std::string("@").append(path("housing.stl"));
  const auto post = [&](const std::string& target) {
    const ProcessResult r =
        run_process({"/usr/bin/curl", "-sS", "--data-binary", upload, "-D", path("headers"), "-o",
                     path("body"), "-w", "%{http_code}", url + target});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return std::atoi(r.out.c_str());
  };
  ASSERT_EQ(post("/v1/slice?layer_height=0.1"), 422);
  nlohmann::json problem = nlohmann::json::parse(read_file(path("body")));
  EXPECT_EQ(problem["field"], "layer_height");
  EXPECT_NE(problem["detail"].get<std::string>().find("0.047 mm tall"), std::string::npos);
  ASSERT_EQ(post("/v1/refine?slice=0.1&levels=0"), 422);
  EXPECT_EQ(nlohmann::json::parse(read_file(path("body")))["field"], "slice");
  ASSERT_EQ(post("/v1/slice?layer_height=0.1&units=m"), 200);
  EXPECT_EQ(nlohmann::json::parse(read_file(path("body")))["layers"].size(), 470u);
  ASSERT_EQ(post("/v1/refine?levels=1&units=auto"), 200);
  const std::string headers = read_file(path("headers"));
  EXPECT_NE(headers.find("suspicious_units"), std::string::npos) << headers;
  ASSERT_EQ(post("/v1/refine?units=yards"), 400);
  EXPECT_EQ(nlohmann::json::parse(read_file(path("body")))["field"], "units");
}

}  // namespace
}  // namespace stlrefine::test
