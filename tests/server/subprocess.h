// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Running the built binaries (stlrefine, stlrefined) from the tests.

#include <sys/types.h>

#include <chrono>
#include <string>
#include <vector>

namespace stlrefine::test {

struct ProcessResult {
  int exit_code = -1;  //!< -1 when killed by a signal or timed out
  std::string out, err;
};

//! Runs argv to completion (killed after `timeout`), stdin from /dev/null, stdout and stderr
//! captured.
ProcessResult run_process(const std::vector<std::string>& argv,
                          std::chrono::seconds timeout = std::chrono::seconds(60));

//! A running child whose stdout is a pipe (stderr is captured to a file).
class Child {
 public:
  explicit Child(const std::vector<std::string>& argv);
  ~Child();  // SIGKILL if still running
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  //! One line from stdout, without the newline; empty on EOF or timeout.
  std::string read_line(std::chrono::milliseconds timeout);
  void signal(int sig);
  //! Exit code after waiting at most `timeout` (-1: killed by a signal, or still running).
  int wait(std::chrono::milliseconds timeout);
  std::string stderr_text() const;
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = -1;
  int out_fd_ = -1;
  std::string err_path_;
  std::string pending_;
  bool reaped_ = false;
};

//! The port of a child stlrefined started with --port 0, from its one `listening on` line on
//! 127.0.0.1; 0 when the line is not that. (No gtest here: bench/reliability links this too.)
int listening_port(Child& child, std::chrono::milliseconds timeout = std::chrono::seconds(20));

//! User + system CPU seconds of the process so far (0 when unreadable).
double proc_cpu_seconds(pid_t pid);

}  // namespace stlrefine::test
