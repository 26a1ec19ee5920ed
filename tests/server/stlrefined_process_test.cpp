// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The stlrefined binary itself: the `listening on` line, flags, and shutdown on signals.

#include <gtest/gtest.h>
#include <httplib.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <thread>

#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;

// Starts stlrefined on a free port; returns the port from its one stdout line.
int start(Child& child) {
  const int port = listening_port(child, 10s);
  if (port == 0) ADD_FAILURE() << "no `listening on` line\n" << child.stderr_text();
  return port;
}

TEST(Stlrefined, ServesAndStopsCleanlyOnSigterm) {
  Child child({STLREFINED, "--port", "0", "--compute-slots", "1", "--access-log"});
  const int port = start(child);
  ASSERT_GT(port, 0);
  httplib::Client client("127.0.0.1", port);
  auto health = client.Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  const auto input = octahedron_triangles();
  auto refined = client.Post("/v1/refine?levels=1", binary_stl(input), "model/stl");
  ASSERT_TRUE(refined);
  EXPECT_EQ(refined->status, 200);
  EXPECT_EQ(read_binary_stl(refined->body).size(), 32u);

  child.signal(SIGTERM);
  EXPECT_EQ(child.wait(10s), 0) << child.stderr_text();
  EXPECT_EQ(child.read_line(100ms), "");  // exactly one line on stdout
  // The access log is JSON lines with the request id.
  EXPECT_NE(child.stderr_text().find(
                R"("method":"POST","path":"/v1/refine","route":"/v1/refine","status":200)"),
            std::string::npos)
      << child.stderr_text();
  EXPECT_NE(child.stderr_text().find(R"("request_id":")"), std::string::npos);
}

TEST(Stlrefined, SigtermFailsQueuedJobsCancelsRunningOnesAfterTheGraceAndExits0) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("stlrefined-shutdown-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  Child child({STLREFINED, "--port", "0", "--compute-slots", "1", "--data-dir", dir.string(),
               "--shutdown-grace", "0", "--max-faces", "20000000"});
  const int port = start(child);
  ASSERT_GT(port, 0);
  httplib::Client client("127.0.0.1", port);
  std::ifstream in(std::filesystem::path(STLREFINE_EXAMPLES_DIR) / "fandisk.stl", std::ios::binary);
  const std::string fandisk((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto running = client.Post("/v1/jobs?scheme=butterfly&levels=4", fandisk, "model/stl");
  auto queued = client.Post("/v1/jobs?scheme=butterfly&levels=1", fandisk, "model/stl");
  ASSERT_TRUE(running && queued);
  ASSERT_EQ(running->status, 202);
  ASSERT_EQ(queued->status, 202);
  std::this_thread::sleep_for(300ms);
  child.signal(SIGTERM);
  EXPECT_EQ(child.wait(10s), 0) << child.stderr_text();
  auto state_of = [&](const httplib::Result& r) {
    const std::string id = r->get_header_value("Location").substr(9);
    std::ifstream job(dir / id / "job.json");
    return nlohmann::json::parse(job);
  };
  const auto q = state_of(queued);
  EXPECT_EQ(q["state"], "failed") << q.dump();
  EXPECT_EQ(q["problem"]["type"], "urn:stlrefine:problem:shutting-down");
  const auto r = state_of(running);
  EXPECT_TRUE(r["state"] == "cancelled" || r["state"] == "done") << r.dump();
  std::filesystem::remove_all(dir);
}

TEST(Stlrefined, StopsCleanlyOnSigint) {
  Child child({STLREFINED, "--port", "0"});
  ASSERT_GT(start(child), 0);
  child.signal(SIGINT);
  EXPECT_EQ(child.wait(10s), 0) << child.stderr_text();
}

TEST(Stlrefined, BadFlagsExitWith2) {
  for (const std::vector<std::string>& flags : {std::vector<std::string>{"--port", "70000"},
                                                {"--port", "80x"},
                                                {"--bogus"},
                                                {"--max-faces", "0"},
                                                {"--compute-slots", "-1"},
                                                {"--max-body-mib", "0"}}) {
    std::vector<std::string> argv{STLREFINED};
    argv.insert(argv.end(), flags.begin(), flags.end());
    const ProcessResult r = run_process(argv, 10s);
    EXPECT_EQ(r.exit_code, 2) << flags[0] << " " << r.err;
    EXPECT_EQ(r.out, "");
  }
  EXPECT_EQ(run_process({STLREFINED, "--help"}, 10s).exit_code, 0);
}

TEST(Stlrefined, PortInUseExitsWith1) {
  Child first({STLREFINED, "--port", "0"});
  const int port = start(first);
  ASSERT_GT(port, 0);
  const ProcessResult second = run_process({STLREFINED, "--port", std::to_string(port)}, 10s);
  EXPECT_EQ(second.exit_code, 1) << second.err;
  EXPECT_EQ(second.out, "");
  first.signal(SIGTERM);
  EXPECT_EQ(first.wait(10s), 0);
}

}  // namespace
}  // namespace stlrefine::test
