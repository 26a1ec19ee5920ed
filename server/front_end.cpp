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
#include <cctype>
#include <cerrno>
#include <cstring>
#include <optional>
#include <stdexcept>

#include "server/thread_priority.h"

namespace stlrefine::server {

namespace {

using Clock = std::chrono::steady_clock;

constexpr std::uint64_t kWakeTag = 0;  // epoll data of the wake eventfd; connections are slot + 1

bool equals_ignore_case(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

// RFC 9110 tchar.
bool is_tchar(unsigned char c) {
  return std::isalnum(c) || std::strchr("!#$%&'*+-.^_`|~", c) != nullptr;
}

std::string_view trim_ows(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

struct HeadError {
  int status;
  const char* slug;
  std::string detail;
};

// Strict: what is accepted here is exactly what httplib parses the same way, so the two
// never disagree about where the head ends or what a field says (no bare CR or LF, no
// folded lines, no controls, one space between the request line's parts).
std::optional<HeadError> parse_head(std::string_view text, RequestHead& head) {
  // text ends with "\r\n\r\n"
  std::size_t line_start = 0;
  std::size_t lines = 0;
  while (line_start < text.size()) {
    const std::size_t end = text.find("\r\n", line_start);
    const std::string_view line = text.substr(line_start, end - line_start);
    line_start = end + 2;
    if (line.empty()) break;  // the blank line
    for (const char ch : line) {
      const auto c = static_cast<unsigned char>(ch);
      if (c == '\r' || c == '\n' || c == 0)
        return HeadError{400, "bad-request", "a bare CR, LF or NUL in the request head"};
    }
    if (lines++ == 0) {
      const std::size_t sp1 = line.find(' ');
      const std::size_t sp2 = sp1 == std::string_view::npos ? sp1 : line.find(' ', sp1 + 1);
      if (sp2 == std::string_view::npos || line.find(' ', sp2 + 1) != std::string_view::npos)
        return HeadError{400, "bad-request", "the request line is not METHOD TARGET VERSION"};
      head.method = std::string(line.substr(0, sp1));
      head.target = std::string(line.substr(sp1 + 1, sp2 - sp1 - 1));
      head.version = std::string(line.substr(sp2 + 1));
      if (head.method.empty() || !std::all_of(head.method.begin(), head.method.end(), [](char c) {
            return is_tchar(static_cast<unsigned char>(c));
          }))
        return HeadError{400, "bad-request", "the method is not a token"};
      if (head.target.size() > FrontEnd::kMaxTargetBytes)
        return HeadError{414, "uri-too-long", "the request target is longer than 8192 bytes"};
      if (head.target.empty() || head.target.front() != '/' ||
          std::any_of(head.target.begin(), head.target.end(), [](char ch) {
            const auto c = static_cast<unsigned char>(ch);
            return c <= 0x20 || c == 0x7f;
          }))
        return HeadError{400, "bad-request", "the request target must be an absolute path"};
      if (head.version != "HTTP/1.1" && head.version != "HTTP/1.0")
        return HeadError{400, "bad-request", "only HTTP/1.0 and HTTP/1.1 are spoken here"};
      continue;
    }
    if (head.fields.size() >= FrontEnd::kMaxFields)
      return HeadError{431, "header-fields-too-large",
                       "more than " + std::to_string(FrontEnd::kMaxFields) + " header fields"};
    if (line.size() > FrontEnd::kMaxLineBytes)
      return HeadError{431, "header-fields-too-large",
                       "a header field line is longer than " +
                           std::to_string(FrontEnd::kMaxLineBytes) + " bytes"};
    const std::size_t colon = line.find(':');
    if (colon == 0 || colon == std::string_view::npos)
      return HeadError{400, "bad-request", "a header field line has no name"};
    const std::string_view name = line.substr(0, colon);
    if (!std::all_of(name.begin(), name.end(),
                     [](char c) { return is_tchar(static_cast<unsigned char>(c)); }))
      return HeadError{400, "bad-request", "a header field name is not a token"};
    const std::string_view value = trim_ows(line.substr(colon + 1));
    if (std::any_of(value.begin(), value.end(), [](char ch) {
          const auto c = static_cast<unsigned char>(ch);
          return (c < 0x20 && c != '\t') || c == 0x7f;
        }))
      return HeadError{400, "bad-request", "a header field value has a control character"};
    head.fields.emplace_back(std::string(name), std::string(value));
  }
  return std::nullopt;
}

// The head httplib parses again on the worker: `Expect` is answered here already.
std::string replay_head(const RequestHead& head) {
  std::string out = head.method + " " + head.target + " " + head.version + "\r\n";
  for (const auto& [name, value] : head.fields)
    if (!equals_ignore_case(name, "Expect")) out += name + ": " + value + "\r\n";
  out += "\r\n";
  return out;
}

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

thread_local ReadRequest* current_request = nullptr;

}  // namespace

const std::string* RequestHead::find(std::string_view name) const {
  for (const auto& field : fields)
    if (equals_ignore_case(field.first, name)) return &field.second;
  return nullptr;
}

struct FrontEnd::Connection {
  enum class State {
    Head,    // reading the request head
    Body,    // reading Content-Length bytes of body
    Answer,  // writing the front end's own answer; input is dropped
    Linger,  // answered and shut down for writing: input is dropped until EOF or timeout
  };
  int fd = -1;
  std::size_t slot = 0;
  State state = State::Head;
  Clock::time_point accepted, deadline, idle_deadline;
  std::string in;           // the head so far
  std::size_t scanned = 0;  // in[0, scanned) holds no "\r\n\r\n"
  std::unique_ptr<RequestHead> head;
  std::unique_ptr<ReadRequest> request;  // Body: the request being read
  std::uint64_t body_expected = 0;
  std::string out;  // Answer: bytes to write
  std::size_t out_sent = 0;
  std::uint32_t events = 0;  // registered with epoll
  std::string remote_ip;
  int remote_port = 0;
};

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
  if (started_) stop({});
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
  started_ = true;
  for (std::size_t i = 0; i < options_.workers; ++i) workers_.emplace_back([this] { work(); });
  loop_thread_ = std::thread([this] { loop(); });
}

void FrontEnd::stop(std::string shutdown_response_for_bodies) {
  if (!started_) return;
  started_ = false;
  {
    std::lock_guard lock(inbox_mutex_);
    shutdown_response_ = std::move(shutdown_response_for_bodies);
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

ReadRequest* FrontEnd::current() {
  return current_request;
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
    current_request = request.get();
    try {
      delegate_.serve(*request);
    } catch (...) {
      // The delegate answers its own errors; nothing may take the worker down.
    }
    current_request = nullptr;
    const int fd = request->fd;
    request.reset();  // releases what the request held before the linger
    {
      std::lock_guard lock(inbox_mutex_);
      returned_.push_back(fd);
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
  std::uint32_t want = EPOLLIN;
  if (c.state == Connection::State::Answer && c.out_sent < c.out.size()) want |= EPOLLOUT;
  if (want == c.events) return;
  epoll_event ev{};
  ev.events = want;
  ev.data.u64 = c.slot + 1;
  ::epoll_ctl(epoll_fd_, c.events == 0 ? EPOLL_CTL_ADD : EPOLL_CTL_MOD, c.fd, &ev);
  c.events = want;
}

void FrontEnd::close(Connection& c) {
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c.fd, nullptr);
  ::close(c.fd);
  --open_;
  free_slots_.push_back(c.slot);
  connections_[c.slot].reset();  // c is gone
}

void FrontEnd::take_new() {
  std::vector<int> adopted, returned;
  {
    std::lock_guard lock(inbox_mutex_);
    adopted.swap(adopted_);
    returned.swap(returned_);
  }
  const auto now = Clock::now();
  auto make = [&](int fd) -> Connection& {
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
    return c;
  };
  for (int fd : returned) {
    // Answered by a worker: shut down for writing, then drop input until the client closes.
    Connection& c = make(fd);
    ::shutdown(fd, SHUT_WR);
    c.state = Connection::State::Linger;
    c.deadline = now + kLinger;
    update_events(c);
  }
  for (int fd : adopted) {
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
    int one = 1;
    // Answers are written in pieces (head, body): without this, Nagle's algorithm and the
    // peer's delayed ACK hold the second piece up to 40 ms.
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    Connection& c = make(fd);
    peer_of(fd, c.remote_ip, c.remote_port);
    c.deadline = now + options_.head_timeout;
    if (stopping_) {
      close(c);
      continue;
    }
    if (open_ > options_.max_connections) {
      answer(c, delegate_.refusal(nullptr, 503, "overloaded",
                                  "the server has " + std::to_string(options_.max_connections) +
                                      " connections open; retry later"));
      continue;
    }
    update_events(c);
  }
}

void FrontEnd::answer(Connection& c, std::string response) {
  c.request.reset();
  c.state = Connection::State::Answer;
  c.out = std::move(response);
  c.out_sent = 0;
  c.deadline = Clock::now() + options_.write_timeout;
  flush(c);
}

void FrontEnd::flush(Connection& c) {
  while (c.out_sent < c.out.size()) {
    const ssize_t n =
        ::send(c.fd, c.out.data() + c.out_sent, c.out.size() - c.out_sent, MSG_NOSIGNAL);
    if (n > 0) {
      c.out_sent += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      update_events(c);
      return;
    }
    return close(c);  // the peer is gone
  }
  // Sent: no more from us; read and drop what the client still sends, then close. Closing
  // with unread input would make the kernel reset the connection, and a client still
  // uploading could lose the answer.
  ::shutdown(c.fd, SHUT_WR);
  c.state = Connection::State::Linger;
  c.out.clear();
  c.out.shrink_to_fit();
  c.deadline = Clock::now() + kLinger;
  update_events(c);
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
  answer(c, delegate_.refusal(c.head.get(), 503, "overloaded",
                              "every worker is busy and " + std::to_string(options_.max_queued) +
                                  " requests wait; retry later"));
}

void FrontEnd::on_head(Connection& c, std::size_t head_end) {
  c.head = std::make_unique<RequestHead>();
  c.head->remote_ip = c.remote_ip;
  c.head->remote_port = c.remote_port;
  if (std::optional<HeadError> error =
          parse_head(std::string_view(c.in).substr(0, head_end), *c.head)) {
    const bool parsed = !c.head->method.empty() && !c.head->target.empty();
    return answer(c, delegate_.refusal(parsed ? c.head.get() : nullptr, error->status, error->slug,
                                       std::move(error->detail)));
  }
  Verdict verdict = delegate_.decide(*c.head);
  if (verdict.kind == Verdict::Kind::Answer) return answer(c, std::move(verdict.response));

  auto request = std::make_unique<ReadRequest>();
  request->fd = c.fd;
  request->head = replay_head(*c.head);
  request->remote_ip = c.remote_ip;
  request->remote_port = c.remote_port;
  request->accepted = c.accepted;
  request->hold = std::move(verdict.hold);
  if (verdict.kind == Verdict::Kind::Dispatch) {
    c.request = std::move(request);
    c.in.clear();
    return dispatch(c);
  }
  // ReadBody
  c.body_expected = verdict.body_bytes;
  request->body.reserve(static_cast<std::size_t>(c.body_expected));
  const std::string_view early = std::string_view(c.in).substr(head_end);
  request->body.append(early.substr(0, static_cast<std::size_t>(c.body_expected)));
  c.in.clear();
  c.in.shrink_to_fit();
  c.request = std::move(request);
  if (c.request->body.size() == c.body_expected) return dispatch(c);
  const std::string* expect = c.head->find("Expect");
  if (expect && equals_ignore_case(*expect, "100-continue") && c.request->body.empty()) {
    static constexpr std::string_view kContinue = "HTTP/1.1 100 Continue\r\n\r\n";
    // 25 bytes into a fresh socket's empty buffer: a partial send means the peer is gone.
    if (::send(c.fd, kContinue.data(), kContinue.size(), MSG_NOSIGNAL) !=
        static_cast<ssize_t>(kContinue.size()))
      return close(c);
  }
  const auto now = Clock::now();
  c.state = Connection::State::Body;
  c.idle_deadline = now + options_.idle_timeout;
  c.deadline = now + options_.head_timeout +
               std::chrono::milliseconds(c.body_expected * 1000 / kMinBodyRate);
}

void FrontEnd::on_readable(Connection& c) {
  char buffer[64 * 1024];
  // A bounded amount per wake-up, so one fast client cannot starve the others.
  for (int round = 0; round < 16; ++round) {
    std::size_t want = sizeof buffer;
    if (c.state == Connection::State::Head) want = std::min(want, kMaxHeadBytes + 4 - c.in.size());
    if (c.state == Connection::State::Body)
      want = std::min<std::uint64_t>(want, c.body_expected - c.request->body.size());
    const ssize_t n = ::recv(c.fd, buffer, want, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
    if (n <= 0) {
      // EOF or reset. A client that hangs up before its request is complete gets nothing.
      return close(c);
    }
    const auto got = static_cast<std::size_t>(n);
    switch (c.state) {
      case Connection::State::Head: {
        c.in.append(buffer, got);
        const std::size_t from = c.scanned >= 3 ? c.scanned - 3 : 0;
        const std::size_t end = c.in.find("\r\n\r\n", from);
        if (end != std::string::npos) return on_head(c, end + 4);
        c.scanned = c.in.size();
        if (c.in.size() > kMaxHeadBytes) {
          return answer(c, delegate_.refusal(nullptr, 431, "header-fields-too-large",
                                             "the request head is longer than " +
                                                 std::to_string(kMaxHeadBytes) + " bytes"));
        }
        break;
      }
      case Connection::State::Body:
        c.request->body.append(buffer, got);
        c.idle_deadline = Clock::now() + options_.idle_timeout;
        if (c.request->body.size() == c.body_expected) return dispatch(c);
        break;
      case Connection::State::Answer:
      case Connection::State::Linger:
        break;  // dropped
    }
  }
}

void FrontEnd::expire(Clock::time_point now) {
  for (std::size_t i = 0; i < connections_.size(); ++i) {
    Connection* c = connections_[i].get();
    if (!c) continue;
    switch (c->state) {
      case Connection::State::Head:
        if (stopping_) {
          close(*c);
        } else if (now > c->deadline) {
          answer(*c, delegate_.refusal(nullptr, 408, "request-timeout",
                                       "the request head did not arrive within " +
                                           std::to_string(options_.head_timeout.count()) + " ms"));
        }
        break;
      case Connection::State::Body:
        if (stopping_) {
          answer(*c, shutdown_response_);
        } else if (now > c->deadline || now > c->idle_deadline) {
          answer(*c, delegate_.refusal(c->head.get(), 408, "request-timeout",
                                       "the body stalled or arrived slower than " +
                                           std::to_string(kMinBodyRate / 1024) + " KiB/s"));
        }
        break;
      case Connection::State::Answer:
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
      Connection& c = *connections_[slot];
      if (events[i].events & EPOLLOUT) {
        flush(c);
        if (!connections_[slot] || connections_[slot].get() != &c) continue;
      }
      if (events[i].events & (EPOLLIN | EPOLLHUP | EPOLLERR)) on_readable(c);
    }
    if (woken || stopping_) take_new();
    const auto now = Clock::now();
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
