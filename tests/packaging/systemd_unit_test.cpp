// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// packaging/stlrefined.service.in: its ExecStart, run for real, and the settings the
// package promises (dedicated user, data directory, hardening, the SIGTERM grace).

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <regex>
#include <sstream>

#include "daemon_check.h"
#include "deploy_files.h"

namespace stlrefine::test {
namespace {

namespace fs = std::filesystem;

const fs::path kUnit = fs::path(STLREFINE_SOURCE_DIR) / "packaging" / "stlrefined.service.in";

std::map<std::string, std::string> service_settings() {
  std::map<std::string, std::string> settings;
  for (const auto& [key, value] : unit_entries(read_text(kUnit), "Service")) settings[key] = value;
  return settings;
}

// ExecStart's words (the unit uses no quoting), "@STLREFINE_BINDIR@" as written.
std::vector<std::string> exec_start() {
  std::istringstream words(service_settings()["ExecStart"]);
  std::vector<std::string> argv;
  for (std::string word; words >> word;) {
    EXPECT_EQ(word.find_first_of("\"'$%"), std::string::npos) << "quoting or expansion: " << word;
    argv.push_back(word);
  }
  return argv;
}

TEST(SystemdUnit, RunsTheInstalledDaemonAsADedicatedUserOnItsStateDirectory) {
  auto s = service_settings();
  const auto argv = exec_start();
  ASSERT_FALSE(argv.empty());
  EXPECT_EQ(argv[0], "@STLREFINE_BINDIR@/stlrefined");  // configured at install time
  EXPECT_EQ(s["User"], "stlrefine");
  EXPECT_EQ(s["StateDirectory"], "stlrefine");
  const std::string data = flag_value(argv, "--data-dir").value_or("");
  EXPECT_EQ(data.rfind("/var/lib/stlrefine", 0), 0u) << data;
  EXPECT_EQ(s["ReadWritePaths"], "/var/lib/stlrefine");
  // The user the package creates (sysusers.d) is the unit's, with the data as its home.
  const std::string sysusers =
      read_text(fs::path(STLREFINE_SOURCE_DIR) / "packaging" / "stlrefine.sysusers");
  EXPECT_TRUE(
      std::regex_search(sysusers, std::regex(R"((^|\n)u stlrefine - "[^"]*" /var/lib/stlrefine )")))
      << sysusers;
}

TEST(SystemdUnit, IsHardenedAndRestartsOnFailure) {
  auto s = service_settings();
  EXPECT_EQ(s["ProtectSystem"], "strict");
  EXPECT_EQ(s["NoNewPrivileges"], "yes");
  EXPECT_EQ(s["PrivateTmp"], "yes");
  EXPECT_EQ(s["ProtectHome"], "yes");
  EXPECT_EQ(s["CapabilityBoundingSet"], "");
  EXPECT_EQ(s["Restart"], "on-failure");
}

// systemd sends SIGTERM, then SIGKILL after TimeoutStopSec: that must leave the daemon its
// whole --shutdown-grace (the unit's, else the default) and some seconds to write answers.
TEST(SystemdUnit, WaitsLongerThanTheShutdownGraceBeforeSigkill) {
  auto s = service_settings();
  const std::string grace =
      flag_value(exec_start(), "--shutdown-grace")
          .value_or(help_default(daemon_help(), "--shutdown-grace").value_or(""));
  ASSERT_FALSE(grace.empty());
  EXPECT_EQ(s["KillSignal"], "SIGTERM");
  ASSERT_FALSE(s["TimeoutStopSec"].empty());
  EXPECT_GE(std::stoi(s["TimeoutStopSec"]), std::stoi(grace) + 10) << s["TimeoutStopSec"];
}

// ExecStart with the daemon the build made, loopback port 0 instead of 8080 and a temporary
// data directory instead of /var/lib/stlrefine: it parses, serves and honours its flags.
TEST(SystemdUnit, ExecStartStartsHealthy) {
  TempDir data("unit");
  expect_serves(rewrite_for_test_machine(exec_start(), {STLREFINED, data.path()}), "/healthz",
                data.path());
}

}  // namespace
}  // namespace stlrefine::test
