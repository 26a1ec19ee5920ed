// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "server/request_head.h"

namespace stlrefine::server {

//! How the writing of an answer ended.
struct AnswerEnd {
  enum class Outcome {
    Complete,    //!< every byte was handed to the kernel
    ClientGone,  //!< the client closed or reset the connection
    TooSlow,     //!< the client read slower than the minimum rate
    Shutdown,    //!< the shutdown grace ended first
  };
  Outcome outcome = Outcome::Complete;
  std::uint64_t bytes_sent = 0;   //!< head and body
  std::uint64_t bytes_total = 0;  //!< what the answer had
};
const char* to_string(AnswerEnd::Outcome outcome);

//! Makes bytes [offset, offset + out.size()) of a body into `out`, on the event loop: quick
//! (a piece is at most FrontEnd::kMadePiece bytes) and not throwing.
using BodyMaker = std::function<void(std::uint64_t offset, std::span<char> out)>;

//! A body of unknown length (server-sent events), pulled on the event loop: appends what
//! is ready now to `out` (nothing: pulled again within FrontEnd::kStreamPoll) and returns
//! false once the stream has ended. Quick and not throwing, like BodyMaker. The answer has no
//! Content-Length: its end is the connection's close.
using StreamPull = std::function<bool(std::string& out)>;

//! A complete answer, written by the event loop (never by a worker, so a client that reads
//! slowly or not at all holds no thread). `head` is sent first (the status line, fields,
//! blank line, and possibly a small body), then `body`, `file` or `made`.
struct Answer {
  std::string head;
  std::string_view body;  //!< a body in memory, kept alive by `keep`
  int file = -1;          //!< or a file (owned: the front end closes it)
  std::uint64_t file_offset = 0, file_length = 0;
  //! or a body made piece by piece as it is sent (a refined mesh's STL, from what `keep`
  //! holds): bytes [made_offset, made_offset + made_length) of what `made` makes.
  BodyMaker made;
  std::uint64_t made_offset = 0, made_length = 0;
  //! or a stream (then nothing of the above but `head`).
  StreamPull stream;
  std::shared_ptr<const void> keep;  //!< what `body` points into, reservations
  //! Called once on the event loop when the answer is written or abandoned.
  std::function<void(const AnswerEnd&)> done;

  Answer() = default;
  explicit Answer(std::string whole) : head(std::move(whole)) {}
  Answer(Answer&& other) noexcept;
  Answer& operator=(Answer&& other) noexcept;
  Answer(const Answer&) = delete;
  Answer& operator=(const Answer&) = delete;
  ~Answer();
  std::uint64_t size() const { return head.size() + body.size() + file_length + made_length; }
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
  std::shared_ptr<void> hold;    //!< kept until the answer is written (a reservation)
  //! ReadBody: called before the body buffer grows, with the bytes it is about to hold:
  //! memory is reserved for what arrives, not for what a header declares. Returns an empty
  //! string when that is reserved, else the complete refusal to answer instead.
  std::function<std::string(std::uint64_t bytes)> reserve_body;
};

//! A request read in full, on its way to (and on) a worker thread.
struct ReadRequest {
  int fd = -1;
  RequestHead head;
  std::string body;  //!< exactly Content-Length bytes
  std::chrono::steady_clock::time_point accepted;
  std::shared_ptr<void> hold;
};

//! The daemon's side of the front end.
class FrontEndDelegate {
 public:
  virtual ~FrontEndDelegate() = default;
  //! On the event loop, once a head is complete and well-formed.
  virtual Verdict decide(const RequestHead& head) = 0;
  //! On a worker thread: the answer to the request (written by the event loop).
  virtual Answer serve(ReadRequest& request) = 0;
  //! The complete response for a refusal the front end makes itself (400 malformed head,
  //! 408 too slow, 414, 431, 503 overloaded). `head` is null when none was parsed.
  virtual std::string refusal(const RequestHead* head, int status, std::string_view slug,
                              std::string detail) = 0;
};

//! Reads requests and writes answers on one epoll thread, and hands complete requests to a
//! bounded pool of workers that only compute.
//!
//! cpp-httplib 0.11.4 reads a connection's head and body on a worker thread with a
//! per-recv timeout and no limit on the head's size or field count, and writes answers
//! there too: a client trickling one byte every few seconds, or never reading its answer,
//! holds a thread; a few such sockets starve every other request, and a 100 MB header line
//! is buffered whole. Here no thread waits on a client:
//!  - heads (at most kMaxHeadBytes, kMaxFields fields, kMaxLineBytes per field line) must be
//!    complete within `head_timeout` of the accept;
//!  - bodies and answers move at `min_rate` or faster, measured over every window
//!    (a sliding check, not one deadline a trickle can stretch); a body's memory is reserved
//!    as it arrives (Verdict::reserve_body), not when a header declares it;
//!  - one client address holds at most `max_connections_per_client` connections, and
//!    connections over either cap get a short look at their head in a small probe lane:
//!    /healthz and /readyz are answered there (decide() answers probes itself), anything
//!    else gets 503, and the lane evicts its oldest socket for a new one, so no flood of
//!    slow sockets can starve the health checks.
class FrontEnd {
 public:
  static constexpr std::size_t kMaxHeadBytes = 64 * 1024;
  static constexpr std::size_t kMaxLineBytes = 8 * 1024;
  static constexpr std::size_t kMaxFields = 100;
  static constexpr std::size_t kMaxTargetBytes = 8192;
  //! After an answer, input is read and dropped this long at most before the close, so the
  //! kernel does not reset the connection (and lose the answer) under a client still
  //! sending.
  static constexpr std::chrono::seconds kLinger{2};
  //! Connections over a cap that may wait for their head at once, and how long.
  static constexpr std::size_t kProbeLane = 64;
  static constexpr std::chrono::milliseconds kProbeHeadTimeout{2000};
  //! A body buffer grows by at least this much (and doubles), so its reservation follows
  //! what arrived.
  static constexpr std::size_t kBodyChunk = 1 << 20;
  //! A made body (Answer::made) is made and sent in pieces of at most this much, one buffer
  //! per connection writing one.
  static constexpr std::size_t kMadePiece = 256 << 10;
  //! A stream with nothing to send is asked again this often (the expiry scan's period).
  //! Streams end when the front end stops; a reader slower than `min_rate` with bytes
  //! waiting is dropped like any other.
  static constexpr std::chrono::milliseconds kStreamPoll{20};

  struct Options {
    std::size_t workers = 4;
    std::size_t max_queued = 16;         //!< complete requests waiting for a worker
    std::size_t max_connections = 1024;  //!< open connections at most
    //! Connections one client address may hold; 0 = no per-address cap.
    std::size_t max_connections_per_client = 256;
    std::chrono::milliseconds head_timeout{10000};
    //! Bodies must arrive, and answers be read, at min_rate bytes/s or more over every
    //! window of these lengths (or finish within it): a trickle cannot stretch a deadline.
    std::chrono::milliseconds body_window{10000};
    std::chrono::milliseconds answer_window{10000};
    std::uint64_t min_rate = 64 * 1024;
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
  //! progress are refused with `shutdown_response_for_bodies`; requests already read are
  //! computed and their answers written in full. When `grace` has passed, `on_grace_over`
  //! is called (to cancel computations) and answers still being written are abandoned
  //! (AnswerEnd::Shutdown). Returns when every connection is closed.
  void stop(std::string shutdown_response_for_bodies, std::chrono::milliseconds grace,
            std::function<void()> on_grace_over = {});

  //! Connections open right now (tests, metrics).
  std::size_t open_connections() const;

 private:
  struct Connection;
  void loop();
  void work();
  void on_readable(Connection& c);
  void on_head(Connection& c, std::size_t head_end);
  void answer(Connection& c, Answer answer);
  void flush(Connection& c);
  void flush_stream(Connection& c);
  void finish_answer(Connection& c, AnswerEnd::Outcome outcome);
  void dispatch(Connection& c);
  void close(Connection& c);
  void update_events(Connection& c);
  void expire(std::chrono::steady_clock::time_point now);
  void take_new();
  bool grow_body(Connection& c, std::size_t incoming);
  bool too_slow(Connection& c, std::chrono::steady_clock::time_point now,
                std::chrono::milliseconds window, std::uint64_t remaining);
  void admit_to_probe_lane(Connection& c);

  Options options_;
  FrontEndDelegate& delegate_;
  int epoll_fd_ = -1;
  int wake_fd_ = -1;

  struct Returned {
    int fd;
    std::string remote_ip;
    Answer answer;
    std::shared_ptr<void> hold;
  };
  // Handed over from other threads: new sockets, answered requests back from workers.
  std::mutex inbox_mutex_;
  std::vector<int> adopted_;
  std::vector<Returned> returned_;

  std::vector<std::unique_ptr<Connection>> connections_;  // indexed by slot
  std::vector<std::size_t> free_slots_;
  std::atomic<std::size_t> open_{0};
  // Event loop only: open connections per client address, and the probe lane (slots, oldest
  // first).
  std::map<std::string, std::size_t> per_client_;
  std::deque<std::size_t> probe_lane_;

  std::mutex work_mutex_;
  std::condition_variable work_cv_;
  std::deque<std::unique_ptr<ReadRequest>> queue_;
  std::size_t busy_workers_ = 0;
  bool workers_stop_ = false;
  std::vector<std::thread> workers_;
  std::thread loop_thread_;
  std::atomic<bool> stopping_{false};
  std::string shutdown_response_;
  std::chrono::steady_clock::time_point grace_end_{};
  std::function<void()> on_grace_over_;
  bool grace_over_ = false;
  bool started_ = false;
};

}  // namespace stlrefine::server
