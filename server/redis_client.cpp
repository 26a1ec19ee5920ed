// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/redis_client.h"

#include <hiredis/hiredis.h>
#include <sys/time.h>

#include <algorithm>
#include <charconv>

namespace stlrefine::server {

namespace {

timeval to_timeval(std::chrono::milliseconds t) {
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(t.count() / 1000);
  tv.tv_usec = static_cast<suseconds_t>((t.count() % 1000) * 1000);
  return tv;
}

// The URL as an error message shows it: credentials replaced by "***".
std::string shown(std::string_view url) {
  const std::size_t scheme = url.find("://");
  const std::size_t at = url.rfind('@');
  if (scheme == std::string_view::npos || at == std::string_view::npos || at < scheme)
    return std::string(url);
  return std::string(url.substr(0, scheme + 3)) + "***" + std::string(url.substr(at));
}

int parse_int(std::string_view text, int lo, int hi, const char* what, std::string_view url) {
  int n = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), n);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size() || n < lo || n > hi)
    throw std::invalid_argument(
        std::string("--queue '").append(shown(url)).append("': ").append(what) +
        " must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], not '" +
        std::string(text) + "'");
  return n;
}

[[noreturn]] void bad(std::string_view url, const std::string& why) {
  std::string m = "--queue '";
  m.append(shown(url)).append("': ").append(why);
  m.append(" (expected redis://[[USER]:PASSWORD@]HOST[:PORT][/DB] or unix:///PATH[?db=N])");
  throw std::invalid_argument(m);
}

}  // namespace

std::string RedisAddress::text() const {
  std::string t;
  if (!unix_path.empty()) {
    t = "unix://";
    t.append(unix_path);
    if (db != 0) t.append("?db=").append(std::to_string(db));
    return t;
  }
  t = "redis://";
  t.append(host.find(':') != std::string::npos ? "[" + host + "]" : host);
  t.append(":").append(std::to_string(port));
  if (db != 0) t.append("/").append(std::to_string(db));
  return t;
}

RedisAddress parse_redis_address(std::string_view url) {
  RedisAddress a;
  if (url.size() > 4096) bad(url.substr(0, 64), "too long");
  for (char c : url)
    if (static_cast<unsigned char>(c) < 0x21 || c == 0x7f) bad(url, "control character or space");
  constexpr std::string_view kUnix = "unix://", kRedis = "redis://";
  if (url.starts_with(kUnix)) {
    std::string_view rest = url.substr(kUnix.size());
    const std::size_t q = rest.find('?');
    if (q != std::string_view::npos) {
      const std::string_view query = rest.substr(q + 1);
      if (!query.starts_with("db=")) bad(url, "the only query parameter is db=N");
      a.db = parse_int(query.substr(3), 0, 15, "db", url);
      rest = rest.substr(0, q);
    }
    if (rest.empty() || rest.front() != '/') bad(url, "the socket path must be absolute");
    if (rest.size() >= 108) bad(url, "the socket path is longer than a unix socket's 107 bytes");
    a.unix_path = std::string(rest);
    return a;
  }
  if (url.starts_with("rediss://")) bad(url, "TLS (rediss://) is not supported");
  if (!url.starts_with(kRedis)) bad(url, "unknown scheme");
  std::string_view rest = url.substr(kRedis.size());
  if (const std::size_t at = rest.rfind('@'); at != std::string_view::npos) {
    // [USER]:PASSWORD@ (requirepass, or an ACL user); taken as written, not percent-decoded.
    const std::string_view credentials = rest.substr(0, at);
    const std::size_t colon = credentials.find(':');
    if (colon == std::string_view::npos) bad(url, "credentials are [USER]:PASSWORD@");
    a.user = std::string(credentials.substr(0, colon));
    a.password = std::string(credentials.substr(colon + 1));
    if (a.password.empty()) bad(url, "an empty password");
    rest = rest.substr(at + 1);
  }
  const std::size_t slash = rest.find('/');
  std::string_view hostport = rest.substr(0, slash);
  if (slash != std::string_view::npos) {
    const std::string_view db = rest.substr(slash + 1);
    if (!db.empty()) a.db = parse_int(db, 0, 15, "the database number", url);
  }
  if (hostport.starts_with("[")) {  // [IPv6]:port
    const std::size_t close = hostport.find(']');
    if (close == std::string_view::npos) bad(url, "unclosed '[' in the host");
    a.host = std::string(hostport.substr(1, close - 1));
    hostport = hostport.substr(close + 1);
    if (!hostport.empty()) {
      if (hostport.front() != ':') bad(url, "expected ':' after ']'");
      a.port = parse_int(hostport.substr(1), 1, 65535, "the port", url);
    }
  } else {
    const std::size_t colon = hostport.find(':');
    a.host = std::string(hostport.substr(0, colon));
    if (colon != std::string_view::npos)
      a.port = parse_int(hostport.substr(colon + 1), 1, 65535, "the port", url);
  }
  if (a.host.empty()) bad(url, "no host");
  if (a.host.size() > 253) bad(url, "the host name is longer than 253 characters");
  return a;
}

RedisReply::RedisReply(redisReply* r)
    : reply_(r), owner_(r, [](redisReply* p) { freeReplyObject(p); }) {}

bool RedisReply::nil() const {
  return !reply_ || reply_->type == REDIS_REPLY_NIL;
}
bool RedisReply::is_array() const {
  return reply_ && reply_->type == REDIS_REPLY_ARRAY;
}
bool RedisReply::is_integer() const {
  return reply_ && reply_->type == REDIS_REPLY_INTEGER;
}
std::size_t RedisReply::size() const {
  return is_array() ? reply_->elements : 0;
}
RedisReply RedisReply::at(std::size_t i) const {
  if (i >= size()) return RedisReply(nullptr, owner_);
  return RedisReply(reply_->element[i], owner_);
}
std::string RedisReply::str() const {
  if (!reply_) return {};
  if (reply_->type == REDIS_REPLY_STRING || reply_->type == REDIS_REPLY_STATUS ||
      reply_->type == REDIS_REPLY_ERROR)
    return std::string(reply_->str, reply_->len);
  if (reply_->type == REDIS_REPLY_INTEGER) return std::to_string(reply_->integer);
  return {};
}
long long RedisReply::integer() const {
  if (!reply_) return 0;
  if (reply_->type == REDIS_REPLY_INTEGER) return reply_->integer;
  long long n = 0;
  const std::string s = str();
  std::from_chars(s.data(), s.data() + s.size(), n);
  return n;
}

RedisConnection::RedisConnection(RedisAddress address, std::chrono::milliseconds timeout)
    : address_(std::move(address)), timeout_(timeout) {}

RedisConnection::~RedisConnection() {
  if (context_) redisFree(context_);
}

void RedisConnection::broken(const std::string& what) {
  if (context_) {
    redisFree(context_);
    context_ = nullptr;
  }
  // Back-off: a dead Redis costs each caller one quick refusal, not a connect timeout each.
  backoff_ =
      std::clamp(backoff_ * 2, std::chrono::milliseconds(100), std::chrono::milliseconds(2000));
  retry_at_ = std::chrono::steady_clock::now() + backoff_;
  last_error_ = what;
  throw RedisUnavailable("Redis at " + address_.text() + ": " + what);
}

void RedisConnection::set_timeout(std::chrono::milliseconds t) {
  if (redisSetTimeout(context_, to_timeval(t)) != REDIS_OK) broken("cannot set a timeout");
}

void RedisConnection::connect() {
  if (context_) return;
  if (std::chrono::steady_clock::now() < retry_at_)
    throw RedisUnavailable("Redis at " + address_.text() + ": " + last_error_ + " (reconnecting)");
  const timeval tv = to_timeval(timeout_);
  context_ = address_.unix_path.empty()
                 ? redisConnectWithTimeout(address_.host.c_str(), address_.port, tv)
                 : redisConnectUnixWithTimeout(address_.unix_path.c_str(), tv);
  if (!context_) broken("cannot allocate a connection");
  if (context_->err) broken(std::string("cannot connect: ") + context_->errstr);
  set_timeout(timeout_);
  backoff_ = std::chrono::milliseconds(0);
  if (!address_.password.empty()) {
    try {
      if (address_.user.empty())
        command({"AUTH", address_.password});
      else
        command({"AUTH", address_.user, address_.password});
    } catch (const RedisError& e) {
      broken(std::string("authentication refused (") + e.what() + ")");  // never the password
    }
  }
  if (address_.db != 0) command({"SELECT", std::to_string(address_.db)});
}

RedisReply RedisConnection::command(const std::vector<std::string>& argv,
                                    std::chrono::milliseconds block) {
  connect();
  std::vector<const char*> args;
  std::vector<std::size_t> lens;
  for (const std::string& a : argv) {
    args.push_back(a.data());
    lens.push_back(a.size());
  }
  if (block.count() > 0) set_timeout(timeout_ + block);
  auto* r = static_cast<redisReply*>(
      redisCommandArgv(context_, static_cast<int>(args.size()), args.data(), lens.data()));
  if (!r) broken(context_->errstr[0] ? context_->errstr : "connection lost");
  RedisReply reply(r);
  if (block.count() > 0) set_timeout(timeout_);
  if (r->type == REDIS_REPLY_ERROR) throw RedisError(argv.front() + ": " + reply.str());
  return reply;
}

std::vector<RedisReply> RedisConnection::pipeline(
    const std::vector<std::vector<std::string>>& commands) {
  connect();
  for (const auto& argv : commands) {
    std::vector<const char*> args;
    std::vector<std::size_t> lens;
    for (const std::string& a : argv) {
      args.push_back(a.data());
      lens.push_back(a.size());
    }
    if (redisAppendCommandArgv(context_, static_cast<int>(args.size()), args.data(), lens.data()) !=
        REDIS_OK)
      broken("cannot queue a command");
  }
  std::vector<RedisReply> replies;
  std::string error;
  for (std::size_t i = 0; i < commands.size(); ++i) {
    void* r = nullptr;
    if (redisGetReply(context_, &r) != REDIS_OK || !r)
      broken(context_->errstr[0] ? context_->errstr : "connection lost");
    replies.emplace_back(static_cast<redisReply*>(r));
    if (replies.back().raw()->type == REDIS_REPLY_ERROR && error.empty())
      error = commands[i].front() + ": " + replies.back().str();
  }
  if (!error.empty()) throw RedisError(error);
  return replies;
}

RedisPool::RedisPool(RedisAddress address, std::chrono::milliseconds timeout, std::size_t idle)
    : address_(std::move(address)), timeout_(timeout), max_idle_(idle) {}

RedisPool::Handle RedisPool::take() {
  {
    std::lock_guard lock(mutex_);
    if (!idle_.empty()) {
      auto c = std::move(idle_.back());
      idle_.pop_back();
      return Handle(*this, std::move(c));
    }
  }
  return Handle(*this, std::make_unique<RedisConnection>(address_, timeout_));
}

RedisPool::Handle::~Handle() {
  std::lock_guard lock(pool_.mutex_);
  if (pool_.idle_.size() < pool_.max_idle_) pool_.idle_.push_back(std::move(c_));
}

}  // namespace stlrefine::server
