// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The stlrefine binary: output files, the info report, and the documented exit codes
// (0 ok, 2 usage / parameter, 3 input file, 4 face budget, 1 internal / output).

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "stlrefine-cli-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
    input_ = write("octahedron.stl", binary_stl(octahedron_triangles()));
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& bytes) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << bytes;
    return p.string();
  }
  static std::string read(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
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

TEST_F(CliTest, RefineWritesTheStlAndTheReport) {
  const ProcessResult r = cli({"refine", input_, "-o", path("out.stl"), "--scheme", "butterfly",
                               "--levels", "2", "--report", path("report.json")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto input = octahedron_triangles();
  const auto output = read_binary_stl(read(path("out.stl")));
  EXPECT_EQ(output.size(), 128u);
  EXPECT_TRUE(corners_preserved(input, output));
  const auto report = nlohmann::json::parse(read(path("report.json")));
  EXPECT_EQ(report.at("output").at("faces"), 128);
  // stderr is not a terminal here: a summary line, no progress redraws.
  EXPECT_EQ(r.err.find('\r'), std::string::npos);
  EXPECT_EQ(r.out, "");
}

TEST_F(CliTest, RefineMatchesThePipeline) {
  // The CLI and the daemon share api/: same parameters, same bytes.
  ASSERT_EQ(cli({"refine", input_, "-o", path("a.stl"), "--levels", "1"}).exit_code, 0);
  ASSERT_EQ(cli({"refine", input_, "--output", path("b.stl"), "--levels", "1", "--threads", "1"})
                .exit_code,
            0);
  EXPECT_EQ(read(path("a.stl")), read(path("b.stl")));
}

TEST_F(CliTest, AsciiOutput) {
  ASSERT_EQ(cli({"refine", input_, "-o", path("out.stl"), "--ascii"}).exit_code, 0);
  EXPECT_EQ(read(path("out.stl")).rfind("solid", 0), 0u);
}

TEST_F(CliTest, InfoPrintsTheReport) {
  const ProcessResult r = cli({"info", input_, "--crease-angle", "80"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("mesh").at("faces"), 8);
  EXPECT_EQ(j.at("mesh").at("genus"), 0);
  EXPECT_EQ(j.at("features").at("crease_angle_deg"), 80.0);
}

TEST_F(CliTest, BadUsageOrParameterExits2) {
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {},
           {"frobnicate"},
           {"refine", input_},  // no -o
           {"refine", input_, "-o", path("x.stl"), "--levels", "2x"},
           {"refine", input_, "-o", path("x.stl"), "--levels", "9"},
           {"refine", input_, "-o", path("x.stl"), "--scheme", "nope"},
           {"refine", input_, "-o", path("x.stl"), "--crease-angle", "nan"},
           {"refine", input_, "-o", path("x.stl"), "--threads", "-1"},
           {"info", input_, "--weld-tolerance", ""},
           {"info", input_, "--bogus"},
       }) {
    const ProcessResult r = cli(args);
    EXPECT_EQ(r.exit_code, 2) << ::testing::PrintToString(args) << r.err;
  }
  EXPECT_FALSE(fs::exists(path("x.stl")));
  const ProcessResult r = cli({"refine", input_, "-o", path("x.stl"), "--crease-angle", "200"});
  EXPECT_NE(r.err.find("--crease-angle"), std::string::npos) << r.err;
}

TEST_F(CliTest, BadInputFileExits3) {
  auto tris = octahedron_triangles();
  tris[1][0][1] = std::numeric_limits<float>::quiet_NaN();
  const std::string nan = write("nan.stl", binary_stl(tris));
  ProcessResult r = cli({"refine", nan, "-o", path("x.stl")});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("byte 150"), std::string::npos) << r.err;
  EXPECT_EQ(cli({"info", path("missing.stl")}).exit_code, 3);
  EXPECT_EQ(cli({"info", write("empty.stl", "")}).exit_code, 3);
  EXPECT_EQ(cli({"info", dir_.string()}).exit_code, 3);  // a directory
  EXPECT_FALSE(fs::exists(path("x.stl")));
}

TEST_F(CliTest, FaceBudgetExits4) {
  const ProcessResult r =
      cli({"refine", input_, "-o", path("x.stl"), "--levels", "3", "--max-faces", "100"});
  EXPECT_EQ(r.exit_code, 4);
  EXPECT_NE(r.err.find("512"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("x.stl")));
}

TEST_F(CliTest, UnwritableOutputExits1) {
  const ProcessResult r = cli({"refine", input_, "-o", path("no/such/dir/out.stl")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
}

TEST_F(CliTest, HelpAndVersionExit0) {
  EXPECT_EQ(cli({"--help"}).exit_code, 0);
  EXPECT_EQ(cli({"refine", "--help"}).exit_code, 0);
  EXPECT_EQ(cli({"--version"}).exit_code, 0);
}

}  // namespace
}  // namespace stlrefine::test
