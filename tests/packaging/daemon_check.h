// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Starting the real stlrefined with a deployment's argument vector and checking it serves.

#include <filesystem>
#include <string>
#include <vector>

namespace stlrefine::test {

//! What a deployment's argument vector must be rewritten to on a test machine: the built
//! binary instead of the installed one, loopback and a free port instead of the deployed
//! address, a temporary data directory instead of the deployed one. Nothing else changes.
struct TestMachineRewrite {
  std::string binary;
  std::filesystem::path data_dir;
};
std::vector<std::string> rewrite_for_test_machine(std::vector<std::string> argv,
                                                  const TestMachineRewrite& rewrite);

//! Runs `argv` (already rewritten) and checks, with gtest expectations: the daemon starts
//! and GET `health_path` answers 200; a job's files land in `data_dir` (--data-dir is
//! honoured); a body one byte over --max-body-mib (the argv's, else the daemon's default) is
//! refused with 413 naming exactly that limit; SIGTERM stops it with exit 0 within
//! --shutdown-grace.
void expect_serves(const std::vector<std::string>& argv, const std::string& health_path,
                   const std::filesystem::path& data_dir);

//! `stlrefined --help`.
std::string daemon_help();

//! A fresh empty directory under the temp directory, removed by the destructor.
class TempDir {
 public:
  explicit TempDir(const std::string& tag);
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace stlrefine::test
