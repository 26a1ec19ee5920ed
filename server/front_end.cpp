// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/front_end.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/sendfile.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <optional>
#include <stdexcept>

#include "api/problem.h"
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
  // text ends with "\r\n\r\n". Empty lines before the request line are skipped (RFC 9112
  // 2.2); a head that is nothing else has no request line at all.
  std::size_t line_start = 0;
  while (text.substr(line_start, 2) == "\r\n" && line_start + 4 < text.size()) line_start += 2;
  if (text.substr(line_start, 2) == "\r\n")
    return HeadError{api::http::kBadRequest, "bad-request", "the request line is empty"};
  std::size_t lines = 0;
  while (line_start < text.size()) {
    const std::size_t end = text.find("\r\n", line_start);
    const std::string_view line = text.substr(line_start, end - line_start);
    line_start = end + 2;
    if (line.empty()) break;  // the blank line
    for (const char ch : line) {
      const auto c = static_cast<unsigned char>(ch);
      if (c == '\r' || c == '\n' || c == 0)
        return HeadError{api::http::kBadRequest, "bad-request",
                         "a bare CR, LF or NUL in the request head"};
    }
    if (lines++ == 0) {
      const std::size_t sp1 = line.find(' ');
      const std::size_t sp2 = sp1 == std::string_view::npos ? sp1 : line.find(' ', sp1 + 1);
      if (sp2 == std::string_view::npos || line.find(' ', sp2 + 1) != std::string_view::npos)
        return HeadError{api::http::kBadRequest, "bad-request",
                         "the request line is not METHOD TARGET VERSION"};
      head.method = std::string(line.substr(0, sp1));
      head.target = std::string(line.substr(sp1 + 1, sp2 - sp1 - 1));
      head.version = std::string(line.substr(sp2 + 1));
      if (head.method.empty() || !std::all_of(head.method.begin(), head.method.end(), [](char c) {
            return is_tchar(static_cast<unsigned char>(c));
          }))
        return HeadError{api::http::kBadRequest, "bad-request", "the method is not a token"};
      if (head.target.size() > FrontEnd::kMaxTargetBytes)
        return HeadError{api::http::kUriTooLong, "uri-too-long",
                         "the request target is longer than 8192 bytes"};
      if (head.target.empty() || head.target.front() != '/' ||
          std::any_of(head.target.begin(), head.target.end(), [](char ch) {
            const auto c = static_cast<unsigned char>(ch);
            return c <= 0x20 || c == 0x7f;
          }))
        return HeadError{api::http::kBadRequest, "bad-request",
                         "the request target must be an absolute path"};
      if (head.version != "HTTP/1.1" && head.version != "HTTP/1.0")
        return HeadError{api::http::kBadRequest, "bad-request",
                         "only HTTP/1.0 and HTTP/1.1 are spoken here"};
      continue;
    }
    if (head.fields.size() >= FrontEnd::kMaxFields)
      return HeadError{api::http::kHeaderFieldsTooLarge, "header-fields-too-large",
                       "more than " + std::to_string(FrontEnd::kMaxFields) + " header fields"};
    if (line.size() > FrontEnd::kMaxLineBytes)
      return HeadError{api::http::kHeaderFieldsTooLarge, "header-fields-too-large",
                       "a header field line is longer than " +
                           std::to_string(FrontEnd::kMaxLineBytes) + " bytes"};
    const std::size_t colon = line.find(':');
    if (colon == 0 || colon == std::string_view::npos)
      return HeadError{api::http::kBadRequest, "bad-request", "a header field line has no name"};
    const std::string_view name = line.substr(0, colon);
    if (!std::all_of(name.begin(), name.end(),
                     [](char c) { return is_tchar(static_cast<unsigned char>(c)); }))
      return HeadError{api::http::kBadRequest, "bad-request", "a header field name is not a token"};
    const std::string_view value = trim_ows(line.substr(colon + 1));
    if (std::any_of(value.begin(), value.end(), [](char ch) {
          const auto c = static_cast<unsigned char>(ch);
          return (c < 0x20 && c != '\t') || c == 0x7f;
        }))
      return HeadError{api::http::kBadRequest, "bad-request",
                       "a header field value has a control character"};
    head.fields.emplace_back(std::string(name), std::string(value));
  }
  return std::nullopt;
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

// Answers are written in pieces of at most this much per connection and wake-up, so one
// fast client cannot hold the event loop.
constexpr std::uint64_t kWriteSlice = 8 << 20;
// And made bodies (Answer::made) in at most this many pieces of FrontEnd::kMadePiece (1 MiB,
// about 21,000 STL facets).
constexpr std::size_t kMadePiecesPerRound = 4;

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
      keep(std::move(other.keep)),
      done(std::move(other.done)) {
  other.body = {};
  other.file = -1;
  other.file_length = 0;
  other.made = nullptr;
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
    keep = std::move(other.keep);
    done = std::move(other.done);
    other.body = {};
    other.file = -1;
    other.file_length = 0;
    other.made = nullptr;
    other.made_length = 0;
  }
  return *this;
}

Answer::~Answer() {
  if (file >= 0) ::close(file);
}

const std::string* RequestHead::find(std::string_view name) const {
  for (const auto& field : fields)
    if (equals_ignore_case(field.first, name)) return &field.second;
  return nullptr;
}

struct FrontEnd::Connection {
  enum class State {
    Head,    // reading the request head
    Body,    // reading Content-Length bytes of body
    Answer,  // writing an answer; input is dropped
    Linger,  // answered and shut down for writing: input is dropped until EOF or timeout
  };
  int fd = -1;
  std::size_t slot = 0;
  State state = State::Head;
  Clock::time_point accepted, deadline;
  // Body and Answer: bytes moved since window_start (the minimum-rate check).
  Clock::time_point window_start;
  std::uint64_t window_bytes = 0;
  std::string in;                        // the head so far
  std::size_t scanned = 0;               // in[0, scanned) holds no "\r\n\r\n"
  std::unique_ptr<ReadRequest> request;  // Body: the request being read
  std::uint64_t body_expected = 0;
  std::function<std::string(std::uint64_t)> reserve_body;
  Answer out;  // Answer: what is written
  std::uint64_t sent = 0;
  // A made body's current piece: its bytes [piece_at, piece_at + piece.size()).
  std::string piece;
  std::uint64_t piece_at = 0;
  std::shared_ptr<void> hold;  // released once the answer is written
  bool in_probe_lane = false;
  bool read_closed = false;  // the client half-closed while its answer is written
  std::uint32_t events = 0;  // registered with epoll
  bool registered = false;
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
  if (c.state == Connection::State::Answer) want |= EPOLLOUT;
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

void FrontEnd::answer(Connection& c, Answer answer) {
  c.request.reset();
  c.reserve_body = nullptr;
  c.state = Connection::State::Answer;
  c.out = std::move(answer);
  c.sent = 0;
  c.window_start = Clock::now();
  c.window_bytes = 0;
  if (grace_over_) return finish_answer(c, AnswerEnd::Outcome::Shutdown);
  flush(c);
}

void FrontEnd::finish_answer(Connection& c, AnswerEnd::Outcome outcome) {
  if (c.out.done) {
    AnswerEnd end{outcome, c.sent, c.out.size()};
    auto done = std::move(c.out.done);
    done(end);
  }
  c.out = Answer();  // the body, its file and what kept them
  c.piece = std::string();
  c.piece_at = 0;
  c.hold.reset();  // the reservation
  if (outcome != AnswerEnd::Outcome::Complete) return close(c);
  // Sent: no more from us; read and drop what the client still sends, then close. Closing
  // with unread input would make the kernel reset the connection, and a client still
  // uploading could lose the answer.
  ::shutdown(c.fd, SHUT_WR);
  c.state = Connection::State::Linger;
  c.deadline = Clock::now() + kLinger;
  update_events(c);
}

void FrontEnd::flush(Connection& c) {
  const Answer& a = c.out;
  const std::uint64_t head_end = a.head.size();
  const std::uint64_t body_end = head_end + a.body.size();
  const std::uint64_t file_end = body_end + a.file_length;
  std::uint64_t budget = kWriteSlice;
  // Making a piece costs the event loop time that sending one does not: fewer per round.
  std::size_t pieces = kMadePiecesPerRound;
  while (c.sent < a.size()) {
    if (budget == 0) return update_events(c);  // the rest on a later round
    ssize_t n;
    if (c.sent < head_end) {
      n = ::send(c.fd, a.head.data() + c.sent, head_end - c.sent, MSG_NOSIGNAL);
    } else if (c.sent < body_end) {
      const std::uint64_t at = c.sent - head_end;
      n = ::send(c.fd, a.body.data() + at, std::min(a.body.size() - at, budget), MSG_NOSIGNAL);
    } else if (c.sent < file_end) {
      const std::uint64_t at = c.sent - body_end;
      auto offset = static_cast<off_t>(a.file_offset + at);
      n = ::sendfile(c.fd, a.file, &offset, std::min(a.file_length - at, budget));
      // A file shorter than announced: the answer cannot be completed.
      if (n == 0) return finish_answer(c, AnswerEnd::Outcome::ClientGone);
    } else {
      const std::uint64_t at = c.sent - file_end;
      if (at < c.piece_at || at >= c.piece_at + c.piece.size()) {
        if (pieces-- == 0) return update_events(c);  // the rest on a later round
        // The next piece, made where it is sent; what the kernel took of the last is gone.
        c.piece.resize(
            static_cast<std::size_t>(std::min<std::uint64_t>(kMadePiece, a.made_length - at)));
        c.piece_at = at;
        try {
          a.made(a.made_offset + at, std::span(c.piece.data(), c.piece.size()));
        } catch (...) {  // a broken promise: the answer cannot be completed
          return finish_answer(c, AnswerEnd::Outcome::ClientGone);
        }
      }
      const std::size_t within = static_cast<std::size_t>(at - c.piece_at);
      n = ::send(c.fd, c.piece.data() + within,
                 std::min<std::uint64_t>(c.piece.size() - within, budget), MSG_NOSIGNAL);
    }
    if (n > 0) {
      const auto moved = static_cast<std::uint64_t>(n);
      c.sent += moved;
      c.window_bytes += moved;
      budget -= std::min(budget, moved);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return update_events(c);
    return finish_answer(c, AnswerEnd::Outcome::ClientGone);  // the peer is gone
  }
  finish_answer(c, AnswerEnd::Outcome::Complete);
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

bool FrontEnd::grow_body(Connection& c, std::size_t incoming) {
  std::string& body = c.request->body;
  const std::size_t need = body.size() + incoming;
  if (need <= body.capacity()) return true;
  std::size_t target = std::max({need, 2 * body.capacity(), kBodyChunk});
  target = static_cast<std::size_t>(std::min<std::uint64_t>(target, c.body_expected));
  if (c.reserve_body) {
    std::string refusal = c.reserve_body(target);
    if (!refusal.empty()) {
      answer(c, Answer(std::move(refusal)));
      return false;
    }
  }
  body.reserve(target);
  return true;
}

void FrontEnd::on_head(Connection& c, std::size_t head_end) {
  const bool probe_lane = c.in_probe_lane;
  if (probe_lane) {
    probe_lane_.erase(std::find(probe_lane_.begin(), probe_lane_.end(), c.slot));
    c.in_probe_lane = false;
  }
  auto request = std::make_unique<ReadRequest>();
  RequestHead& head = request->head;
  head.remote_ip = c.remote_ip;
  head.remote_port = c.remote_port;
  if (std::optional<HeadError> error =
          parse_head(std::string_view(c.in).substr(0, head_end), head)) {
    const bool parsed = !head.method.empty() && !head.target.empty();
    return answer(c, Answer(delegate_.refusal(parsed ? &head : nullptr, error->status, error->slug,
                                              std::move(error->detail))));
  }
  Verdict verdict = delegate_.decide(head);
  if (verdict.kind == Verdict::Kind::Answer) return answer(c, Answer(std::move(verdict.response)));
  if (probe_lane) {
    // Over a connection cap: only what decide() answers at once (the probes, refusals).
    return answer(
        c, Answer(delegate_.refusal(&head, api::http::kServiceUnavailable, "overloaded",
                                    "too many connections are open (from this address, or in all); "
                                    "retry later")));
  }

  request->fd = c.fd;
  request->accepted = c.accepted;
  request->hold = std::move(verdict.hold);
  if (verdict.kind == Verdict::Kind::Dispatch) {
    c.request = std::move(request);
    c.in.clear();
    return dispatch(c);
  }
  // ReadBody
  c.body_expected = verdict.body_bytes;
  c.reserve_body = std::move(verdict.reserve_body);
  c.request = std::move(request);
  const std::string_view early =
      std::string_view(c.in).substr(head_end).substr(0, static_cast<std::size_t>(c.body_expected));
  if (!early.empty()) {
    if (!grow_body(c, early.size())) return;
    c.request->body.append(early);
  }
  c.in.clear();
  c.in.shrink_to_fit();
  if (c.request->body.size() == c.body_expected) return dispatch(c);
  const std::string* expect = c.request->head.find("Expect");
  if (expect && equals_ignore_case(*expect, "100-continue") && c.request->body.empty()) {
    static constexpr std::string_view kContinue = "HTTP/1.1 100 Continue\r\n\r\n";
    // 25 bytes into a fresh socket's empty buffer: a partial send means the peer is gone.
    if (::send(c.fd, kContinue.data(), kContinue.size(), MSG_NOSIGNAL) !=
        static_cast<ssize_t>(kContinue.size()))
      return close(c);
  }
  c.state = Connection::State::Body;
  c.window_start = Clock::now();
  c.window_bytes = 0;
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
      // EOF or reset. A client that hangs up before its request is complete gets nothing;
      // one that half-closes while its answer is written still gets it.
      if (n == 0 && c.state == Connection::State::Answer) {
        c.read_closed = true;  // EPOLLIN would report the EOF again and again
        return update_events(c);
      }
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
          return answer(c, Answer(delegate_.refusal(nullptr, api::http::kHeaderFieldsTooLarge,
                                                    "header-fields-too-large",
                                                    "the request head is longer than " +
                                                        std::to_string(kMaxHeadBytes) + " bytes")));
        }
        break;
      }
      case Connection::State::Body:
        if (!grow_body(c, got)) return;
        c.request->body.append(buffer, got);
        c.window_bytes += got;
        if (c.request->body.size() == c.body_expected) return dispatch(c);
        break;
      case Connection::State::Answer:
      case Connection::State::Linger:
        break;  // dropped
    }
  }
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
        if (grace_over_)
          finish_answer(*c, AnswerEnd::Outcome::Shutdown);
        else if (too_slow(*c, now, options_.answer_window, c->out.size() - c->sent))
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
