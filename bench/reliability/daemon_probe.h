// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A stlrefined child process for the reliability programs: started on a free loopback port,
// its memory and descriptors read from /proc/<pid>.

#include <sys/types.h>

#include <memory>
#include <string>
#include <vector>

#include "subprocess.h"  // tests/server

namespace stlrefine::bench {

class DaemonProbe {
 public:
  //! Starts `binary --port 0 args...` and reads its port. \throw std::runtime_error
  DaemonProbe(const std::string& binary, const std::vector<std::string>& args);
  ~DaemonProbe();  // SIGTERM, then SIGKILL after 30 s
  DaemonProbe(const DaemonProbe&) = delete;
  DaemonProbe& operator=(const DaemonProbe&) = delete;

  int port() const { return port_; }
  pid_t pid() const;
  //! A line of /proc/<pid>/status in bytes ("VmRSS", "VmHWM"); -1 when unreadable.
  long long status_bytes(const std::string& key) const;
  //! Resets VmHWM to the current RSS (/proc/<pid>/clear_refs 5).
  void reset_peak() const;
  //! Open descriptors (/proc/<pid>/fd).
  std::size_t open_fds() const;
  std::string stderr_text() const;

 private:
  std::unique_ptr<test::Child> child_;
  int port_ = 0;
};

//! The body of a file, or an empty string when unreadable. ".gz" files are unpacked with
//! gzip -dc.
std::string read_input(const std::string& path);

}  // namespace stlrefine::bench
