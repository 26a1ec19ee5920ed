// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "daemon_check.h"

#include <gtest/gtest.h>
#include <httplib.h>
#include <unistd.h>

#include <csignal>
#include <nlohmann/json.hpp>

#include "deploy_files.h"
#include "http_test_client.h"
#include "subprocess.h"
#include "test_stl.h"

namespace stlrefine::test {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

TempDir::TempDir(const std::string& tag) {
  std::string tmpl = (fs::temp_directory_path() / ("stlrefine-" + tag + "-XXXXXX")).string();
  if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path_ = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

std::string daemon_help() {
  const ProcessResult r = run_process({STLREFINED, "--help"}, 20s);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return r.out;
}

std::vector<std::string> rewrite_for_test_machine(std::vector<std::string> argv,
                                                  const TestMachineRewrite& rewrite) {
  if (argv.empty()) {
    ADD_FAILURE() << "empty argument vector";
    return argv;
  }
  argv[0] = rewrite.binary;
  EXPECT_TRUE(set_flag(argv, "--host", "127.0.0.1")) << "no --host";
  EXPECT_TRUE(set_flag(argv, "--port", "0")) << "no --port";
  EXPECT_TRUE(set_flag(argv, "--data-dir", rewrite.data_dir.string())) << "no --data-dir";
  return argv;
}

void expect_serves(const std::vector<std::string>& argv, const std::string& health_path,
                   const fs::path& data_dir) {
  SCOPED_TRACE(::testing::PrintToString(argv));
  Child child(argv);
  const int port = listening_port(child, 20s);
  ASSERT_GT(port, 0) << "the daemon did not start; exit " << child.wait(5s) << "\n"
                     << child.stderr_text();

  httplib::Client client("127.0.0.1", port);
  const auto health = client.Get(health_path);
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200) << health->body;

  // --data-dir: a job's input and record are written under it.
  const auto job =
      client.Post("/v1/jobs?levels=1", binary_stl(octahedron_triangles()), "model/stl");
  ASSERT_TRUE(job);
  ASSERT_EQ(job->status, 202) << job->body;
  const std::string location = job->get_header_value("Location");
  const std::string id = location.substr(location.rfind('/') + 1);
  ASSERT_FALSE(id.empty()) << location;
  EXPECT_TRUE(fs::is_directory(data_dir / id)) << data_dir / id;

  // --max-body-mib: refused from the announced length, before any body byte is sent.
  const std::string help = daemon_help();
  const std::uint64_t mib =
      std::stoull(flag_value(argv, "--max-body-mib")
                      .value_or(help_default(help, "--max-body-mib").value_or("0")));
  ASSERT_GT(mib, 0u);
  const std::uint64_t limit = mib << 20;
  const std::string head =
      "POST /v1/refine HTTP/1.1\r\nHost: stlrefine\r\nContent-Type: model/stl\r\n"
      "Content-Length: " +
      std::to_string(limit + 1) + "\r\n\r\n";
  const auto answers = parse_responses(stlrefine::test::exchange(port, head));
  ASSERT_FALSE(answers.empty());
  EXPECT_EQ(answers.front().status, 413);
  const auto problem = nlohmann::json::parse(answers.front().body, nullptr, false);
  EXPECT_EQ(problem.value("max_body_bytes", std::uint64_t{0}), limit) << answers.front().body;

  // SIGTERM: a clean stop (the job above, one octahedron level, is long done; nothing waits
  // for the grace).
  child.signal(SIGTERM);
  EXPECT_EQ(child.wait(20s), 0) << child.stderr_text();
}

}  // namespace stlrefine::test
