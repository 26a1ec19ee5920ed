// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

namespace stlrefine::server {

//! A request line and header fields as the client sent them (values trimmed).
struct RequestHead {
  std::string method, target, version;
  std::vector<std::pair<std::string, std::string>> fields;
  std::string remote_ip;
  int remote_port = 0;

  //! The first value of a field (names are case-insensitive), or nullptr.
  const std::string* find(std::string_view name) const;
};

//! What the daemon decides on a request head. decide() runs on the event loop: it must be
//! quick and must not block.
struct Verdict {
  enum class Kind {
    Answer,    //!< write `response`, then read and drop the client's body, then close
    ReadBody,  //!< read `body_bytes` bytes of body, then hand the request to a worker
    Dispatch,  //!< no body: hand the request to a worker now
  };
  Kind kind = Kind::Dispatch;
  std::string response;          //!< Answer: the complete HTTP response
  std::uint64_t body_bytes = 0;  //!< ReadBody: the Content-Length (`100 Continue` is sent
                                 //!< first when the client asked with `Expect`)
  std::shared_ptr<void> hold;    //!< kept until the connection is closed (a reservation)
};

//! A request read in full, on its way to (and on) a worker thread.
struct ReadRequest {
  int fd = -1;
  std::string head;  //!< request line + fields + blank line, `Expect` removed
  std::string body;  //!< exactly Content-Length bytes
  std::string remote_ip;
  int remote_port = 0;
  std::chrono::steady_clock::time_point accepted;
  std::shared_ptr<void> hold;
};

//! The daemon's side of the front end.
class FrontEndDelegate {
 public:
  virtual ~FrontEndDelegate() = default;
  //! On the event loop, once a head is complete and well-formed.
  virtual Verdict decide(const RequestHead& head) = 0;
  //! On a worker thread: answer the request on request.fd (not closed here).
  virtual void serve(ReadRequest& request) = 0;
  //! The complete response for a refusal the front end makes itself (400 malformed head,
  //! 408 too slow, 414, 431, 503 overloaded). `head` is null when none was parsed.
  virtual std::string refusal(const RequestHead* head, int status, std::string_view slug,
                              std::string detail) = 0;
};

//! Reads requests on one epoll thread and hands complete ones to a bounded pool of workers.
//!
//! cpp-httplib 0.11.4 reads a connection's head and body on a worker thread with a
//! per-recv timeout and no limit on the head's size or field count: a client trickling one
//! byte every few seconds holds a thread indefinitely, a few hundred such sockets starve
//! every other request, and a 100 MB header line is buffered whole. Here no thread waits
//! on a client: heads (at most kMaxHeadBytes, kMaxFields fields, kMaxLineBytes per field
//! line) must be complete within `head_timeout` of the accept, bodies must keep arriving
//! (idle timeout) at an average of at least kMinBodyRate after the first `head_timeout`.
//! Workers only compute and write answers.
class FrontEnd {
 public:
  static constexpr std::size_t kMaxHeadBytes = 64 * 1024;
  static constexpr std::size_t kMaxLineBytes = 8 * 1024;
  static constexpr std::size_t kMaxFields = 100;
  static constexpr std::size_t kMaxTargetBytes = 8192;
  static constexpr std::uint64_t kMinBodyRate = 64 * 1024;  // bytes per second
  //! After an answer, input is read and dropped this long at most before the close, so the
  //! kernel does not reset the connection (and lose the answer) under a client still
  //! sending.
  static constexpr std::chrono::seconds kLinger{2};

  struct Options {
    std::size_t workers = 4;
    std::size_t max_queued = 16;         //!< complete requests waiting for a worker
    std::size_t max_connections = 1024;  //!< open connections at most; more get 503
    std::chrono::milliseconds head_timeout{10000};
    std::chrono::milliseconds idle_timeout{10000};  //!< between two reads of a body
    std::chrono::milliseconds write_timeout{60000};
    //! Workers run at this much lower priority (nice increment; the computations run on
    //! them), the event loop at the process's: probes and refusals never wait for compute.
    int worker_nice = 0;
  };

  FrontEnd(Options options, FrontEndDelegate& delegate);
  ~FrontEnd();
  FrontEnd(const FrontEnd&) = delete;
  FrontEnd& operator=(const FrontEnd&) = delete;

  //! Takes an accepted socket (thread-safe; the accept loop calls it).
  void adopt(int fd);
  //! Starts the event loop and the workers.
  void start();
  //! Stops reading new requests: connections still sending a head are closed, bodies in
  //! progress are refused (503); requests already read are answered. Returns when every
  //! connection is closed.
  void stop(std::string shutdown_response_for_bodies);

  //! The request the calling worker thread is serving (null elsewhere).
  static ReadRequest* current();

  //! Connections open right now (tests, metrics).
  std::size_t open_connections() const;

 private:
  struct Connection;
  void loop();
  void work();
  void on_readable(Connection& c);
  void on_head(Connection& c, std::size_t head_end);
  void answer(Connection& c, std::string response);
  void flush(Connection& c);
  void dispatch(Connection& c);
  void close(Connection& c);
  void update_events(Connection& c);
  void expire(std::chrono::steady_clock::time_point now);
  void take_new();

  Options options_;
  FrontEndDelegate& delegate_;
  int epoll_fd_ = -1;
  int wake_fd_ = -1;

  // Handed over from other threads: new sockets, sockets back from workers.
  std::mutex inbox_mutex_;
  std::vector<int> adopted_;
  std::vector<int> returned_;

  std::vector<std::unique_ptr<Connection>> connections_;  // indexed by slot
  std::vector<std::size_t> free_slots_;
  std::atomic<std::size_t> open_{0};

  std::mutex work_mutex_;
  std::condition_variable work_cv_;
  std::deque<std::unique_ptr<ReadRequest>> queue_;
  std::size_t busy_workers_ = 0;
  bool workers_stop_ = false;
  std::vector<std::thread> workers_;
  std::thread loop_thread_;
  std::atomic<bool> stopping_{false};
  std::string shutdown_response_;
  bool started_ = false;
};

}  // namespace stlrefine::server
