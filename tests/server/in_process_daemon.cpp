// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "in_process_daemon.h"

#include <csignal>

namespace stlrefine::test {

InProcessDaemon::InProcessDaemon(server::DaemonConfig config, std::chrono::seconds client_timeout)
    : client_timeout_(client_timeout) {
  std::signal(SIGPIPE, SIG_IGN);  // a client that hangs up must not end the test binary
  daemon_ = std::make_unique<server::Daemon>(std::move(config));
  port_ = daemon_->bind("127.0.0.1", 0);
  thread_ = std::thread([this] { daemon_->run(); });
  httplib::Client c = client();
  for (int i = 0; i < 200; ++i) {
    if (auto r = c.Get("/healthz"); r && r->status == 200) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

void InProcessDaemon::stop() {
  if (!daemon_) return;
  daemon_->stop();
  thread_.join();
  daemon_.reset();
}

httplib::Client InProcessDaemon::client() const {
  httplib::Client c("127.0.0.1", port_);
  c.set_read_timeout(client_timeout_.count(), 0);
  return c;
}

}  // namespace stlrefine::test
