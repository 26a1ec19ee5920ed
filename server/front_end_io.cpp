// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
// The front end's reading of heads and bodies and its writing of answers, on its event loop.
#include <sys/epoll.h>
#include <sys/sendfile.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <optional>

#include "api/problem.h"
#include "server/front_end.h"
#include "server/front_end_connection.h"
#include "server/request_head.h"

namespace stlrefine::server {

namespace {

using Clock = std::chrono::steady_clock;

// Answers are written in pieces of at most this much per connection and wake-up, so one
// fast client cannot hold the event loop.
constexpr std::uint64_t kWriteSlice = 8 << 20;
// And made bodies (Answer::made) in at most this many pieces of FrontEnd::kMadePiece (1 MiB,
// about 21,000 STL facets).
constexpr std::size_t kMadePiecesPerRound = 4;
}  // namespace

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
  c.stream_idle = false;
  c.stream_ended = false;
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

void FrontEnd::flush_stream(Connection& c) {
  // The head, then each pulled piece (c.piece: stream bytes [piece_at, piece_at + size)).
  const Answer& a = c.out;
  std::uint64_t budget = kWriteSlice;
  c.stream_idle = false;
  for (;;) {
    std::string_view pending;
    if (c.sent < a.head.size()) {
      pending = std::string_view(a.head).substr(static_cast<std::size_t>(c.sent));
    } else {
      const std::uint64_t at = c.sent - a.head.size();
      if (at >= c.piece_at + c.piece.size()) {
        if (c.stream_ended) return finish_answer(c, AnswerEnd::Outcome::Complete);
        c.piece_at = at;
        c.piece.clear();
        bool more = false;
        try {
          more = a.stream(c.piece);
        } catch (...) {  // a broken stream ends
        }
        c.stream_ended = !more;
        if (c.piece.empty()) {
          if (c.stream_ended) return finish_answer(c, AnswerEnd::Outcome::Complete);
          c.stream_idle = true;  // expire() pulls again
          return update_events(c);
        }
      }
      pending = std::string_view(c.piece).substr(static_cast<std::size_t>(at - c.piece_at));
    }
    if (budget == 0) return update_events(c);
    const ssize_t n =
        ::send(c.fd, pending.data(), std::min<std::uint64_t>(pending.size(), budget), MSG_NOSIGNAL);
    if (n > 0) {
      c.sent += static_cast<std::uint64_t>(n);
      c.window_bytes += static_cast<std::uint64_t>(n);
      budget -= std::min<std::uint64_t>(budget, static_cast<std::uint64_t>(n));
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return update_events(c);
    return finish_answer(c, AnswerEnd::Outcome::ClientGone);
  }
}

void FrontEnd::flush(Connection& c) {
  if (c.out.stream) return flush_stream(c);
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
      // An event stream's client that hangs up is gone (SSE clients never half-close): its
      // place among the open streams is given back now, not at a write 15 s later.
      if (n == 0 && c.state == Connection::State::Answer && c.out.stream)
        return finish_answer(c, AnswerEnd::Outcome::ClientGone);
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

}  // namespace stlrefine::server
