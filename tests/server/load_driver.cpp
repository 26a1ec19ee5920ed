// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "load_driver.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <thread>

namespace stlrefine::test {

namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

struct Exchange {
  bool complete = false;  // one whole response was read
  std::string error;      // why not
  RawResponse response;
};

bool send_all(int fd, std::string_view bytes, std::string& error) {
  while (!bytes.empty()) {
    const ssize_t n = ::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = std::string("send: ") + std::strerror(errno);
      return false;
    }
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
  return true;
}

// One request on a fresh connection; the daemon closes after its answer. With a body the
// head asks `Expect: 100-continue` first, as curl does for large uploads: a refusal then
// costs no upload.
Exchange exchange_once(int port, const std::string& head, const std::string& body,
                       std::chrono::seconds timeout) {
  Exchange out;
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) {
    out.error = std::string("socket: ") + std::strerror(errno);
    return out;
  }
  timeval tv{static_cast<time_t>(timeout.count()), 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    out.error = std::string("connect: ") + std::strerror(errno);
    ::close(fd);
    return out;
  }
  std::string raw, send_error, recv_error;
  char chunk[1 << 16];
  // Reads until `marker` is in raw (empty: until the close).
  auto read_until = [&](std::string_view marker) {
    while (marker.empty() || raw.find(marker) == std::string::npos) {
      const ssize_t n = ::recv(fd, chunk, sizeof chunk, 0);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        recv_error = std::string("recv: ") + std::strerror(errno);
        return false;
      }
      if (n == 0) return marker.empty();
      raw.append(chunk, static_cast<std::size_t>(n));
    }
    return true;
  };
  bool send_body = send_all(fd, head, send_error) && !body.empty();
  if (send_body) {
    // 100 Continue, or already the final answer (a refusal).
    read_until("\r\n\r\n");
    if (raw.rfind("HTTP/1.1 100 ", 0) == 0) {
      raw.erase(0, raw.find("\r\n\r\n") + 4);
      send_all(fd, body, send_error);
    }
  }
  if (recv_error.empty()) read_until({});
  ::close(fd);
  const std::vector<RawResponse> responses = parse_responses(raw);
  if (responses.size() == 1 && responses[0].has_header("content-length") &&
      responses[0].body.size() == std::stoull(responses[0].header("content-length"))) {
    out.complete = true;
    out.response = responses[0];
    return out;
  }
  out.error = !recv_error.empty() ? recv_error
              : !send_error.empty()
                  ? send_error
                  : "incomplete answer (" + std::to_string(raw.size()) + " bytes, " +
                        std::to_string(responses.size()) + " responses)";
  return out;
}

std::string post_head(const LoadRequest& r) {
  return "POST " + r.target +
         " HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: model/stl\r\nExpect: 100-continue\r\n"
         "Content-Length: " +
         std::to_string(r.body.size()) + "\r\n\r\n";
}

}  // namespace

long long proc_status_bytes(pid_t pid, const std::string& key) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key + ":", 0) == 0) return std::stoll(line.substr(key.size() + 1)) * 1024;
  return -1;
}

std::size_t proc_open_fds(pid_t pid) {
  std::size_t n = 0;
  std::error_code ec;
  for (std::filesystem::directory_iterator it("/proc/" + std::to_string(pid) + "/fd", ec), end;
       !ec && it != end; it.increment(ec))
    ++n;
  return n;
}

double percentile(std::vector<double> samples, double p) {
  if (samples.empty()) return 0;
  std::sort(samples.begin(), samples.end());
  const double rank = std::ceil(p / 100.0 * double(samples.size()));
  const std::size_t i = rank < 1 ? 0 : std::min(samples.size() - 1, std::size_t(rank) - 1);
  return samples[i];
}

LoadReport run_load(const LoadOptions& options,
                    const std::function<void(const LoadReport&)>& progress) {
  LoadReport report;
  std::mutex mutex;
  const auto start = Clock::now();
  const auto end = start + options.duration;
  std::atomic<bool> done{false};
  const double cpu_before = proc_cpu_seconds(options.pid);

  std::vector<std::string> heads;
  for (const LoadRequest& r : options.requests) heads.push_back(post_head(r));

  auto client = [&](int k) {
    if (options.client_nice > 0) {
      const id_t tid = static_cast<id_t>(::syscall(SYS_gettid));
      ::setpriority(PRIO_PROCESS, tid, ::getpriority(PRIO_PROCESS, tid) + options.client_nice);
    }
    std::mt19937 random(static_cast<unsigned>(k) * 7919u + 1u);
    std::uniform_real_distribution<double> jitter(0.5, 1.5);
    for (std::size_t n = 0; Clock::now() < end; ++n) {
      const std::size_t which = (std::size_t(k) + n) % heads.size();
      const auto t0 = Clock::now();
      const Exchange e = exchange_once(options.port, heads[which], options.requests[which].body,
                                       options.request_timeout);
      const double ms = ms_since(t0);
      std::chrono::milliseconds wait{0};
      {
        std::lock_guard lock(mutex);
        ++report.requests;
        if (!e.complete) {
          ++report.socket_errors;
          if (report.error_examples.size() < 10)
            report.error_examples.push_back(options.requests[which].target + ": " + e.error);
        } else {
          const RawResponse& r = e.response;
          ++report.by_status[r.status];
          if (r.status == 200) {
            const auto& check = options.requests[which].check;
            if (!check || check(r)) {
              ++report.ok;
              report.ok_ms.push_back(ms);
            } else {
              ++report.bad_body;
            }
          } else if (r.status == 503) {
            wait = options.backoff;
            if (r.has_header("retry-after"))
              wait = std::chrono::seconds(std::stoi(r.header("retry-after")));
            wait = std::chrono::milliseconds(
                static_cast<long long>(double(wait.count()) * jitter(random)));
            ++report.busy;
            report.busy_ms.push_back(ms);
            if (!r.has_header("retry-after")) ++report.busy_without_retry_after;
            std::string kind = "unparsable";
            try {
              const nlohmann::json j = nlohmann::json::parse(r.body);
              kind = j.value("type", "?");
              if (j.contains("reason")) kind += " (" + j.value("reason", "") + ")";
            } catch (const std::exception&) {
            }
            ++report.busy_kinds[kind];
          }
        }
      }
      if (wait.count() > 0) std::this_thread::sleep_until(std::min(Clock::now() + wait, end));
    }
  };

  std::thread prober([&] {
    const std::string get = "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
    auto next = Clock::now();
    while (!done) {
      const auto t0 = Clock::now();
      const Exchange e = exchange_once(options.port, get, {}, std::chrono::seconds(10));
      const double ms = ms_since(t0);
      {
        std::lock_guard lock(mutex);
        if (e.complete && e.response.status == 200)
          report.healthz_ms.push_back(ms);
        else
          ++report.healthz_failures;
      }
      next += options.probe_period;
      std::this_thread::sleep_until(next);
    }
  });

  std::thread sampler([&] {
    auto next = Clock::now();
    auto next_report = Clock::now() + options.report_period;
    while (!done) {
      LoadSample s;
      s.seconds = std::chrono::duration<double>(Clock::now() - start).count();
      s.rss_bytes = proc_status_bytes(options.pid, "VmRSS");
      s.fds = proc_open_fds(options.pid);
      std::unique_lock lock(mutex);
      report.samples.push_back(s);
      report.max_rss_bytes = std::max(report.max_rss_bytes, s.rss_bytes);
      if (progress && options.report_period.count() > 0 && Clock::now() >= next_report) {
        report.seconds = s.seconds;
        const LoadReport snapshot = report;
        lock.unlock();
        progress(snapshot);
        next_report += options.report_period;
      } else {
        lock.unlock();
      }
      next += options.sample_period;
      std::this_thread::sleep_until(next);
    }
  });

  std::vector<std::thread> clients;
  for (int k = 0; k < options.clients; ++k) clients.emplace_back(client, k);
  for (std::thread& t : clients) t.join();
  if (options.clients == 0) std::this_thread::sleep_until(end);  // probes alone
  done = true;
  prober.join();
  sampler.join();
  report.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  report.daemon_cpu_seconds = proc_cpu_seconds(options.pid) - cpu_before;
  // The peak as the kernel saw it, not only at the sampling instants.
  report.max_rss_bytes = std::max(report.max_rss_bytes, proc_status_bytes(options.pid, "VmHWM"));
  return report;
}

}  // namespace stlrefine::test
