// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// examples/stlrefine_client.py (issue 19 item 6: a Python client, standard library only)
// against the real daemon: upload as a form, follow the job's events (or poll) until
// `state` says done, download every result under the name the server gives it
// (Content-Disposition); a refused submission exits 2 quoting the parameter.

#include <gtest/gtest.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

TEST(ExampleClient, SubmitsFollowsAndDownloads) {
  if (!fs::exists("/usr/bin/python3")) GTEST_SKIP() << "python3 is not installed";
  const fs::path dir =
      fs::temp_directory_path() / ("stlrefine_client_" + std::to_string(::getpid()));
  fs::create_directories(dir / "data");
  fs::copy_file(fs::path(STLREFINE_EXAMPLES_DIR) / "fandisk.stl", dir / "fandisk.stl");
  Child daemon({STLREFINED, "--port", "0", "--data-dir", (dir / "data").string()});
  const int port = listening_port(daemon);
  ASSERT_GT(port, 0) << daemon.stderr_text();
  const std::string url = "http://127.0.0.1:" + std::to_string(port);
  const std::string client = (fs::path(STLREFINE_EXAMPLES_DIR) / "stlrefine_client.py").string();

  ProcessResult r = run_process({"/usr/bin/python3", client, (dir / "fandisk.stl").string(),
                                 "--url", url, "--poll", "0.1", "--param", "scheme=loop", "--param",
                                 "levels=1", "--param", "slice=0.5", "--param", "slice_format=svg"},
                                120s);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.err.find("done"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("polling"), std::string::npos) << r.err;  // followed by events
  const std::vector<Triangle> input = read_binary_stl(read_file(dir / "fandisk.stl"));
  const std::vector<Triangle> refined = read_binary_stl(read_file(dir / "fandisk_refined.stl"));
  EXPECT_EQ(refined.size(), 4 * input.size());
  const nlohmann::json report = nlohmann::json::parse(read_file(dir / "fandisk_report.json"));
  EXPECT_EQ(report["scheme"], "loop");
  // The contours carry the part's name (the server kept it from the upload).
  EXPECT_NE(read_file(dir / "fandisk_slices.svg").find("<title>fandisk"), std::string::npos);
  // Every file it printed exists.
  std::size_t printed = 0;
  for (std::size_t at = 0; (at = r.out.find('\n', at)) != std::string::npos; ++at) ++printed;
  EXPECT_EQ(printed, 3u) << r.out;

  // Polling instead of events gives the same files.
  fs::remove(dir / "fandisk_refined.stl");
  r = run_process({"/usr/bin/python3", client, (dir / "fandisk.stl").string(), "--url", url,
                   "--poll", "0.1", "--no-events", "--param", "scheme=loop", "--param", "levels=1"},
                  120s);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(read_binary_stl(read_file(dir / "fandisk_refined.stl")).size(), 4 * input.size());

  // A refused submission: exit 2, the problem quoting the parameter.
  r = run_process({"/usr/bin/python3", client, (dir / "fandisk.stl").string(), "--url", url,
                   "--param", "levels=99"},
                  60s);
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("field levels"), std::string::npos) << r.err;
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(30s), 0) << daemon.stderr_text();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace stlrefine::test
