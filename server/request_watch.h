// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace stlrefine::server {

//! Raises a request's cancel flag (the one the core's CancelScope and level loop check) when
//! its deadline passes, when its client hangs up, or on cancel_all() (raise(Cancelled) is
//! for owners that cancel it themselves, as DELETE of a job does): runaway or abandoned
//! work frees its compute slot and memory within one chunk of work.
class RequestWatch {
 public:
  enum class Reason { None, Deadline, Disconnected, Shutdown, Cancelled };

  struct Ticket {
    std::atomic<bool> cancel{false};
    //! Why cancel was raised (the first reason wins).
    Reason reason() const { return static_cast<Reason>(reason_.load()); }
    void raise(Reason why);

   private:
    friend class RequestWatch;
    std::atomic<int> reason_{0};
    int fd = -1;
    std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
  };

  explicit RequestWatch(std::chrono::milliseconds period = std::chrono::milliseconds(20));
  ~RequestWatch();
  RequestWatch(const RequestWatch&) = delete;
  RequestWatch& operator=(const RequestWatch&) = delete;

  //! Watches until the ticket is destroyed. `fd` < 0: no connection to watch; `deadline`
  //! zero: none.
  std::shared_ptr<Ticket> watch(int fd, std::chrono::milliseconds deadline);
  //! Cancels every watched request, and every later one at once (shutdown).
  void cancel_all();

 private:
  void run();

  const std::chrono::milliseconds period_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<std::weak_ptr<Ticket>> tickets_;
  bool stop_ = false;
  bool cancel_all_ = false;
  std::thread thread_;
};

}  // namespace stlrefine::server
