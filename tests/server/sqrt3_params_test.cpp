// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The sqrt3 schemes' parameters end to end: `alpha`, `alpha_features` and the adaptive
// mode's `adaptive_angle` / `adaptive_tol` / `max_level` parsed by api/ (ranges from core),
// `--alpha` / `--alpha-features` / `--adaptive-angle` on the stlrefine CLI, and the same
// query parameters on POST /v1/refine and POST /v1/jobs of stlrefined.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

#include "api/params.h"
#include "core/error.h"
#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

Error refine_error(const api::RawParams& raw) {
  try {
    api::parse_refine_params(raw, {});
  } catch (const Error& e) {
    return e;
  }
  ADD_FAILURE() << "no Error thrown";
  return Error(ErrorCode::Internal, "none", "none");
}

TEST(Sqrt3Params, AlphaParsedWithDefaults) {
  const api::RefineRequest r = api::parse_refine_params(
      {{"scheme", "sqrt3-unified"}, {"alpha", "0.25"}, {"alpha_features", "0.75"}}, {});
  EXPECT_EQ(r.refine.scheme, "sqrt3-unified");
  EXPECT_EQ(r.refine.scheme_options.find("alpha"), 0.25);
  EXPECT_EQ(r.refine.scheme_options.find("alpha_features"), 0.75);
  const api::RefineRequest d = api::parse_refine_params({{"scheme", "sqrt3"}}, {});
  // Absent options are not set: the scheme is made with its declared defaults.
  EXPECT_TRUE(d.refine.scheme_options.empty());
  EXPECT_EQ(find_scheme_option("alpha")->default_value, 1.0);
  EXPECT_EQ(find_scheme_option("alpha_features")->default_value, 1.0);
  for (const char* scheme : {"sqrt3", "sqrt3-interp", "sqrt3-unified"})
    EXPECT_NO_THROW(api::parse_refine_params({{"scheme", scheme}}, {})) << scheme;
}

TEST(Sqrt3Params, AlphaErrorsNameTheField) {
  const std::vector<std::tuple<api::RawParams, std::string, std::string>> cases{
      {{{"alpha", "abc"}}, "alpha", "not_a_number"},
      {{{"alpha", "nan"}}, "alpha", "not_a_number"},
      {{{"alpha", ""}}, "alpha", "not_a_number"},
      {{{"alpha", "1.5"}}, "alpha", "out_of_range"},
      {{{"alpha", "-0.01"}}, "alpha", "out_of_range"},
      {{{"alpha_features", "2"}}, "alpha_features", "out_of_range"},
      {{{"alpha_features", "0.5x"}}, "alpha_features", "not_a_number"},
      {{{"alpha", "0.5"}, {"alpha", "0.5"}}, "alpha", "duplicate_parameter"},
  };
  for (const auto& [raw, field, reason] : cases) {
    const Error e = refine_error(raw);
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter) << field << " " << e.what();
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_EQ(e.reason(), reason) << e.what();
  }
}

TEST(Sqrt3Params, AdaptiveAngleParsedAndChecked) {
  const api::RefineRequest r = api::parse_refine_params(
      {{"scheme", "sqrt3-interp"}, {"adaptive_angle", "20"}, {"max_level", "5"}}, {});
  EXPECT_DOUBLE_EQ(r.refine.adaptive_angle, 20);
  EXPECT_EQ(r.refine.max_level, 5);
  EXPECT_TRUE(r.refine.adaptive());
  EXPECT_EQ(api::parse_refine_params({}, {}).refine.adaptive_angle, 0.0);
  EXPECT_NO_THROW(
      api::parse_refine_params({{"scheme", "butterfly"}, {"adaptive_angle", "10"}}, {}));
  EXPECT_NO_THROW(api::parse_refine_params(
      {{"scheme", "sqrt3"}, {"adaptive_angle", "10"}, {"adaptive_tol", "0.01"}}, {}));
  const std::vector<std::tuple<api::RawParams, std::string, std::string>> cases{
      {{{"adaptive_angle", "abc"}}, "adaptive_angle", "not_a_number"},
      {{{"adaptive_angle", "inf"}}, "adaptive_angle", "not_a_number"},
      {{{"adaptive_angle", "181"}}, "adaptive_angle", "out_of_range"},
      {{{"adaptive_angle", "-1"}}, "adaptive_angle", "out_of_range"},
      {{{"scheme", "loop"}, {"adaptive_angle", "10"}}, "adaptive_angle", "adaptive_unsupported"},
      {{{"scheme", "sqrt3-interp"}, {"adaptive_angle", "10"}, {"max_level", "9"}},
       "max_level",
       "out_of_range"},
  };
  for (const auto& [raw, field, reason] : cases) {
    const Error e = refine_error(raw);
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter) << field << " " << e.what();
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_EQ(e.reason(), reason) << e.what();
  }
}

class Sqrt3BinaryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "stlrefine-sqrt3-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
    input_ = path("octahedron.stl");
    std::ofstream(input_, std::ios::binary) << binary_stl(octahedron_triangles());
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static std::string read(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  static ProcessResult cli(std::vector<std::string> args) {
    args.insert(args.begin(), STLREFINE_CLI);
    return run_process(args, 60s);
  }

  fs::path dir_;
  std::string input_;
};

TEST_F(Sqrt3BinaryTest, CliAlphaOptions) {
  // Crease angle 180: the octahedron's vertices are smooth, so alpha decides alone.
  const std::vector<std::string> base{"refine",   input_, "--scheme",       "sqrt3-unified",
                                      "--levels", "2",    "--crease-angle", "180"};
  auto with = [&](std::vector<std::string> extra, const std::string& out) {
    std::vector<std::string> args = base;
    args.insert(args.end(), {"-o", path(out), "--report", path(out + ".json")});
    args.insert(args.end(), extra.begin(), extra.end());
    return cli(args);
  };
  const auto input = octahedron_triangles();
  ProcessResult r = with({}, "interp.stl");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_binary_stl(read(path("interp.stl"))).size(), 8u * 9u);
  EXPECT_TRUE(corners_preserved(input, read_binary_stl(read(path("interp.stl")))));

  r = with({"--alpha", "0"}, "approx.stl");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(corners_preserved(input, read_binary_stl(read(path("approx.stl")))));
  const auto report = nlohmann::json::parse(read(path("approx.stl.json")));
  EXPECT_EQ(report.at("output").at("faces"), 72);

  r = with({"--alpha", "0.5", "--alpha-features", "0"}, "blend.stl");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_binary_stl(read(path("blend.stl"))).size(), 72u);

  r = with({"--alpha", "2"}, "bad.stl");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--alpha"), std::string::npos) << r.err;
  r = with({"--alpha-features", "x"}, "bad.stl");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--alpha-features"), std::string::npos) << r.err;
}

TEST_F(Sqrt3BinaryTest, CliAdaptiveOptions) {
  // Crease angle 180: the octahedron is one smooth patch, so the dihedral angle decides.
  const std::vector<std::string> base{"refine",         input_, "--scheme",    "sqrt3-interp",
                                      "--crease-angle", "180",  "--max-level", "3"};
  auto with = [&](std::vector<std::string> extra, const std::string& out) {
    std::vector<std::string> args = base;
    args.insert(args.end(), {"-o", path(out), "--report", path(out + ".json")});
    args.insert(args.end(), extra.begin(), extra.end());
    return cli(args);
  };
  const auto input = octahedron_triangles();
  ProcessResult r = with({"--adaptive-angle", "20"}, "angle.stl");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto refined = read_binary_stl(read(path("angle.stl")));
  EXPECT_GT(refined.size(), 8u);
  EXPECT_LE(refined.size(), 8u * 27u);
  EXPECT_TRUE(corners_preserved(input, refined));
  const auto report = nlohmann::json::parse(read(path("angle.stl.json")));
  EXPECT_EQ(report.at("adaptive_angle"), 20.0);
  EXPECT_EQ(report.at("output").at("faces"), refined.size());
  EXPECT_GE(report.at("levels"), 1);
  EXPECT_EQ(report.at("max_input_displacement"), 0.0);

  r = with({"--adaptive-angle", "20", "--adaptive-tol", "0.001"}, "both.stl");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_GE(read_binary_stl(read(path("both.stl"))).size(), refined.size());

  r = with({"--adaptive-angle", "200"}, "bad.stl");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--adaptive-angle"), std::string::npos) << r.err;
  // The adaptive budget: an upper bound from max_level up front, then a hard stop.
  r = with({"--adaptive-angle", "1", "--max-faces", "20"}, "big.stl");
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_NE(r.err.find("max_faces"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("big.stl")));
}

TEST_F(Sqrt3BinaryTest, DaemonAlphaAndAdaptiveQueryParameters) {
  if (!fs::exists("/usr/bin/curl")) GTEST_SKIP() << "curl is not installed";
  Child daemon({STLREFINED, "--port", "0", "--data-dir", path("jobs")});
  const std::string line = daemon.read_line(10s);
  std::smatch m;
  ASSERT_TRUE(std::regex_match(line, m, std::regex(R"(^listening on (http://[0-9.]+:[0-9]+)$)")))
      << line << daemon.stderr_text();
  const std::string url = m[1].str();
  auto post = [&](const std::string& target) {
    const ProcessResult r = run_process({"/usr/bin/curl", "-sS", "--data-binary", "@" + input_,
                                         "-o", path("body"), "-w", "%{http_code}", url + target});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return std::atoi(r.out.c_str());
  };
  const auto input = octahedron_triangles();
  ASSERT_EQ(post("/v1/refine?scheme=sqrt3-unified&levels=2&crease_angle=180&alpha=0"), 200);
  const auto smoothed = read_binary_stl(read(path("body")));
  EXPECT_EQ(smoothed.size(), 72u);
  EXPECT_FALSE(corners_preserved(input, smoothed));
  ASSERT_EQ(post("/v1/refine?scheme=sqrt3-unified&levels=2&crease_angle=180&alpha=1"), 200);
  EXPECT_TRUE(corners_preserved(input, read_binary_stl(read(path("body")))));
  ASSERT_EQ(post("/v1/refine?scheme=sqrt3-unified&levels=1&alpha=0.5&alpha_features=0.25"), 200);
  ASSERT_EQ(post("/v1/refine?scheme=sqrt3-interp&levels=3"), 200);
  EXPECT_EQ(read_binary_stl(read(path("body"))).size(), 8u * 27u);

  EXPECT_EQ(post("/v1/refine?scheme=sqrt3-unified&alpha=7"), 400);
  EXPECT_EQ(nlohmann::json::parse(read(path("body"))).at("field"), "alpha");
  EXPECT_EQ(post("/v1/refine?scheme=sqrt3-unified&alpha_features=nan"), 400);
  EXPECT_EQ(nlohmann::json::parse(read(path("body"))).at("field"), "alpha_features");

  // The adaptive mode, synchronous and as a job.
  const std::string adaptive = "scheme=sqrt3-interp&crease_angle=180&adaptive_angle=20&max_level=3";
  ASSERT_EQ(post("/v1/refine?" + adaptive), 200);
  const std::size_t faces = read_binary_stl(read(path("body"))).size();
  EXPECT_GT(faces, 8u);
  EXPECT_LE(faces, 8u * 27u);
  EXPECT_EQ(post("/v1/refine?scheme=sqrt3-interp&adaptive_angle=x"), 400);
  EXPECT_EQ(nlohmann::json::parse(read(path("body"))).at("field"), "adaptive_angle");
  EXPECT_EQ(post("/v1/refine?scheme=loop&adaptive_angle=10"), 400);
  EXPECT_EQ(nlohmann::json::parse(read(path("body"))).at("field"), "adaptive_angle");
  EXPECT_EQ(post("/v1/refine?scheme=sqrt3-interp&crease_angle=180&adaptive_angle=1&max_faces=20"),
            422);
  EXPECT_EQ(nlohmann::json::parse(read(path("body"))).at("field"), "max_faces");

  ASSERT_EQ(post("/v1/jobs?" + adaptive), 202);
  const std::string job = nlohmann::json::parse(read(path("body"))).at("id");
  std::string state;
  for (int i = 0; i < 200 && state != "done" && state != "failed"; ++i) {
    const ProcessResult g =
        run_process({"/usr/bin/curl", "-sS", url + "/v1/jobs/" + job}, std::chrono::seconds(10));
    state = nlohmann::json::parse(g.out).at("state");
    if (state != "done") std::this_thread::sleep_for(50ms);
  }
  ASSERT_EQ(state, "done");
  const ProcessResult g = run_process(
      {"/usr/bin/curl", "-sS", "-o", path("job.stl"), url + "/v1/jobs/" + job + "/result.stl"});
  ASSERT_EQ(g.exit_code, 0) << g.err;
  EXPECT_EQ(read_binary_stl(read(path("job.stl"))).size(), faces);
}

}  // namespace
}  // namespace stlrefine::test
