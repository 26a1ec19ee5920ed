// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A small synchronous Redis client over hiredis for the job queue (server/queue_redis.h):
// an address parsed from `--queue`, one connection per thread that owns it (hiredis contexts
// are not thread-safe) or a small pool, a timeout on every call so that a dead Redis never
// holds a thread, and a reconnect with back-off.

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

struct redisContext;
struct redisReply;

namespace stlrefine::server {

//! Where Redis is: `redis://[[USER]:PASSWORD@]HOST:PORT[/DB]` (PORT optional, 6379) or
//! `unix:///PATH[?db=N]`.
struct RedisAddress {
  std::string host;          //!< TCP host (name or address; IPv6 in brackets in the URL)
  int port = 6379;           //!< TCP port
  std::string unix_path;     //!< socket path; set for unix:// (then host is empty)
  int db = 0;                //!< SELECTed after connecting, in [0, 15]
  std::string user;          //!< AUTH user (ACL); empty: the default user
  std::string password;      //!< AUTH after connecting when not empty
  std::string text() const;  //!< the address without its credentials
};

//! \throw std::invalid_argument naming what is wrong with `url`.
RedisAddress parse_redis_address(std::string_view url);

//! Redis could not be reached, or the connection broke or timed out (the call may or may not
//! have happened). The caller retries later; a submission answers 503.
class RedisUnavailable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! Redis answered with an error reply (e.g. NOGROUP): a bug or a Redis in an unexpected
//! state, not an outage.
class RedisError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! An owned reply: a tree of strings, integers, arrays and nil.
class RedisReply {
 public:
  RedisReply() = default;
  explicit RedisReply(redisReply* r);
  bool nil() const;
  bool is_array() const;
  bool is_integer() const;
  std::size_t size() const;  //!< elements of an array (0 otherwise)
  //! Element `i` of an array, not owned (lives as long as this reply).
  RedisReply at(std::size_t i) const;
  std::string str() const;    //!< string or status (empty for nil)
  long long integer() const;  //!< integer (or a string that is one)
  redisReply* raw() const { return reply_; }

 private:
  RedisReply(redisReply* r, std::shared_ptr<redisReply> owner)
      : reply_(r), owner_(std::move(owner)) {}
  redisReply* reply_ = nullptr;
  std::shared_ptr<redisReply> owner_;
};

//! One connection, used by one thread at a time. Connects on first use; after a failure it
//! waits a back-off (100 ms doubling to 2 s) before trying again, and calls in between fail
//! at once with RedisUnavailable.
class RedisConnection {
 public:
  //! `timeout`: connecting, and each call's reply (a blocking command's wait comes on top,
  //! see command()).
  RedisConnection(RedisAddress address, std::chrono::milliseconds timeout);
  ~RedisConnection();
  RedisConnection(const RedisConnection&) = delete;
  RedisConnection& operator=(const RedisConnection&) = delete;

  //! One command, binary-safe. `block`: how long the command itself may wait in Redis (XREADGROUP
  //! BLOCK), added to the timeout for this call.
  //! \throw RedisUnavailable, RedisError
  RedisReply command(const std::vector<std::string>& argv,
                     std::chrono::milliseconds block = std::chrono::milliseconds(0));
  //! Several commands in one round trip; each reply in order (an error reply throws RedisError
  //! after all were read).
  std::vector<RedisReply> pipeline(const std::vector<std::vector<std::string>>& commands);
  const RedisAddress& address() const { return address_; }

 private:
  void connect();
  [[noreturn]] void broken(const std::string& what);
  void set_timeout(std::chrono::milliseconds t);

  RedisAddress address_;
  std::chrono::milliseconds timeout_;
  redisContext* context_ = nullptr;
  std::chrono::steady_clock::time_point retry_at_{};
  std::chrono::milliseconds backoff_{0};
  std::string last_error_;
};

//! Connections for threads that do not own one (HTTP workers): taken for one operation and
//! given back; at most `idle` are kept.
class RedisPool {
 public:
  RedisPool(RedisAddress address, std::chrono::milliseconds timeout, std::size_t idle = 8);
  class Handle {
   public:
    Handle(RedisPool& pool, std::unique_ptr<RedisConnection> c) : pool_(pool), c_(std::move(c)) {}
    ~Handle();
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;
    RedisConnection* operator->() { return c_.get(); }
    RedisConnection& operator*() { return *c_; }

   private:
    RedisPool& pool_;
    std::unique_ptr<RedisConnection> c_;
  };
  Handle take();
  const RedisAddress& address() const { return address_; }
  std::chrono::milliseconds timeout() const { return timeout_; }

 private:
  RedisAddress address_;
  std::chrono::milliseconds timeout_;
  std::size_t max_idle_;
  std::mutex mutex_;
  std::vector<std::unique_ptr<RedisConnection>> idle_;
};

}  // namespace stlrefine::server
