// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// loop-g2 and butterfly-g1 end to end: `kappa` and `ramp_steps` parsed by api/ (ranges
// from core), the stlrefine CLI (`refine --scheme loop-g2 --kappa`, `spectrum`), and
// POST /v1/refine of stlrefined with both schemes.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>

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

TEST(SpectralParams, KappaAndRampParsedWithDefaults) {
  const api::RefineRequest r =
      api::parse_refine_params({{"scheme", "loop-g2"}, {"kappa", "0.25"}, {"ramp_steps", "6"}}, {});
  EXPECT_EQ(r.refine.scheme, "loop-g2");
  EXPECT_EQ(r.refine.scheme_options.find("kappa"), 0.25);
  EXPECT_EQ(r.refine.scheme_options.find("ramp_steps"), 6.0);
  const api::RefineRequest d = api::parse_refine_params({{"scheme", "butterfly-g1"}}, {});
  EXPECT_TRUE(d.refine.scheme_options.empty());
  EXPECT_EQ(find_scheme_option("kappa")->default_value, 0.5);
  EXPECT_EQ(find_scheme_option("ramp_steps")->default_value, 0);
  EXPECT_NO_THROW(api::parse_refine_params({{"kappa", "1"}}, {}));
}

TEST(SpectralParams, ErrorsNameTheField) {
  const std::vector<std::tuple<api::RawParams, std::string, std::string>> cases{
      {{{"kappa", "0"}}, "kappa", "out_of_range"},
      {{{"kappa", "-0.5"}}, "kappa", "out_of_range"},
      {{{"kappa", "1.01"}}, "kappa", "out_of_range"},
      {{{"kappa", "nan"}}, "kappa", "not_a_number"},
      {{{"kappa", "x"}}, "kappa", "not_a_number"},
      {{{"ramp_steps", "9"}}, "ramp_steps", "out_of_range"},
      {{{"ramp_steps", "-1"}}, "ramp_steps", "out_of_range"},
      {{{"ramp_steps", "2.5"}}, "ramp_steps", "not_a_number"},
      {{{"scheme", "loop-g3"}}, "scheme", "unknown_scheme"},
  };
  for (const auto& [raw, field, reason] : cases) {
    const Error e = refine_error(raw);
    EXPECT_EQ(e.code(), ErrorCode::InvalidParameter) << field << " " << e.what();
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_EQ(e.reason(), reason) << e.what();
  }
}

TEST(SpectralParams, AdaptiveModeIsRefused) {
  // Neither scheme is interpolating in the adaptive mode's sense (neighbours move).
  for (const char* scheme : {"loop-g2", "butterfly-g1"}) {
    const Error e = refine_error({{"scheme", scheme}, {"adaptive_tol", "0.1"}});
    EXPECT_EQ(e.field(), "adaptive_tol") << scheme;
  }
}

class SpectralBinaryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "stlrefine-spectral-XXXXXX").string();
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
    return run_process(args, 120s);
  }

  fs::path dir_;
  std::string input_;
};

TEST_F(SpectralBinaryTest, CliRefineWithBothSchemes) {
  const auto input = octahedron_triangles();
  ProcessResult r = cli({"refine", input_, "-o", path("g1.stl"), "--scheme", "butterfly-g1",
                         "--levels", "3", "--crease-angle", "180"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_binary_stl(read(path("g1.stl"))).size(), 8u * 64u);
  EXPECT_TRUE(corners_preserved(input, read_binary_stl(read(path("g1.stl")))));
  r = cli({"refine", input_, "-o", path("g2.stl"), "--scheme", "loop-g2", "--levels", "2",
           "--kappa", "0.25", "--ramp-steps", "6"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_binary_stl(read(path("g2.stl"))).size(), 8u * 16u);
  r = cli({"refine", input_, "-o", path("bad.stl"), "--scheme", "loop-g2", "--kappa", "0"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--kappa"), std::string::npos) << r.err;
  r = cli({"refine", input_, "-o", path("bad.stl"), "--scheme", "loop-g2", "--ramp-steps", "99"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--ramp-steps"), std::string::npos) << r.err;
}

TEST_F(SpectralBinaryTest, CliSpectrum) {
  // One valence: one eigenvalue per line; Loop's lambda at n = 7 is 3/8 + cos(2 pi/7)/4.
  ProcessResult r = cli({"spectrum", "--scheme", "loop", "--valence", "7"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("\n0.530872  0.530872  1  2  2\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("C1 (Reif): yes; G2 eigenvalue condition: no"), std::string::npos) << r.out;
  // loop-g2 moves the frequency-2 pair to lambda^2 / 2 and meets the G2 condition.
  r = cli({"spectrum", "--scheme", "loop-g2", "--valence", "7"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("\n0.140913  0.140913  2  2  2\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("G2 eigenvalue condition: yes"), std::string::npos) << r.out;
  // A range: a Markdown table, one row per valence; the modified butterfly's 1/2.
  r = cli({"spectrum", "--scheme", "butterfly", "--valence", "3..5", "--count", "3"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("| 3 | 3 | 0.500000 | 1 | 2/2 |"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("| 5 | 3 | 0.500000 | 1 | 2/2 |"), std::string::npos) << r.out;
  // The base of butterfly-g1 at valence 9: the frequency-2 pair is subdominant.
  r = cli({"spectrum", "--scheme", "butterfly-g1", "--unmodified", "--valence", "9"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("# subdominant 0.497294 at frequency 2"), std::string::npos) << r.out;
  r = cli({"spectrum", "--scheme", "sqrt3-interp", "--curve"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("1.000000 0.333333 0.135802 0.111111 0.037037"), std::string::npos) << r.out;
  // Errors name the option.
  const std::vector<std::pair<std::vector<std::string>, std::string>> bad{
      {{"spectrum", "--valence", "2"}, "--valence"},
      {{"spectrum", "--valence", "9..4"}, "--valence"},
      {{"spectrum", "--valence", "x"}, "--valence"},
      {{"spectrum", "--scheme", "nope"}, "--scheme"},
      {{"spectrum", "--scheme", "loop", "--unmodified"}, "--unmodified"},
      {{"spectrum", "--scheme", "loop-g2", "--kappa", "3"}, "--kappa"},
      {{"spectrum", "--format", "csv", "--valence", "5"}, "--format"}};
  for (const auto& [args, option] : bad) {
    r = cli(args);
    EXPECT_EQ(r.exit_code, 2) << option;
    EXPECT_NE(r.err.find(option), std::string::npos) << r.err;
  }
}

TEST_F(SpectralBinaryTest, DaemonRefinesWithBothSchemes) {
  if (!fs::exists("/usr/bin/curl")) GTEST_SKIP() << "curl is not installed";
  Child daemon({STLREFINED, "--port", "0"});
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
  ASSERT_EQ(post("/v1/refine?scheme=butterfly-g1&levels=3&crease_angle=180"), 200);
  EXPECT_EQ(read_binary_stl(read(path("body"))).size(), 8u * 64u);
  EXPECT_TRUE(corners_preserved(input, read_binary_stl(read(path("body")))));
  ASSERT_EQ(post("/v1/refine?scheme=loop-g2&levels=2&kappa=0.3&ramp_steps=6"), 200);
  EXPECT_EQ(read_binary_stl(read(path("body"))).size(), 8u * 16u);
  EXPECT_EQ(post("/v1/refine?scheme=loop-g2&kappa=0"), 400);
  EXPECT_EQ(nlohmann::json::parse(read(path("body"))).at("field"), "kappa");
  EXPECT_EQ(post("/v1/refine?scheme=loop-g2&ramp_steps=20"), 400);
  EXPECT_EQ(nlohmann::json::parse(read(path("body"))).at("field"), "ramp_steps");
}

}  // namespace
}  // namespace stlrefine::test
