// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// A job's `callback_url`: when the job ends, its JSON is POSTed there with
// `X-Stlrefine-Timestamp: <unix seconds>` and `X-Stlrefine-Signature: sha256=<HMAC-SHA256
// hex of "<timestamp>.<body>">` under the job's tenant's callback key (tenant_callback_key:
// one tenant cannot verify, or forge, what another receives; the timestamp lets a receiver
// refuse replays), retried with exponential back-off. Only hosts on the server's allow-list
// (`--callback-allow HOST[:PORT]`) are called, and never a loopback, link-local, private or
// otherwise special address unless the allow-list names that address itself: the check is
// made on the resolved addresses, at submit and again at each delivery, and the request
// goes to the address checked (no second resolution a DNS rebinding could answer).

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "api/problem.h"

namespace stlrefine::server {

struct CallbackPolicy {
  std::string secret;                       //!< HMAC key; empty: callbacks are refused
  std::vector<std::string> allow;           //!< HOST[:PORT] entries; empty: callbacks are refused
  int attempts = 5;                         //!< deliveries tried at most
  std::chrono::milliseconds backoff{1000};  //!< before the 2nd try; doubles after each
  std::chrono::milliseconds timeout{5000};  //!< connect, send and answer, per try
};

//! Where a checked callback goes.
struct CallbackTarget {
  std::string scheme;  //!< http or https
  std::string host;    //!< as in the URL (brackets removed)
  int port = 0;
  std::string path;     //!< path and query, "/" at least
  std::string address;  //!< the resolved address that passed the checks
};

//! Checks `url` (syntax, scheme, allow-list, resolved addresses) against `policy`: a 400
//! problem naming `callback_url`, or nullopt with `out` set.
std::optional<api::Problem> check_callback_url(const CallbackPolicy& policy, const std::string& url,
                                               CallbackTarget* out);

//! A tenant's callback key: the HMAC-SHA256 of its tenant id (JobStore::tenant_of) under the
//! server's callback secret, as 64 lowercase hex digits (the key is those 64 ASCII bytes).
std::string tenant_callback_key(const std::string& secret, const std::string& tenant);
//! tenant_callback_key of an API key, with the tenant id made from the data directory's
//! `.tenant-key` as the daemon makes it: what the operator hands the key's holder
//! (stlrefined --print-callback-key). An empty key: the tenant of a daemon without API keys
//! (tenant id "").
std::string callback_key_of_api_key(const std::filesystem::path& data_dir,
                                    const std::string& secret, std::string_view api_key);
//! "sha256=" + the HMAC-SHA256 of "<timestamp>.<body>" under `key`, in lowercase hex.
std::string callback_signature(const std::string& key, std::int64_t timestamp,
                               const std::string& body);

//! Delivers callbacks on its own thread, one at a time, with retries.
class CallbackSender {
 public:
  explicit CallbackSender(CallbackPolicy policy);
  //! Stops; deliveries still pending are dropped (and logged).
  ~CallbackSender();
  CallbackSender(const CallbackSender&) = delete;
  CallbackSender& operator=(const CallbackSender&) = delete;

  //! Queues the POST of `body` (a job's JSON) to `url`, signed with `tenant`'s key.
  void send(std::string url, std::string body, const std::string& tenant);
  const CallbackPolicy& policy() const { return policy_; }

 private:
  struct Delivery {
    std::string url, body;
    std::string key;  // the tenant's callback key
    int attempt = 0;
    std::chrono::steady_clock::time_point due;
  };
  void run();
  bool deliver(const Delivery& d);

  CallbackPolicy policy_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Delivery> queue_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace stlrefine::server
