// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/job_callbacks.h"

#include <arpa/inet.h>
#include <httplib.h>
#include <netdb.h>
#include <netinet/in.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <sys/socket.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <stdexcept>

#include "server/routes.h"

namespace stlrefine::server {

namespace {

constexpr std::size_t kMaxUrl = 2048;

api::Problem url_problem(std::string detail) {
  api::Problem p = api::bad_request("invalid-parameter", std::move(detail));
  p.field = "callback_url";
  return p;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// "host", "host:port", "[v6]", "[v6]:port" -> host (no brackets) and port (0: none).
bool split_host_port(std::string_view text, std::string& host, int& port) {
  port = 0;
  std::string_view rest;
  if (!text.empty() && text.front() == '[') {
    const std::size_t close = text.find(']');
    if (close == std::string_view::npos) return false;
    host = std::string(text.substr(1, close - 1));
    rest = text.substr(close + 1);
  } else {
    const std::size_t colon = text.find(':');
    host = std::string(text.substr(0, colon));
    rest = colon == std::string_view::npos ? std::string_view() : text.substr(colon);
  }
  if (host.empty()) return false;
  if (!rest.empty()) {
    if (rest.front() != ':' || rest.size() < 2 || rest.size() > 6) return false;
    const auto [end, ec] = std::from_chars(rest.data() + 1, rest.data() + rest.size(), port);
    if (ec != std::errc() || end != rest.data() + rest.size() || port < 1 || port > 65535)
      return false;
  }
  host = lower(host);
  return true;
}

bool ip_literal(const std::string& host) {
  unsigned char buf[sizeof(in6_addr)];
  return ::inet_pton(AF_INET, host.c_str(), buf) == 1 ||
         ::inet_pton(AF_INET6, host.c_str(), buf) == 1;
}

// Loopback, link-local, private, shared (CGNAT), unspecified, multicast, reserved: what a
// callback must not reach unless named by the allow-list itself.
bool special_v4(std::uint32_t a) {
  const auto in = [a](std::uint32_t net, int bits) {
    return (a >> (32 - bits)) == (net >> (32 - bits));
  };
  return in(0x00000000, 8) || in(0x0A000000, 8) || in(0x64400000, 10) || in(0x7F000000, 8) ||
         in(0xA9FE0000, 16) || in(0xAC100000, 12) || in(0xC0000000, 24) || in(0xC0A80000, 16) ||
         in(0xC6120000, 15) || in(0xE0000000, 4) || in(0xF0000000, 4);
}

bool special_address(const sockaddr* sa) {
  if (sa->sa_family == AF_INET) {
    const auto* v4 = reinterpret_cast<const sockaddr_in*>(sa);
    return special_v4(ntohl(v4->sin_addr.s_addr));
  }
  if (sa->sa_family == AF_INET6) {
    const auto* v6 = reinterpret_cast<const sockaddr_in6*>(sa);
    const unsigned char* b = v6->sin6_addr.s6_addr;
    if (IN6_IS_ADDR_V4MAPPED(&v6->sin6_addr) || IN6_IS_ADDR_V4COMPAT(&v6->sin6_addr)) {
      const std::uint32_t a = (std::uint32_t{b[12]} << 24) | (std::uint32_t{b[13]} << 16) |
                              (std::uint32_t{b[14]} << 8) | b[15];
      return special_v4(a);
    }
    // Prefixes that carry an IPv4 address to somewhere else: NAT64 (64:ff9b::/96 and the
    // local-use 64:ff9b:1::/48), 6to4 (2002::/16), Teredo (2001::/32), IPv4-translated
    // (::ffff:0:0:0/96): refused whatever the embedded address, as is anything the
    // allow-list does not name by address.
    const bool nat64 = b[0] == 0x00 && b[1] == 0x64 && b[2] == 0xff && b[3] == 0x9b;
    const bool six_to_four = b[0] == 0x20 && b[1] == 0x02;
    const bool teredo = b[0] == 0x20 && b[1] == 0x01 && b[2] == 0x00 && b[3] == 0x00;
    const bool translated = std::all_of(b, b + 8, [](unsigned char x) { return x == 0; }) &&
                            b[8] == 0xff && b[9] == 0xff && b[10] == 0 && b[11] == 0;
    return IN6_IS_ADDR_UNSPECIFIED(&v6->sin6_addr) || IN6_IS_ADDR_LOOPBACK(&v6->sin6_addr) ||
           IN6_IS_ADDR_LINKLOCAL(&v6->sin6_addr) || IN6_IS_ADDR_SITELOCAL(&v6->sin6_addr) ||
           IN6_IS_ADDR_MULTICAST(&v6->sin6_addr) || (b[0] & 0xFE) == 0xFC ||  // fc00::/7
           nat64 || six_to_four || teredo || translated;
  }
  return true;  // not an IP address at all
}

std::string address_text(const sockaddr* sa) {
  char text[INET6_ADDRSTRLEN] = {};
  if (sa->sa_family == AF_INET)
    ::inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(sa)->sin_addr, text, sizeof text);
  else
    ::inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6*>(sa)->sin6_addr, text, sizeof text);
  return text;
}

}  // namespace

std::optional<api::Problem> check_callback_url(const CallbackPolicy& policy, const std::string& url,
                                               CallbackTarget* out) {
  if (policy.allow.empty() || policy.secret.empty())
    return url_problem(
        "this server sends no callbacks (it needs --callback-allow and --callback-secret); "
        "follow the job with GET /v1/jobs/{id}/events instead");
  if (url.size() > kMaxUrl) return url_problem("callback_url is longer than 2048 bytes");
  if (std::any_of(url.begin(), url.end(), [](char ch) {
        const auto c = static_cast<unsigned char>(ch);
        return c <= 0x20 || c >= 0x7f;
      }))
    return url_problem("callback_url has a space, a control or a non-ASCII byte");
  CallbackTarget t;
  const std::size_t colon = url.find("://");
  t.scheme = lower(url.substr(0, colon));
  if (colon == std::string::npos || (t.scheme != "http" && t.scheme != "https"))
    return url_problem("callback_url must be an http:// or https:// URL");
  const std::size_t authority_at = colon + 3;
  const std::size_t path_at = url.find_first_of("/?#", authority_at);
  const std::string authority = url.substr(authority_at, path_at - authority_at);
  if (authority.find('@') != std::string::npos)
    return url_problem("callback_url must not carry a user name or password");
  if (!split_host_port(authority, t.host, t.port))
    return url_problem("callback_url has no valid host[:port]");
  if (t.port == 0) t.port = t.scheme == "https" ? 443 : 80;
  t.path = path_at == std::string::npos ? "/" : url.substr(path_at);
  if (t.path.find('#') != std::string::npos)
    return url_problem("callback_url must not have a fragment");
  if (t.path.front() == '?') t.path.insert(0, "/");

  // The allow-list: the host (and the port, when the entry has one).
  const std::string* entry = nullptr;
  for (const std::string& e : policy.allow) {
    std::string host;
    int port = 0;
    // An entry without a port allows the scheme's default port only (80 / 443), not every
    // service on that host.
    const int default_port = t.scheme == "https" ? 443 : 80;
    if (split_host_port(e, host, port) && host == t.host &&
        (port == 0 ? t.port == default_port : port == t.port)) {
      entry = &e;
      break;
    }
  }
  if (!entry)
    return url_problem("callback_url's host " + shortened(t.host) + ":" + std::to_string(t.port) +
                       " is not on this server's --callback-allow list");
  // Resolved now; every address must be public unless the entry names the address itself.
  const bool named_address = ip_literal(t.host);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = named_address ? AI_NUMERICHOST : 0;
  addrinfo* found = nullptr;
  const std::string port_text = std::to_string(t.port);
  if (::getaddrinfo(t.host.c_str(), port_text.c_str(), &hints, &found) != 0 || !found)
    return url_problem("callback_url's host " + shortened(t.host) + " does not resolve");
  std::optional<api::Problem> refused;
  for (addrinfo* a = found; a; a = a->ai_next) {
    if (special_address(a->ai_addr) && !named_address) {
      refused = url_problem("callback_url's host " + shortened(t.host) + " resolves to " +
                            address_text(a->ai_addr) +
                            ", a loopback, link-local or private address; only an allow-list "
                            "entry naming that address permits it");
      break;
    }
    if (t.address.empty()) t.address = address_text(a->ai_addr);
  }
  ::freeaddrinfo(found);
  if (refused) return refused;
  if (out) *out = std::move(t);
  return std::nullopt;
}

namespace {

std::string hmac_hex(std::string_view key, std::string_view message) {
  unsigned char mac[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  if (!HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()),
            reinterpret_cast<const unsigned char*>(message.data()), message.size(), mac, &size))
    throw std::runtime_error("HMAC-SHA256 failed");
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (unsigned int i = 0; i < size; ++i) {
    out.push_back(kHex[mac[i] >> 4]);
    out.push_back(kHex[mac[i] & 15]);
  }
  return out;
}

}  // namespace

std::string tenant_callback_key(const std::string& secret, const std::string& tenant) {
  return hmac_hex(secret, tenant);
}

std::string callback_signature(const std::string& key, std::int64_t timestamp,
                               const std::string& body) {
  std::string message = std::to_string(timestamp);
  message.push_back('.');
  message.append(body);
  std::string out = "sha256=";
  out.append(hmac_hex(key, message));
  return out;
}

CallbackSender::CallbackSender(CallbackPolicy policy) : policy_(std::move(policy)) {
  thread_ = std::thread([this] { run(); });
}

CallbackSender::~CallbackSender() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
  for (const Delivery& d : queue_)
    log_line("stlrefined: callback to " + shortened(d.url) + " dropped at shutdown");
}

void CallbackSender::send(std::string url, std::string body, const std::string& tenant) {
  std::string key = tenant_callback_key(policy_.secret, tenant);
  {
    std::lock_guard lock(mutex_);
    // Bounded: a receiver that never answers must not grow the daemon's memory. Past the
    // bound the newest callback is dropped and logged (the job's state is still served).
    constexpr std::size_t kMaxPending = 10000;
    if (queue_.size() >= kMaxPending) {
      log_line("stlrefined: callback to " + shortened(url) +
               " dropped: " + std::to_string(kMaxPending) + " callbacks already pending");
      return;
    }
    queue_.push_back(
        {std::move(url), std::move(body), std::move(key), 0, std::chrono::steady_clock::now()});
  }
  wake_.notify_all();
}

void CallbackSender::run() {
  std::unique_lock lock(mutex_);
  for (;;) {
    if (stopping_) return;
    if (queue_.empty()) {
      wake_.wait(lock);
      continue;
    }
    // The delivery due first.
    auto next =
        std::min_element(queue_.begin(), queue_.end(),
                         [](const Delivery& a, const Delivery& b) { return a.due < b.due; });
    if (next->due > std::chrono::steady_clock::now()) {
      wake_.wait_until(lock, next->due);
      continue;
    }
    Delivery d = std::move(*next);
    queue_.erase(next);
    lock.unlock();
    const bool delivered = deliver(d);
    lock.lock();
    if (delivered) continue;
    if (++d.attempt >= policy_.attempts) {
      log_line("stlrefined: callback to " + shortened(d.url) + " failed " +
               std::to_string(d.attempt) + " times; given up");
      continue;
    }
    d.due = std::chrono::steady_clock::now() + policy_.backoff * (1 << (d.attempt - 1));
    queue_.push_back(std::move(d));
  }
}

bool CallbackSender::deliver(const Delivery& d) {
  // Checked again now: the allow-list's name may resolve elsewhere than at submit.
  CallbackTarget t;
  if (std::optional<api::Problem> refused = check_callback_url(policy_, d.url, &t)) {
    log_line("stlrefined: callback to " + shortened(d.url) + " refused: " + refused->detail);
    return false;
  }
  const std::string host = t.host.find(':') != std::string::npos ? "[" + t.host + "]" : t.host;
  httplib::Client client(t.scheme + "://" + host + ":" + std::to_string(t.port));
  // The address checked, not a second resolution (https still verifies the host's name).
  client.set_hostname_addr_map({{t.host, t.address}});
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(policy_.timeout);
  client.set_connection_timeout(seconds);
  client.set_read_timeout(seconds);
  client.set_write_timeout(seconds);
  client.set_follow_location(false);
  // Signed as sent: each attempt carries its own time, so a receiver can refuse old ones.
  const std::int64_t now = std::chrono::duration_cast<std::chrono::seconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
  httplib::Headers headers = {{"X-Stlrefine-Timestamp", std::to_string(now)},
                              {"X-Stlrefine-Signature", callback_signature(d.key, now, d.body)},
                              {"User-Agent", "stlrefined"}};
  const httplib::Result r = client.Post(t.path, headers, d.body, "application/json");
  if (r && r->status / 100 == 2) return true;  // any 2xx
  log_line("stlrefined: callback to " + shortened(d.url) + " attempt " +
           std::to_string(d.attempt + 1) + ": " +
           (r ? "status " + std::to_string(r->status) : httplib::to_string(r.error())));
  return false;
}

}  // namespace stlrefine::server
