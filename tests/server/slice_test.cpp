// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Slicing through the front ends (issue 6 item 4) and the adaptive parameters (issue 4
// item 5): api/params parsing and field-named errors; `stlrefine slice` and
// `stlrefine refine --slice` run as built binaries; POST /v1/slice and refine + slice (one
// zip) with the real curl against the real stlrefined, the zip opened with libzip.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "api/params.h"
#include "core/error.h"
#include "subprocess.h"
#include "test_stl.h"
#include "test_zip.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using api::RawParams;

template <class Fn>
Error error_of(Fn&& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return e;
  }
  ADD_FAILURE() << "no Error thrown";
  return Error(ErrorCode::Internal, "none", "none");
}

// --- parameters

TEST(SliceParams, Defaults) {
  const api::SliceRequest r = api::parse_slice_params({}, {});
  EXPECT_DOUBLE_EQ(r.slice.params.layer_height, 0.1);
  EXPECT_EQ(r.slice.format, slicer::SliceFormat::Json);
  EXPECT_FALSE(r.slice.params.z_min);
  EXPECT_TRUE(r.slice.params.heights.empty());
  EXPECT_EQ(r.slice.params.max_points, api::RequestLimits{}.max_slice_points);
}

TEST(SliceParams, ParsesEveryField) {
  api::RequestLimits limits;
  limits.accept_threads = true;
  limits.max_slice_points = 1234;
  const api::SliceRequest r = api::parse_slice_params({{"layer_height", "0.25"},
                                                       {"format", "cli-binary"},
                                                       {"z_min", "-1.5"},
                                                       {"z_max", "2"},
                                                       {"max_layers", "50"},
                                                       {"threads", "2"},
                                                       {"weld_tolerance", "1e-6"}},
                                                      limits);
  EXPECT_DOUBLE_EQ(r.slice.params.layer_height, 0.25);
  EXPECT_EQ(r.slice.format, slicer::SliceFormat::CliBinary);
  EXPECT_DOUBLE_EQ(*r.slice.params.z_min, -1.5);
  EXPECT_DOUBLE_EQ(*r.slice.params.z_max, 2.0);
  EXPECT_EQ(r.slice.params.max_layers, 50u);
  EXPECT_EQ(r.slice.params.threads, 2);
  EXPECT_EQ(r.slice.params.max_points, 1234u);
  EXPECT_DOUBLE_EQ(r.weld_tolerance, 1e-6);

  const api::SliceRequest h = api::parse_slice_params({{"heights", "0.5, -1,2.25"}}, {});
  EXPECT_EQ(h.slice.params.heights, (std::vector<double>{0.5, -1, 2.25}));
  for (const char* f : {"json", "svg", "cli", "cli-ascii", "cli-binary"})
    EXPECT_NO_THROW(api::parse_slice_params({{"format", f}}, {})) << f;
}

TEST(SliceParams, BadValuesNameTheField) {
  const std::vector<std::pair<RawParams, std::string>> cases{
      {{{"layer_height", "0"}}, "layer_height"},
      {{{"layer_height", "-0.1"}}, "layer_height"},
      {{{"layer_height", "0.1mm"}}, "layer_height"},
      {{{"layer_height", "nan"}}, "layer_height"},
      {{{"layer_height", "1e5"}}, "layer_height"},
      {{{"format", "stl"}}, "format"},
      {{{"z_min", "x"}}, "z_min"},
      {{{"z_min", "2"}, {"z_max", "1"}}, "z_min"},
      {{{"heights", "1,,2"}}, "heights"},
      {{{"heights", "1,inf"}}, "heights"},
      {{{"heights", "1"}, {"z_min", "0"}}, "heights"},
      {{{"max_layers", "0"}}, "max_layers"},
      {{{"max_layers", "1000001"}}, "max_layers"},
      {{{"weld_tolerance", "-1"}}, "weld_tolerance"},
      {{{"threads", "2"}}, "threads"},  // the daemon decides threads itself
      {{{"layer_hight", "0.1"}}, "layer_hight"},
      {{{"format", "json"}, {"format", "svg"}}, "format"},
  };
  // Captured by name: clang 14 (the asan preset) cannot capture a structured binding.
  for (const auto& [raw, field] : cases) {
    const Error e = error_of([&raw = raw] { api::parse_slice_params(raw, {}); });
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter) << field << " " << e.what();
    EXPECT_EQ(e.field(), field) << e.what();
  }
}

TEST(RefineSliceParams, SliceAndFormat) {
  const api::RefineRequest plain = api::parse_refine_params({}, {});
  EXPECT_FALSE(plain.slice);
  const api::RefineRequest r =
      api::parse_refine_params({{"slice", "0.5"}, {"slice_format", "svg"}}, {});
  ASSERT_TRUE(r.slice);
  EXPECT_DOUBLE_EQ(r.slice->params.layer_height, 0.5);
  EXPECT_EQ(r.slice->format, slicer::SliceFormat::Svg);
  const api::RefineRequest d = api::parse_refine_params({{"slice", "0.2"}}, {});
  ASSERT_TRUE(d.slice);
  EXPECT_EQ(d.slice->format, slicer::SliceFormat::Json);

  const std::vector<std::pair<RawParams, std::string>> cases{
      {{{"slice", "0"}}, "slice"},
      {{{"slice", "abc"}}, "slice"},
      {{{"slice", "0.1"}, {"slice_format", "dxf"}}, "slice_format"},
      {{{"slice_format", "json"}}, "slice_format"},  // a format without a layer height
      {{{"slice", "0.1"}, {"slice", "0.2"}}, "slice"},
  };
  for (const auto& [raw, field] : cases) {
    const Error e = error_of([&raw = raw] { api::parse_refine_params(raw, {}); });
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter) << field << " " << e.what();
    EXPECT_EQ(e.field(), field) << e.what();
  }
}

TEST(RefineAdaptiveParams, ParsedAndFieldNamed) {
  const api::RefineRequest r = api::parse_refine_params(
      {{"scheme", "butterfly"}, {"adaptive_tol", "0.01"}, {"max_level", "3"}}, {});
  EXPECT_DOUBLE_EQ(r.refine.adaptive_tol, 0.01);
  EXPECT_EQ(r.refine.max_level, 3);
  const api::RefineRequest d = api::parse_refine_params({}, {});
  EXPECT_EQ(d.refine.adaptive_tol, 0.0);
  EXPECT_EQ(d.refine.max_level, RefineParams{}.max_level);

  // Parsing errors; the ranges themselves are RefineParams::validate's.
  const std::vector<std::pair<RawParams, std::string>> cases{
      {{{"adaptive_tol", "abc"}}, "adaptive_tol"},
      {{{"adaptive_tol", "nan"}}, "adaptive_tol"},
      {{{"adaptive_tol", ""}}, "adaptive_tol"},
      {{{"max_level", "2x"}}, "max_level"},
      {{{"max_level", "2.5"}}, "max_level"},
      {{{"max_level", "1e400"}}, "max_level"},
      {{{"max_level", "1"}, {"max_level", "2"}}, "max_level"},
  };
  for (const auto& [raw, field] : cases) {
    const Error e = error_of([&raw = raw] { api::parse_refine_params(raw, {}); });
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter) << field << " " << e.what();
    EXPECT_EQ(e.field(), field) << e.what();
  }
}

// --- the binaries

class SliceBinaryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "stlrefine-slice-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
    input_ = path("octahedron.stl");
    std::ofstream(input_, std::ios::binary) << binary_stl(octahedron_triangles());
  }
  void TearDown() override { fs::remove_all(dir_); }

  static std::string read(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static ProcessResult cli(std::vector<std::string> args) {
    args.insert(args.begin(), STLREFINE_CLI);
    return run_process(args, 60s);
  }

  fs::path dir_;
  std::string input_;
};

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t i = text.find(what); i != std::string::npos; i = text.find(what, i + 1)) ++n;
  return n;
}

TEST_F(SliceBinaryTest, CliSliceWritesEveryFormat) {
  // The octahedron spans z in [-1, 1]: h = 0.5 gives planes -0.75, -0.25, 0.25, 0.75.
  ProcessResult r = cli({"slice", input_, "--layer-height", "0.5", "--format", "cli", "-o",
                         path("o.cli"), "--report", path("r.json")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string cli_text = read(path("o.cli"));
  EXPECT_EQ(cli_text.rfind("$$HEADERSTART", 0), 0u);
  EXPECT_NE(cli_text.find("$$LAYERS/4"), std::string::npos);
  EXPECT_NE(cli_text.find("$$LABEL/1,octahedron"), std::string::npos);
  EXPECT_EQ(count(cli_text, "$$LAYER/"), 4u);
  EXPECT_EQ(count(cli_text, "$$POLYLINE/1,1,"), 4u);  // one outer ccw loop per layer
  const auto report = nlohmann::json::parse(read(path("r.json")));
  EXPECT_EQ(report.at("slice").at("layers"), 4);
  EXPECT_EQ(report.at("slice").at("outer_loops"), 4);

  r = cli({"slice", input_, "--heights", "0,0.5", "--format", "json", "-o", path("o.json")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(read(path("o.json")));
  ASSERT_EQ(j.at("layers").size(), 2u);
  // The z = 0 section is the square |x| + |y| = 1, area 2; at z = 0.5 its half, area 0.5.
  EXPECT_NEAR(j["layers"][0]["area"].get<double>(), 2.0, 1e-9);
  EXPECT_NEAR(j["layers"][1]["area"].get<double>(), 0.5, 1e-9);
  EXPECT_EQ(j["layers"][0]["polygons"][0]["type"], "outer");

  r = cli({"slice", input_, "--format", "svg", "-o", path("o.svg")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(read(path("o.svg")).find("<svg"), std::string::npos);
  r = cli(
      {"slice", input_, "--format", "cli-binary", "--layer-height", "0.5", "-o", path("o.bcli")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(read(path("o.bcli")).find("$$BINARY"), std::string::npos);
}

TEST_F(SliceBinaryTest, CliSliceExitCodes) {
  ProcessResult r = cli({"slice", input_, "--layer-height", "0", "-o", path("x")});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--layer-height"), std::string::npos) << r.err;
  r = cli({"slice", input_, "--format", "dxf", "-o", path("x")});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--format"), std::string::npos) << r.err;
  r = cli({"slice", input_, "--layer-height", "0.01", "--max-layers", "10", "-o", path("x")});
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_NE(r.err.find("max_layers"), std::string::npos) << r.err;
  r = cli({"slice", path("missing.stl"), "-o", path("x")});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_FALSE(fs::exists(path("x")));
}

TEST_F(SliceBinaryTest, CliRefineThenSlice) {
  ProcessResult r = cli({"refine", input_, "-o", path("r.stl"), "--levels", "2", "--slice", "0.5",
                         "--slice-format", "json", "--slice-out", path("r.json"), "--report",
                         path("report.json")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_binary_stl(read(path("r.stl"))).size(), 128u);
  const auto j = nlohmann::json::parse(read(path("r.json")));
  EXPECT_EQ(j.at("layer_count"), 4);
  const auto report = nlohmann::json::parse(read(path("report.json")));
  EXPECT_EQ(report.at("slice").at("layers"), 4);

  r = cli({"refine", input_, "-o", path("x.stl"), "--slice", "0.5"});
  EXPECT_EQ(r.exit_code, 2);  // --slice needs --slice-out
  r = cli({"refine", input_, "-o", path("x.stl"), "--slice-format", "cli", "--slice-out",
           path("x.cli")});
  EXPECT_EQ(r.exit_code, 2);
  r = cli({"refine", input_, "-o", path("x.stl"), "--slice", "-1", "--slice-out", path("x.cli")});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--slice"), std::string::npos) << r.err;
  r = cli({"refine", input_, "-o", path("x.stl"), "--max-level", "x"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--max-level"), std::string::npos) << r.err;
  r = cli({"refine", input_, "-o", path("x.stl"), "--adaptive-tol", "abc"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--adaptive-tol"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("x.stl")));
}

// --- HTTP with curl against the stlrefined binary

struct CurlAnswer {
  int status = 0;
  std::string headers, body;
};

class SliceHttpTest : public SliceBinaryTest {
 protected:
  void SetUp() override {
    if (!fs::exists("/usr/bin/curl")) GTEST_SKIP() << "curl is not installed";
    SliceBinaryTest::SetUp();
    daemon_ = std::make_unique<Child>(std::vector<std::string>{STLREFINED, "--port", "0"});
    const std::string line = daemon_->read_line(10s);
    std::smatch m;
    ASSERT_TRUE(std::regex_match(line, m, std::regex(R"(^listening on (http://[0-9.]+:[0-9]+)$)")))
        << line << daemon_->stderr_text();
    url_ = m[1].str();
  }

  // curl --data-binary @file URL, with curl's own defaults.
  CurlAnswer post(const std::string& file, const std::string& target) {
    std::string data_arg = "@";
    data_arg += file;
    std::string url = url_;
    url += target;
    const ProcessResult r =
        run_process({"/usr/bin/curl", "-sS", "--data-binary", data_arg, "-D", path("headers"), "-o",
                     path("body"), "-w", "%{http_code}", url});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return {std::atoi(r.out.c_str()), read(path("headers")), read(path("body"))};
  }

  std::unique_ptr<Child> daemon_;
  std::string url_;
};

TEST_F(SliceHttpTest, SliceRoute) {
  const std::string fandisk = STLREFINE_EXAMPLES_DIR "/fandisk.stl";
  CurlAnswer a = post(fandisk, "/v1/slice?layer_height=0.5&format=json");
  ASSERT_EQ(a.status, 200) << a.body;
  EXPECT_NE(a.headers.find("Content-Type: application/json"), std::string::npos) << a.headers;
  EXPECT_NE(a.headers.find("X-Stlrefine-Report: {"), std::string::npos);
  const auto j = nlohmann::json::parse(a.body);
  EXPECT_EQ(j.at("format"), "stlrefine-slices");
  EXPECT_GT(j.at("layer_count").get<int>(), 0);
  for (const auto& layer : j.at("layers")) EXPECT_TRUE(layer.at("open").empty());

  a = post(fandisk, "/v1/slice?layer_height=0.5&format=cli&z_min=-2&z_max=-1");
  ASSERT_EQ(a.status, 200) << a.body;
  EXPECT_EQ(a.body.rfind("$$HEADERSTART", 0), 0u);
  EXPECT_NE(a.body.find("$$LAYERS/2"), std::string::npos);
  a = post(fandisk, "/v1/slice?layer_height=0.5&format=svg");
  ASSERT_EQ(a.status, 200);
  EXPECT_NE(a.headers.find("Content-Type: image/svg+xml"), std::string::npos) << a.headers;
}

TEST_F(SliceHttpTest, ErrorsNameTheFieldAndTheServerKeepsServing) {
  const std::string fandisk = STLREFINE_EXAMPLES_DIR "/fandisk.stl";
  CurlAnswer a = post(fandisk, "/v1/slice?layer_height=0");
  EXPECT_EQ(a.status, 400);
  EXPECT_NE(a.headers.find("application/problem+json"), std::string::npos);
  EXPECT_EQ(nlohmann::json::parse(a.body).at("field"), "layer_height");

  a = post(fandisk, "/v1/slice?format=dxf");
  EXPECT_EQ(a.status, 400);
  EXPECT_EQ(nlohmann::json::parse(a.body).at("field"), "format");
  a = post(fandisk, "/v1/slice?layer_height=0.1&color=red");
  EXPECT_EQ(a.status, 400);
  EXPECT_EQ(nlohmann::json::parse(a.body).at("field"), "color");

  // Too many layers: 422 from the plan, before any contour work.
  a = post(fandisk, "/v1/slice?layer_height=0.001&max_layers=10");
  EXPECT_EQ(a.status, 422) << a.body;
  auto p = nlohmann::json::parse(a.body);
  EXPECT_EQ(p.at("type"), "urn:stlrefine:problem:budget-exceeded");
  EXPECT_EQ(p.at("field"), "max_layers");
  a = post(fandisk, "/v1/refine?levels=1&slice=0.5&slice_format=pdf");
  EXPECT_EQ(a.status, 400);
  EXPECT_EQ(nlohmann::json::parse(a.body).at("field"), "slice_format");
  a = post(fandisk, "/v1/refine?levels=1&slice=-0.5");
  EXPECT_EQ(a.status, 400);
  EXPECT_EQ(nlohmann::json::parse(a.body).at("field"), "slice");
  a = post(fandisk, "/v1/refine?levels=1&max_level=abc");
  EXPECT_EQ(a.status, 400);
  EXPECT_EQ(nlohmann::json::parse(a.body).at("field"), "max_level");
  a = post(fandisk, "/v1/refine?levels=1&adaptive_tol=x");
  EXPECT_EQ(a.status, 400);
  EXPECT_EQ(nlohmann::json::parse(a.body).at("field"), "adaptive_tol");
  const std::string junk = path("junk.stl");
  std::ofstream(junk, std::ios::binary) << "solid x\nfacet normal 0 0 1\nouter loop\n";
  a = post(junk, "/v1/slice?layer_height=0.5");
  EXPECT_EQ(a.status, 422);

  // Still serving.
  a = post(fandisk, "/v1/slice?layer_height=1");
  EXPECT_EQ(a.status, 200) << a.body;
}

TEST_F(SliceHttpTest, RefineWithSliceAnswersOneZip) {
  const std::string fandisk = STLREFINE_EXAMPLES_DIR "/fandisk.stl";
  // Without slice: the refined STL, the same bytes as the CLI writes.
  CurlAnswer plain = post(fandisk, "/v1/refine?scheme=butterfly&levels=1");
  ASSERT_EQ(plain.status, 200);
  EXPECT_NE(plain.headers.find("Content-Type: model/stl"), std::string::npos);
  ASSERT_EQ(cli({"refine", fandisk, "-o", path("cli.stl"), "--levels", "1"}).exit_code, 0);
  EXPECT_TRUE(plain.body == read(path("cli.stl")));

  const CurlAnswer a =
      post(fandisk, "/v1/refine?scheme=butterfly&levels=1&slice=0.5&slice_format=json");
  ASSERT_EQ(a.status, 200) << a.body;
  EXPECT_NE(a.headers.find("Content-Type: application/zip"), std::string::npos) << a.headers;
  EXPECT_NE(a.headers.find("refined.zip"), std::string::npos);
  const auto entries = unzip(a.body);
  ASSERT_EQ(entries.size(), 3u);
  ASSERT_TRUE(entries.count("refined.stl"));
  EXPECT_TRUE(entries.at("refined.stl") == plain.body);
  ASSERT_TRUE(entries.count("slices.json"));
  const auto j = nlohmann::json::parse(entries.at("slices.json"));
  EXPECT_GT(j.at("layer_count").get<int>(), 0);
  ASSERT_TRUE(entries.count("report.json"));
  const auto report = nlohmann::json::parse(entries.at("report.json"));
  EXPECT_EQ(report.at("slice").at("layers"), j.at("layer_count"));
  EXPECT_EQ(report.at("output").at("faces"), 4 * 12946);

  const CurlAnswer b = post(fandisk, "/v1/refine?levels=1&slice=0.5&slice_format=cli-binary");
  ASSERT_EQ(b.status, 200);
  const auto bin = unzip(b.body);
  ASSERT_TRUE(bin.count("slices.cli"));
  EXPECT_NE(bin.at("slices.cli").find("$$BINARY"), std::string::npos);
}

}  // namespace
}  // namespace stlrefine::test
