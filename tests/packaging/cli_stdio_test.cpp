// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// `-` as stdin / stdout in the stlrefine CLI, end to end through a shell's redirections:
// the bytes equal those of the same run on files, and stdout carries nothing else.

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "daemon_check.h"
#include "deploy_files.h"
#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

class CliStdio : public ::testing::Test {
 protected:
  void SetUp() override {
    // "part.stl": the contour files are labelled with the input's stem, and "part" for stdin.
    std::ofstream(path("part.stl"), std::ios::binary) << binary_stl(octahedron_triangles());
  }
  std::string path(const std::string& name) const { return (dir_.path() / name).string(); }

  // `stlrefine ARGS` run by /bin/sh, e.g. sh("refine - -o - < 'IN' > 'OUT'").
  static ProcessResult sh(const std::string& args) {
    return run_process({"/bin/sh", "-c", std::string("'") + STLREFINE_CLI + "' " + args}, 60s);
  }
  static std::string q(const std::string& p) { return "'" + p + "'"; }

  TempDir dir_{"cli-stdio"};
};

TEST_F(CliStdio, RefineFromStdinToStdout) {
  const ProcessResult piped =
      sh("refine - -o - --levels 2 < " + q(path("part.stl")) + " > " + q(path("piped.stl")));
  ASSERT_EQ(piped.exit_code, 0) << piped.err;
  ASSERT_EQ(
      sh("refine " + q(path("part.stl")) + " -o " + q(path("file.stl")) + " --levels 2").exit_code,
      0);
  const std::string out = read_text(path("piped.stl"));
  EXPECT_EQ(out, read_text(path("file.stl")));  // nothing but the STL on stdout
  EXPECT_EQ(read_binary_stl(out).size(), 128u);
  EXPECT_NE(piped.err.find("8 -> 128 faces"), std::string::npos) << piped.err;  // on stderr
}

TEST_F(CliStdio, RefineAsciiAndReportOnStdoutWithAFileInput) {
  const ProcessResult r = sh("refine " + q(path("part.stl")) + " -o - --ascii --report " +
                             q(path("report.json")) + " > " + q(path("out.stl")));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_text(path("out.stl")).rfind("solid", 0), 0u);
  const auto report = nlohmann::json::parse(read_text(path("report.json")));
  EXPECT_EQ(report.at("output").at("faces"), 32);

  // The report alone on stdout, the STL to a file.
  const ProcessResult j = sh("refine - -o " + q(path("b.stl")) + " --report - < " +
                             q(path("part.stl")) + " > " + q(path("report2.json")));
  ASSERT_EQ(j.exit_code, 0) << j.err;
  EXPECT_EQ(nlohmann::json::parse(read_text(path("report2.json"))).at("output").at("faces"), 32);
  EXPECT_EQ(read_binary_stl(read_text(path("b.stl"))).size(), 32u);
}

TEST_F(CliStdio, InfoReadsStdin) {
  const ProcessResult piped = sh("info - < " + q(path("part.stl")));
  ASSERT_EQ(piped.exit_code, 0) << piped.err;
  const ProcessResult file = sh("info " + q(path("part.stl")));
  ASSERT_EQ(file.exit_code, 0) << file.err;
  auto a = nlohmann::json::parse(piped.out), b = nlohmann::json::parse(file.out);
  EXPECT_EQ(a.at("mesh").at("faces"), 8);
  a.erase("seconds");
  b.erase("seconds");
  EXPECT_EQ(a, b);
}

TEST_F(CliStdio, SliceFromStdinToStdout) {
  const ProcessResult piped = sh("slice - -o - --layer-height 0.25 --format svg < " +
                                 q(path("part.stl")) + " > " + q(path("piped.svg")));
  ASSERT_EQ(piped.exit_code, 0) << piped.err;
  ASSERT_EQ(sh("slice " + q(path("part.stl")) + " -o " + q(path("file.svg")) +
               " --layer-height 0.25 --format svg")
                .exit_code,
            0);
  const std::string svg = read_text(path("piped.svg"));
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_EQ(svg, read_text(path("file.svg")));
  EXPECT_NE(piped.err.find("layers"), std::string::npos) << piped.err;
}

TEST_F(CliStdio, AtMostOneOutputOnStdout) {
  for (const std::string& args : {
           "refine - -o - --report - < " + q(path("part.stl")),
           "refine - -o - --slice 0.5 --slice-out - < " + q(path("part.stl")),
           "slice - -o - --report - < " + q(path("part.stl")),
           "info - --curvature - < " + q(path("part.stl")),
       }) {
    const ProcessResult r = sh(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_EQ(r.out, "") << args;
    EXPECT_NE(r.err.find("stdout already carries"), std::string::npos) << r.err;
  }
}

TEST_F(CliStdio, BadStdinExits3NamingStdin) {
  const ProcessResult empty = sh("refine - -o - < /dev/null");
  EXPECT_EQ(empty.exit_code, 3) << empty.err;
  EXPECT_EQ(empty.out, "");
  const ProcessResult text = sh("info - < " + q(STLREFINE_SOURCE_DIR "/LICENSE"));
  EXPECT_EQ(text.exit_code, 3) << text.err;
  EXPECT_EQ(text.err.rfind("stlrefine: stdin: ", 0), 0u) << text.err;
}

}  // namespace
}  // namespace stlrefine::test
