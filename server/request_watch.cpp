// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/request_watch.h"

#include <poll.h>

#include <algorithm>

namespace stlrefine::server {

void RequestWatch::Ticket::raise(Reason why) {
  int none = 0;
  reason_.compare_exchange_strong(none, static_cast<int>(why));
  cancel = true;
}

RequestWatch::RequestWatch(std::chrono::milliseconds period) : period_(period) {
  thread_ = std::thread([this] { run(); });
}

RequestWatch::~RequestWatch() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

std::shared_ptr<RequestWatch::Ticket> RequestWatch::watch(int fd,
                                                          std::chrono::milliseconds deadline) {
  auto ticket = std::make_shared<Ticket>();
  ticket->fd = fd;
  if (deadline.count() > 0) ticket->deadline = std::chrono::steady_clock::now() + deadline;
  std::lock_guard lock(mutex_);
  if (cancel_all_) ticket->raise(Reason::Shutdown);
  tickets_.push_back(ticket);
  return ticket;
}

void RequestWatch::cancel_all() {
  std::lock_guard lock(mutex_);
  cancel_all_ = true;
  for (const auto& weak : tickets_)
    if (auto ticket = weak.lock()) ticket->raise(Reason::Shutdown);
}

void RequestWatch::run() {
  std::vector<std::shared_ptr<Ticket>> live;
  std::vector<pollfd> fds;
  std::unique_lock lock(mutex_);
  while (!stop_) {
    wake_.wait_for(lock, period_);
    if (stop_) break;
    live.clear();
    std::erase_if(tickets_, [&](const std::weak_ptr<Ticket>& weak) {
      auto ticket = weak.lock();
      if (!ticket) return true;
      live.push_back(std::move(ticket));
      return false;
    });
    lock.unlock();
    const auto now = std::chrono::steady_clock::now();
    fds.clear();
    for (const auto& ticket : live) {
      if (now >= ticket->deadline) ticket->raise(Reason::Deadline);
      // POLLRDHUP: the client shut down its side or reset; either way nobody reads the answer.
      fds.push_back({ticket->fd, static_cast<short>(POLLRDHUP), 0});  // fd < 0 is skipped
    }
    if (!fds.empty() && ::poll(fds.data(), fds.size(), 0) > 0) {
      for (std::size_t i = 0; i < fds.size(); ++i)
        if (fds[i].revents & (POLLRDHUP | POLLHUP | POLLERR)) live[i]->raise(Reason::Disconnected);
    }
    live.clear();  // drop our references before sleeping
    lock.lock();
  }
}

}  // namespace stlrefine::server
