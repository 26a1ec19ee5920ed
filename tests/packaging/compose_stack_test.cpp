// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// docker/: the daemon's argument vector as docker would build it from the Dockerfile's
// ENTRYPOINT / CMD and compose's `command:`, run for real; the health checks; nginx's limits
// against the daemon's. No docker is needed: the files are read as docker, compose and
// nginx read them (tests/packaging/deploy_files.h).

#include <gtest/gtest.h>

#include <regex>

#include "daemon_check.h"
#include "deploy_files.h"
#include "subprocess.h"

namespace stlrefine::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

const fs::path kDocker = fs::path(STLREFINE_SOURCE_DIR) / "docker";

struct Stack {
  std::string dockerfile = read_text(kDocker / "Dockerfile");
  std::string compose = read_text(kDocker / "compose.yaml");
  std::string nginx = read_text(kDocker / "nginx.conf");
  std::vector<std::string> argv = container_argv(dockerfile, compose, "stlrefined");
};

// "http://127.0.0.1:8080/healthz" in a health check command -> {port, path}.
std::pair<std::string, std::string> probe_of(const std::string& command) {
  std::smatch m;
  const std::regex url(R"(http://(127\.0\.0\.1|localhost):([0-9]+)(/[^\s"']*))");
  if (!std::regex_search(command, m, url)) return {};
  return {m[2], m[3]};
}

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : " ") + item;
  return out;
}

TEST(ComposeStack, ArgumentVectorGivesEveryFlagOnce) {
  const Stack stack;
  ASSERT_FALSE(stack.argv.empty());
  EXPECT_EQ(stack.argv[0], "stlrefined");  // /usr/local/bin in the image
  EXPECT_EQ(repeated_flags(stack.argv), std::vector<std::string>{}) << joined(stack.argv);
  // Reachable from the nginx container, on the port nginx's upstream names.
  EXPECT_EQ(flag_value(stack.argv, "--host"), "0.0.0.0");
  const std::string port = flag_value(stack.argv, "--port").value_or("");
  EXPECT_NE(stack.nginx.find("server stlrefined:" + port + ";"), std::string::npos) << port;
  // The data directory is the image's VOLUME and where compose mounts the jobs volume.
  const std::string data = flag_value(stack.argv, "--data-dir").value_or("");
  ASSERT_FALSE(data.empty());
  const auto stage = final_stage(stack.dockerfile);
  EXPECT_EQ(instruction(stage, "VOLUME"), data);
  const auto volumes = yaml_get(stack.compose, {"services", "stlrefined", "volumes"});
  ASSERT_TRUE(volumes && volumes->is_sequence);
  EXPECT_EQ(volumes->items, std::vector<std::string>{"jobs:" + data});
}

// The crash loop of issue 19: a flag in both ENTRYPOINT and `command:` makes the daemon
// exit 2 before it listens. This is why the test above insists on "once".
TEST(ComposeStack, DaemonRefusesAFlagGivenTwice) {
  TempDir data("compose-twice");
  std::vector<std::string> argv = rewrite_for_test_machine(Stack().argv, {STLREFINED, data.path()});
  argv.insert(argv.end(), {"--data-dir", data.path().string()});
  const ProcessResult r = run_process(argv, 20s);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--data-dir"), std::string::npos) << r.err;
}

// What `docker compose up` starts: ENTRYPOINT + command, with only the binary's path, the
// listen address (loopback, not every interface), the port (a free one, not 8080) and the
// data directory (a temporary one, not /data) rewritten for the test machine.
TEST(ComposeStack, DaemonStartsHealthyWithTheComposeArguments) {
  const Stack stack;
  TempDir data("compose");
  const auto argv = rewrite_for_test_machine(stack.argv, {STLREFINED, data.path()});
  const auto healthcheck = instruction(final_stage(stack.dockerfile), "HEALTHCHECK");
  ASSERT_TRUE(healthcheck);
  const auto [port, path] = probe_of(*healthcheck);
  EXPECT_EQ(port, flag_value(stack.argv, "--port"));
  expect_serves(argv, path, data.path());
}

// podman's default (OCI) image format drops HEALTHCHECK, so compose repeats it; both probe
// the same port and path (the one the test above GETs).
TEST(ComposeStack, ComposeHealthcheckProbesWhatTheImageProbes) {
  const Stack stack;
  const auto image = instruction(final_stage(stack.dockerfile), "HEALTHCHECK");
  const auto compose = yaml_get(stack.compose, {"services", "stlrefined", "healthcheck", "test"});
  ASSERT_TRUE(image);
  ASSERT_TRUE(compose && compose->is_sequence);
  EXPECT_EQ(compose->items.front(), "CMD");
  EXPECT_EQ(probe_of(joined(compose->items)), probe_of(*image));
  EXPECT_EQ(probe_of(*image).second, "/healthz");
  const auto depends =
      yaml_get(stack.compose, {"services", "nginx", "depends_on", "stlrefined", "condition"});
  ASSERT_TRUE(depends);
  EXPECT_EQ(depends->scalar, "service_healthy");
}

// A synchronous refine sends nothing until it is done: nginx must wait at least the
// daemon's --request-deadline (compose's, else the daemon's default), and accept the bodies
// the daemon accepts.
TEST(ComposeStack, NginxWaitsAtLeastTheDaemonsDeadline) {
  const Stack stack;
  const std::string help = daemon_help();
  const double deadline =
      std::stod(flag_value(stack.argv, "--request-deadline")
                    .value_or(help_default(help, "--request-deadline").value_or("0")));
  ASSERT_GT(deadline, 0) << "no deadline: nginx cannot wait for ever";
  for (const char* directive : {"proxy_read_timeout", "proxy_send_timeout"}) {
    const auto seconds = nginx_seconds(stack.nginx, directive);
    ASSERT_TRUE(seconds) << directive;
    EXPECT_GE(*seconds, deadline) << directive;
  }
  const double mib = std::stod(flag_value(stack.argv, "--max-body-mib")
                                   .value_or(help_default(help, "--max-body-mib").value_or("0")));
  EXPECT_EQ(nginx_bytes(stack.nginx, "client_max_body_size"), mib * 1024 * 1024);
}

// docker stop sends SIGTERM, then SIGKILL after stop_grace_period: that must leave the
// daemon its whole --shutdown-grace and some seconds to write answers.
TEST(ComposeStack, StopGracePeriodOutlastsTheShutdownGrace) {
  const Stack stack;
  const int grace =
      std::stoi(flag_value(stack.argv, "--shutdown-grace")
                    .value_or(help_default(daemon_help(), "--shutdown-grace").value_or("")));
  const auto stop = yaml_get(stack.compose, {"services", "stlrefined", "stop_grace_period"});
  ASSERT_TRUE(stop);
  std::smatch m;
  ASSERT_TRUE(std::regex_match(stop->scalar, m, std::regex("([0-9]+)s"))) << stop->scalar;
  EXPECT_GE(std::stoi(m[1]), grace + 10);
  EXPECT_EQ(instruction(final_stage(stack.dockerfile), "STOPSIGNAL"), "SIGTERM");
}

// The legacy builder reads .dockerignore only at the root of the build context; BuildKit
// prefers <Dockerfile>.dockerignore, so none may exist beside the Dockerfile to differ.
TEST(ComposeStack, DockerignoreIsAtTheBuildContextRoot) {
  const Stack stack;
  const auto context = yaml_get(stack.compose, {"services", "stlrefined", "build", "context"});
  const auto dockerfile =
      yaml_get(stack.compose, {"services", "stlrefined", "build", "dockerfile"});
  ASSERT_TRUE(context && dockerfile);
  const fs::path root = fs::weakly_canonical(kDocker / context->scalar);
  EXPECT_EQ(root, fs::weakly_canonical(fs::path(STLREFINE_SOURCE_DIR)));
  EXPECT_TRUE(fs::exists(root / dockerfile->scalar));
  const std::string ignore = read_text(root / ".dockerignore");
  for (const char* pattern : {"\n.git\n", "\nbuild\n", "\nbuild-*\n"})
    EXPECT_NE(ignore.find(pattern), std::string::npos) << pattern;
  EXPECT_FALSE(fs::exists(root / (dockerfile->scalar + ".dockerignore")));
}

}  // namespace
}  // namespace stlrefine::test
