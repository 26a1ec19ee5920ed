// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A Daemon serving on an ephemeral loopback port from its own thread, for one test.

#include <httplib.h>

#include <chrono>
#include <memory>
#include <thread>

#include "server/daemon.h"

namespace stlrefine::test {

class InProcessDaemon {
 public:
  //! Binds 127.0.0.1:0, starts serving and waits (up to 2 s) until /healthz answers.
  //! `client_timeout` is the read timeout of the clients client() makes.
  explicit InProcessDaemon(server::DaemonConfig config,
                           std::chrono::seconds client_timeout = std::chrono::seconds(60));
  ~InProcessDaemon() { stop(); }
  InProcessDaemon(const InProcessDaemon&) = delete;
  InProcessDaemon& operator=(const InProcessDaemon&) = delete;

  //! Stops serving and joins the thread; idempotent.
  void stop();
  httplib::Client client() const;
  server::Daemon& daemon() { return *daemon_; }
  int port() const { return port_; }

 private:
  std::unique_ptr<server::Daemon> daemon_;
  std::thread thread_;
  int port_ = 0;
  std::chrono::seconds client_timeout_;
};

}  // namespace stlrefine::test
