// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/front_end.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <stdexcept>

#include "api/problem.h"
#include "server/front_end_connection.h"
#include "server/thread_priority.h"

namespace stlrefine::server {

namespace {

using Clock = std::chrono::steady_clock;

constexpr std::uint64_t kWakeTag = 0;  // epoll data of the wake eventfd; connections are slot + 1

void peer_of(int fd, std::string& ip, int& port) {
  sockaddr_storage addr{};
  socklen_t len = sizeof addr;
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) return;
  char text[INET6_ADDRSTRLEN] = {};
  if (addr.ss_family == AF_INET) {
    const auto* a = reinterpret_cast<const sockaddr_in*>(&addr);
    ::inet_ntop(AF_INET, &a->sin_addr, text, sizeof text);
    port = ntohs(a->sin_port);
  } else if (addr.ss_family == AF_INET6) {
    const auto* a = reinterpret_cast<const sockaddr_in6*>(&addr);
    ::inet_ntop(AF_INET6, &a->sin6_addr, text, sizeof text);
    port = ntohs(a->sin6_port);
  }
  ip = text;
}

}  // namespace

const char* to_string(AnswerEnd::Outcome outcome) {
  switch (outcome) {
    case AnswerEnd::Outcome::Complete:
      return "complete";
    case AnswerEnd::Outcome::ClientGone:
      return "client_gone";
    case AnswerEnd::Outcome::TooSlow:
      return "too_slow";
    case AnswerEnd::Outcome::Shutdown:
      return "shutdown";
  }
  return "unknown";
}

Answer::Answer(Answer&& other) noexcept
    : head(std::move(other.head)),
      body(other.body),
      file(other.file),
      file_offset(other.file_offset),
      file_length(other.file_length),
      made(std::move(other.made)),
      made_offset(other.made_offset),
      made_length(other.made_length),
      stream(std::move(other.stream)),
      keep(std::move(other.keep)),
      done(std::move(other.done)) {
  other.body = {};
  other.file = -1;
  other.file_length = 0;
  other.made = nullptr;
  other.stream = nullptr;
  other.made_length = 0;
}

Answer& Answer::operator=(Answer&& other) noexcept {
  if (this != &other) {
    if (file >= 0) ::close(file);
    head = std::move(other.head);
    body = other.body;
    file = other.file;
    file_offset = other.file_offset;
    file_length = other.file_length;
    made = std::move(other.made);
    made_offset = other.made_offset;
    made_length = other.made_length;
    stream = std::move(other.stream);
    keep = std::move(other.keep);
    done = std::move(other.done);
    other.body = {};
    other.file = -1;
    other.file_length = 0;
    other.made = nullptr;
    other.stream = nullptr;
    other.made_length = 0;
  }
  return *this;
}

Answer::~Answer() {
  if (file >= 0) ::close(file);
}

FrontEnd::FrontEnd(Options options, FrontEndDelegate& delegate)
    : options_(options), delegate_(delegate) {
  epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (epoll_fd_ < 0 || wake_fd_ < 0) throw std::runtime_error("cannot create the event loop");
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.u64 = kWakeTag;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &ev);
}

FrontEnd::~FrontEnd() {
  if (started_) stop({}, std::chrono::milliseconds(0));
  for (int fd : adopted_) ::close(fd);
  ::close(wake_fd_);
  ::close(epoll_fd_);
}

void FrontEnd::adopt(int fd) {
  {
    std::lock_guard lock(inbox_mutex_);
    adopted_.push_back(fd);
  }
  ++open_;
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t n = ::write(wake_fd_, &one, sizeof one);
}

void FrontEnd::start() {
  // sendfile(2) has no MSG_NOSIGNAL: a client gone mid-download must not end the process.
  std::signal(SIGPIPE, SIG_IGN);
  started_ = true;
  for (std::size_t i = 0; i < options_.workers; ++i) workers_.emplace_back([this] { work(); });
  loop_thread_ = std::thread([this] { loop(); });
}

void FrontEnd::stop(std::string shutdown_response_for_bodies, std::chrono::milliseconds grace,
                    std::function<void()> on_grace_over) {
  if (!started_) return;
  started_ = false;
  {
    std::lock_guard lock(inbox_mutex_);
    shutdown_response_ = std::move(shutdown_response_for_bodies);
    grace_end_ = Clock::now() + grace;
    on_grace_over_ = std::move(on_grace_over);
  }
  stopping_ = true;
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t n = ::write(wake_fd_, &one, sizeof one);
  loop_thread_.join();
  {
    std::lock_guard lock(work_mutex_);
    workers_stop_ = true;
  }
  work_cv_.notify_all();
  for (std::thread& t : workers_) t.join();
  workers_.clear();
}

std::size_t FrontEnd::open_connections() const {
  return open_;
}

void FrontEnd::work() {
  lower_thread_priority(options_.worker_nice);
  for (;;) {
    std::unique_ptr<ReadRequest> request;
    {
      std::unique_lock lock(work_mutex_);
      work_cv_.wait(lock, [&] { return !queue_.empty() || workers_stop_; });
      if (queue_.empty()) return;
      request = std::move(queue_.front());
      queue_.pop_front();
      ++busy_workers_;
    }
    Answer answer;
    try {
      answer = delegate_.serve(*request);
    } catch (...) {
      // The delegate answers its own errors; nothing may take the worker down.
      try {
        answer = Answer(delegate_.refusal(&request->head, api::http::kInternalServerError,
                                          "internal", "an internal error occurred"));
      } catch (...) {
      }
    }
    Returned back{request->fd, std::move(request->head.remote_ip), std::move(answer),
                  std::move(request->hold)};
    request.reset();  // the body goes now; the reservation stays until the answer is sent
    {
      std::lock_guard lock(inbox_mutex_);
      returned_.push_back(std::move(back));
    }
    {
      std::lock_guard lock(work_mutex_);
      --busy_workers_;
    }
    const std::uint64_t one = 1;
    [[maybe_unused]] const ssize_t n = ::write(wake_fd_, &one, sizeof one);
  }
}

void FrontEnd::update_events(Connection& c) {
  std::uint32_t want = c.read_closed ? 0u : static_cast<std::uint32_t>(EPOLLIN);
  if (c.state == Connection::State::Answer && !c.stream_idle) want |= EPOLLOUT;
  if (want == c.events) return;
  epoll_event ev{};
  ev.events = want;
  ev.data.u64 = c.slot + 1;
  ::epoll_ctl(epoll_fd_, c.registered ? EPOLL_CTL_MOD : EPOLL_CTL_ADD, c.fd, &ev);
  c.registered = true;
  c.events = want;
}

void FrontEnd::close(Connection& c) {
  if (c.out.done) {
    // Closed before its answer was written (never reached while writing normally).
    AnswerEnd end{AnswerEnd::Outcome::ClientGone, c.sent, c.out.size()};
    auto done = std::move(c.out.done);
    done(end);
  }
  if (c.in_probe_lane) probe_lane_.erase(std::find(probe_lane_.begin(), probe_lane_.end(), c.slot));
  if (auto it = per_client_.find(c.remote_ip); it != per_client_.end() && --it->second == 0)
    per_client_.erase(it);
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c.fd, nullptr);
  ::close(c.fd);
  --open_;
  free_slots_.push_back(c.slot);
  connections_[c.slot].reset();  // c is gone
}

void FrontEnd::admit_to_probe_lane(Connection& c) {
  if (probe_lane_.size() >= kProbeLane) {
    const std::size_t oldest = probe_lane_.front();  // close() takes it out of the lane
    if (connections_[oldest]) close(*connections_[oldest]);
  }
  c.in_probe_lane = true;
  c.deadline = c.accepted + kProbeHeadTimeout;
  probe_lane_.push_back(c.slot);
}

void FrontEnd::take_new() {
  std::vector<int> adopted;
  std::vector<Returned> returned;
  {
    std::lock_guard lock(inbox_mutex_);
    adopted.swap(adopted_);
    returned.swap(returned_);
  }
  const auto now = Clock::now();
  auto make = [&](int fd, std::string remote_ip) -> Connection& {
    std::size_t slot;
    if (free_slots_.empty()) {
      slot = connections_.size();
      connections_.emplace_back();
    } else {
      slot = free_slots_.back();
      free_slots_.pop_back();
    }
    connections_[slot] = std::make_unique<Connection>();
    Connection& c = *connections_[slot];
    c.fd = fd;
    c.slot = slot;
    c.accepted = now;
    c.remote_ip = std::move(remote_ip);
    return c;
  };
  for (Returned& r : returned) {
    // Answered by a worker (its client address is still counted): write the answer here.
    Connection& c = make(r.fd, std::move(r.remote_ip));
    c.hold = std::move(r.hold);
    answer(c, std::move(r.answer));
  }
  for (int fd : adopted) {
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
    int one = 1;
    // Answers are written in pieces (head, body): without this, Nagle's algorithm and the
    // peer's delayed ACK hold the second piece up to 40 ms.
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    std::string ip;
    int port = 0;
    peer_of(fd, ip, port);
    Connection& c = make(fd, ip);
    c.remote_port = port;
    const std::size_t from_client = ++per_client_[ip];
    c.deadline = now + options_.head_timeout;
    if (stopping_) {
      close(c);
      continue;
    }
    const bool over_cap =
        open_ > options_.max_connections || (options_.max_connections_per_client > 0 &&
                                             from_client > options_.max_connections_per_client);
    if (over_cap) admit_to_probe_lane(c);
    update_events(c);
  }
}

void FrontEnd::dispatch(Connection& c) {
  std::unique_ptr<ReadRequest> request = std::move(c.request);
  {
    std::lock_guard lock(work_mutex_);
    if (queue_.size() < options_.max_queued) {
      ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c.fd, nullptr);
      queue_.push_back(std::move(request));
      free_slots_.push_back(c.slot);
      connections_[c.slot].reset();  // the fd now belongs to the request
      work_cv_.notify_one();
      return;
    }
  }
  answer(c, Answer(delegate_.refusal(&request->head, api::http::kServiceUnavailable, "overloaded",
                                     "every worker is busy and " +
                                         std::to_string(options_.max_queued) +
                                         " requests wait; retry later")));
}

bool FrontEnd::too_slow(Connection& c, Clock::time_point now, std::chrono::milliseconds window,
                        std::uint64_t remaining) {
  if (now - c.window_start < window) return false;
  const double seconds = std::chrono::duration<double>(now - c.window_start).count();
  // What the window should have moved: the minimum rate, or all that was left of the
  // transfer when the window began.
  const auto at_rate = static_cast<std::uint64_t>(static_cast<double>(options_.min_rate) * seconds);
  const std::uint64_t wanted = std::min(at_rate, c.window_bytes + remaining);
  if (c.window_bytes == 0 || c.window_bytes < wanted) return true;
  c.window_start = now;
  c.window_bytes = 0;
  return false;
}

void FrontEnd::expire(Clock::time_point now) {
  for (std::size_t i = 0; i < connections_.size(); ++i) {
    Connection* c = connections_[i].get();
    if (!c) continue;
    switch (c->state) {
      case Connection::State::Head:
        if (stopping_ || (c->in_probe_lane && now > c->deadline)) {
          close(*c);
        } else if (now > c->deadline) {
          answer(*c, Answer(delegate_.refusal(
                         nullptr, api::http::kRequestTimeout, "request-timeout",
                         "the request head did not arrive within " +
                             std::to_string(options_.head_timeout.count()) + " ms")));
        }
        break;
      case Connection::State::Body:
        if (stopping_) {
          answer(*c, Answer(std::string(shutdown_response_)));
        } else if (too_slow(*c, now, options_.body_window,
                            c->body_expected - c->request->body.size())) {
          answer(*c,
                 Answer(delegate_.refusal(
                     &c->request->head, api::http::kRequestTimeout, "request-timeout",
                     "the body arrived slower than " + std::to_string(options_.min_rate / 1024) +
                         " KiB/s over " + std::to_string(options_.body_window.count()) + " ms")));
        }
        break;
      case Connection::State::Answer:
        if (grace_over_) {
          finish_answer(*c, AnswerEnd::Outcome::Shutdown);
        } else if (c->out.stream) {
          // A stream ends with the daemon (its client reconnects to another); one idle is
          // asked again, and only bytes waiting for the reader count against its rate.
          const std::uint64_t pulled = c->out.head.size() + c->piece_at + c->piece.size();
          const std::uint64_t waiting = pulled - std::min(c->sent, pulled);
          if (stopping_) {
            finish_answer(*c, AnswerEnd::Outcome::Complete);
          } else if (c->stream_idle) {
            c->window_start = now;
            c->window_bytes = 0;
            flush(*c);
          } else if (too_slow(*c, now, options_.answer_window, waiting)) {
            finish_answer(*c, AnswerEnd::Outcome::TooSlow);
          }
        } else if (too_slow(*c, now, options_.answer_window, c->out.size() - c->sent))
          finish_answer(*c, AnswerEnd::Outcome::TooSlow);
        break;
      case Connection::State::Linger:
        if (now > c->deadline) close(*c);
        break;
    }
  }
}

void FrontEnd::loop() {
  epoll_event events[256];
  auto last_scan = Clock::now();
  for (;;) {
    const int n = ::epoll_wait(epoll_fd_, events, 256, 50);
    bool woken = false;
    for (int i = 0; i < n; ++i) {
      const std::uint64_t tag = events[i].data.u64;
      if (tag == kWakeTag) {
        std::uint64_t count;
        [[maybe_unused]] const ssize_t r = ::read(wake_fd_, &count, sizeof count);
        woken = true;
        continue;
      }
      const std::size_t slot = tag - 1;
      if (slot >= connections_.size() || !connections_[slot]) continue;
      Connection* c = connections_[slot].get();
      if ((events[i].events & EPOLLOUT) && c->state == Connection::State::Answer) {
        flush(*c);
        if (connections_[slot].get() != c) continue;  // closed
      }
      if (events[i].events & (EPOLLIN | EPOLLHUP | EPOLLERR)) on_readable(*c);
    }
    if (woken || stopping_) take_new();
    const auto now = Clock::now();
    if (stopping_ && !grace_over_) {
      std::function<void()> on_grace_over;
      {
        std::lock_guard lock(inbox_mutex_);
        if (now >= grace_end_) {
          grace_over_ = true;
          on_grace_over = std::move(on_grace_over_);
        }
      }
      if (on_grace_over) on_grace_over();
    }
    if (now - last_scan >= std::chrono::milliseconds(20) || stopping_) {
      expire(now);
      last_scan = now;
    }
    if (stopping_) {
      const bool idle = std::none_of(connections_.begin(), connections_.end(),
                                     [](const auto& c) { return c != nullptr; });
      bool workers_idle;
      {
        std::lock_guard lock(work_mutex_);
        workers_idle = queue_.empty() && busy_workers_ == 0;
      }
      bool inbox_empty;
      {
        std::lock_guard lock(inbox_mutex_);
        inbox_empty = returned_.empty() && adopted_.empty();
      }
      if (idle && workers_idle && inbox_empty) return;
    }
  }
}

}  // namespace stlrefine::server
