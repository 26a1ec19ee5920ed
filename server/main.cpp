// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// stlrefined: the refinement daemon. See server/README.md for the HTTP interface.
//
// Exit codes: 0 after a clean shutdown (SIGINT / SIGTERM), 2 for bad flags, 1 when the
// address cannot be bound or anything else fails.

#include <malloc.h>
#include <pthread.h>
#include <signal.h>
#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "server/daemon.h"
#include "server/job_callbacks.h"
#include "server/memory_budget.h"

namespace {

// SIGINT / SIGTERM are blocked in every thread (the mask is inherited, so this runs before
// any thread exists) and taken by one thread with sigtimedwait: the first stops accepting
// and lets requests in flight finish, a second one also cancels running refinements.
sigset_t shutdown_signals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  return set;
}

void watch_signals(stlrefine::server::Daemon& daemon, const std::atomic<bool>& done) {
  const sigset_t set = shutdown_signals();
  const timespec poll{0, 200'000'000};
  int received = 0;
  while (!done) {
    if (sigtimedwait(&set, nullptr, &poll) < 0) continue;  // EAGAIN (timeout) or EINTR
    if (++received == 1) {
      std::cerr << "stlrefined: shutting down (finishing requests in flight)\n";
      daemon.stop();
    } else {
      std::cerr << "stlrefined: cancelling running refinements\n";
      daemon.cancel_running();
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  const sigset_t signals = shutdown_signals();
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  // Large blocks (every mesh array) straight from mmap and back to the kernel when freed.
  // glibc's default raises this threshold to 32 MiB after the first large free, and then
  // each thread's arena keeps what the refinements freed: under load the daemon held
  // 0.9-1.4 GiB with a 256 MiB budget (tests/server/load_test.cpp); with it, 160 MiB.
  ::mallopt(M_MMAP_THRESHOLD, 1 << 20);
  // A client that hangs up mid-response must cost an EPIPE, not the process.
  std::signal(SIGPIPE, SIG_IGN);
  // Every connection is a descriptor: take the hard limit, not the (often 1024) soft one.
  if (rlimit files{}; ::getrlimit(RLIMIT_NOFILE, &files) == 0 && files.rlim_cur < files.rlim_max) {
    files.rlim_cur = files.rlim_max;
    ::setrlimit(RLIMIT_NOFILE, &files);
  }

  CLI::App app{"stlrefined: HTTP daemon that refines STL files with interpolatory subdivision"};
  app.set_version_flag("--version", std::string(STLREFINE_VERSION));
  std::string host = "127.0.0.1";
  int port = 8080;
  std::size_t threads = 0;
  std::size_t compute_slots = 0;
  std::size_t max_body_mib = 256;
  std::uint64_t max_faces = 20'000'000;
  std::uint64_t max_slice_points = 20'000'000;
  int read_timeout = 10;
  int write_timeout = 10;
  std::size_t max_connections_per_client = 256;
  std::uint64_t min_transfer_rate_kib = 64;
  bool access_log = false;
  std::string data_dir = "stlrefine-data";
  std::size_t job_queue = 16;
  double retention_hours = 24;
  std::uint64_t disk_budget_mib = 10240;
  int shutdown_grace = 30;
  std::string api_key_file;
  std::vector<std::string> cors_origins;
  std::size_t max_connections = 1024;
  std::string memory_budget;
  double request_deadline = 900;
  int compute_nice = 10;
  bool test_faults = false;
  app.set_config("--config", "", "Read options from this TOML/INI file (key = value)");
  app.add_option("--host", host, "Address to listen on")->capture_default_str();
  app.add_option("--port", port, "Port to listen on; 0 picks a free one")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  app.add_option("--threads", threads, "HTTP worker threads (0 = compute slots + 4)")
      ->check(CLI::Range(0, 4096))
      ->capture_default_str();
  app.add_option("--compute-slots", compute_slots,
                 "Requests computing at once; more get 503 (0 = hardware threads)")
      ->check(CLI::Range(0, 4096))
      ->capture_default_str();
  app.add_option("--max-body-mib", max_body_mib, "Largest request body in MiB (413 above)")
      ->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  app.add_option("--max-faces", max_faces, "Face cap of one refinement (422 above)")
      ->check(CLI::Range(std::uint64_t{1}, (std::uint64_t{1} << 31) - 1))
      ->capture_default_str();
  app.add_option("--max-slice-points", max_slice_points,
                 "Contour points one slice answer may hold (422 above)")
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1} << 40))
      ->capture_default_str();
  app.add_option("--read-timeout", read_timeout,
                 "Seconds a request head may take; a body must also arrive at "
                 "--min-transfer-rate over every window this long")
      ->check(CLI::Range(1, 3600))
      ->capture_default_str();
  app.add_option("--write-timeout", write_timeout,
                 "An answer must be read at --min-transfer-rate over every window this long "
                 "(seconds), or the connection is dropped")
      ->check(CLI::Range(1, 3600))
      ->capture_default_str();
  app.add_flag("--access-log", access_log, "Log one JSON line per request on stderr");
  app.add_option("--data-dir", data_dir,
                 "Directory for job inputs and results (jobs survive restarts); empty disables "
                 "jobs")
      ->capture_default_str();
  app.add_option("--job-queue", job_queue, "Jobs waiting for a slot; more get 503")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--job-retention-hours", retention_hours,
                 "Hours a finished job's results are kept (then 410)")
      ->check(CLI::Range(0.001, 24.0 * 365))
      ->capture_default_str();
  app.add_option("--job-disk-mib", disk_budget_mib,
                 "Result bytes kept at most (MiB); the oldest finished jobs expire first")
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1} << 30))
      ->capture_default_str();
  app.add_option("--shutdown-grace", shutdown_grace,
                 "Seconds requests and jobs in flight may finish (answers be written) after "
                 "SIGTERM before they are cancelled")
      ->check(CLI::Range(0, 3600))
      ->capture_default_str();
  app.add_option(
      "--api-key-file", api_key_file,
      "File with one API key per line (>= 16 characters); then every route but "
      "/healthz, /readyz and /metrics needs Authorization: Bearer <key> or X-Api-Key: <key>");
  app.add_option("--cors-origin", cors_origins,
                 "An origin (scheme://host[:port], or *) whose browser pages may call the API "
                 "(CORS); repeat for several. None: no CORS headers, preflights answer 403");
  app.add_option("--max-connections", max_connections,
                 "Connections open at once; more are only answered if they are /healthz or "
                 "/readyz, else 503")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 20))
      ->capture_default_str();
  app.add_option("--max-connections-per-client", max_connections_per_client,
                 "Connections one client address may hold (as --max-connections); 0 = no "
                 "cap. Behind a reverse proxy every client has the proxy's address: raise it")
      ->check(CLI::Range(std::size_t{0}, std::size_t{1} << 20))
      ->capture_default_str();
  app.add_option("--min-transfer-rate", min_transfer_rate_kib,
                 "KiB/s a body must arrive at, and an answer be read at, over every "
                 "--read-timeout / --write-timeout window")
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1} << 20))
      ->capture_default_str();
  app.add_option("--memory-budget", memory_budget,
                 "Memory the daemon may use in all: bytes, or with a suffix K, M, G, T (binary: "
                 "512M, 8G); a request predicted above its share gets 422, one that does not "
                 "fit next to the running ones 503 (default: half the RAM or cgroup limit)")
      ->check([](const std::string& text) {
        try {
          const std::uint64_t bytes = stlrefine::server::parse_byte_size(text);
          if (bytes < 2 * stlrefine::server::kDaemonReserve)
            return std::string("the memory budget must be at least 128M");
          return std::string();
        } catch (const std::invalid_argument& e) {
          return std::string(e.what());
        }
      });
  app.add_option("--request-deadline", request_deadline,
                 "Seconds a computation (refine, slice, info, job) may run before it is "
                 "cancelled (504; a job fails); 0 = no deadline")
      ->check(CLI::Range(0.0, 7.0 * 24 * 3600))
      ->capture_default_str();
  app.add_option("--compute-nice", compute_nice,
                 "Nice increment of the threads that compute; the event loop keeps the "
                 "process's priority so probes and refusals are answered at once (0 = off)")
      ->check(CLI::Range(0, 19))
      ->capture_default_str();
  std::string callback_secret;
  std::vector<std::string> callback_allow;
  app.add_option("--callback-secret", callback_secret,
                 "Key of the HMAC-SHA256 signature (X-Stlrefine-Signature) of job callbacks; "
                 "also from STLREFINE_CALLBACK_SECRET (better: not seen in ps)");
  app.add_option("--callback-allow", callback_allow,
                 "HOST[:PORT] a job's callback_url may call (repeatable); loopback, "
                 "link-local and private addresses only when named here as an address")
      ->delimiter(',');
  // Queue mode (issue 20): several replicas, one Redis.
  std::string queue, role = "all", instance;
  int lease_seconds = 30, max_attempts = 3;
  app.add_option("--queue", queue,
                 "Queue mode: redis://[[USER]:PASSWORD@]HOST[:PORT][/DB] or unix:///PATH[?db=N]; "
                 "jobs of every "
                 "replica in one Redis, files in the shared --data-dir (also STLREFINE_QUEUE)");
  app.add_option("--role", role,
                 "Queue mode: api (queues and answers, runs no jobs), worker or all (run them)")
      ->check(CLI::IsMember({"api", "worker", "all"}))
      ->capture_default_str();
  app.add_option("--lease-seconds", lease_seconds,
                 "Queue mode: a running job silent this long is run again by another replica")
      ->check(CLI::Range(1, 3600))
      ->capture_default_str();
  app.add_option("--max-attempts", max_attempts,
                 "Queue mode: runs of a job whose runner stopped before it finished")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--instance", instance,
                 "This replica's name (a job's worker; default: host name, with :pid in queue "
                 "mode)");
  std::size_t max_event_streams = 256, max_event_streams_per_tenant = 32;
  app.add_option("--max-event-streams", max_event_streams,
                 "Job event streams (GET /v1/jobs/{id}/events) open at once; one more gets 429 "
                 "+ Retry-After")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 20))
      ->capture_default_str();
  app.add_option("--max-event-streams-per-tenant", max_event_streams_per_tenant,
                 "Job event streams one API key (without keys: one client address) may hold "
                 "open; one more gets 429 + Retry-After")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 20))
      ->capture_default_str();
  // Tests only: lets a request header make its handler throw or fail an allocation.
  app.add_flag("--test-faults", test_faults, "")->group("");
  // Every option can also come from the environment: STLREFINED_PORT=9000, ...
  for (CLI::Option* option : app.get_options()) {
    std::string name = option->get_single_name();
    if (name.empty() || name == "help" || name == "version" || name == "config") continue;
    std::string env = "STLREFINED_";
    for (char c : name) env += c == '-' ? '_' : static_cast<char>(std::toupper(c));
    option->envname(env);
  }
  // Operator's command, not a setting (so no environment variable): print a tenant's
  // callback key (server/job_callbacks.h) and exit.
  std::string print_callback_key;
  CLI::Option* print_key = app.add_option(
      "--print-callback-key", print_callback_key,
      "Print the callback key of the tenant of API KEY ('-': read the key from stdin; '' for "
      "a daemon without API keys), from --callback-secret and --data-dir, and exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;  // --help and --version are "errors" with code 0
  }

  try {
    stlrefine::server::DaemonConfig config;
    config.http_threads = threads;
    config.compute_slots = compute_slots;
    config.max_body_bytes = max_body_mib << 20;
    config.max_faces = max_faces;
    config.max_slice_points = max_slice_points;
    config.read_timeout = std::chrono::seconds(read_timeout);
    config.write_timeout = std::chrono::seconds(write_timeout);
    config.access_log = access_log;
    config.jobs.data_dir = data_dir;
    config.jobs.max_queued = job_queue;
    config.jobs.retention = std::chrono::seconds(static_cast<long long>(retention_hours * 3600));
    config.jobs.disk_budget_bytes = disk_budget_mib << 20;
    config.shutdown_grace = std::chrono::seconds(shutdown_grace);
    config.max_connections = max_connections;
    config.max_connections_per_client = max_connections_per_client;
    config.min_transfer_rate = min_transfer_rate_kib << 10;
    config.compute_nice = compute_nice;
    config.memory_budget =
        memory_budget.empty() ? 0 : stlrefine::server::parse_byte_size(memory_budget);
    config.request_deadline =
        std::chrono::milliseconds(static_cast<long long>(std::llround(request_deadline * 1000)));
    config.test_faults = test_faults;
    if (callback_secret.empty())
      if (const char* env = std::getenv("STLREFINE_CALLBACK_SECRET")) callback_secret = env;
    config.jobs.callbacks.secret = callback_secret;
    config.jobs.callbacks.allow = callback_allow;
    if (queue.empty())
      if (const char* env = std::getenv("STLREFINE_QUEUE")) queue = env;
    config.jobs.queue = queue;
    config.jobs.run_jobs = role != "api";
    config.jobs.lease = std::chrono::seconds(lease_seconds);
    config.jobs.max_attempts = max_attempts;
    config.jobs.instance = instance;
    config.jobs.max_event_streams = max_event_streams;
    config.jobs.max_event_streams_per_tenant = max_event_streams_per_tenant;
    if (print_key->count() > 0) {
      if (print_callback_key == "-") {
        std::getline(std::cin, print_callback_key);
        while (!print_callback_key.empty() &&
               (print_callback_key.back() == '\r' || print_callback_key.back() == ' '))
          print_callback_key.pop_back();
      }
      std::cout << stlrefine::server::callback_key_of_api_key(data_dir, callback_secret,
                                                              print_callback_key)
                << std::endl;
      return 0;
    }
    if (!api_key_file.empty()) {
      std::ifstream keys(api_key_file);
      if (!keys) throw std::runtime_error("cannot read --api-key-file " + api_key_file);
      for (std::string line; std::getline(keys, line);) {
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
        if (!line.empty() && line.front() != '#') config.api_keys.push_back(line);
      }
      if (config.api_keys.empty()) throw std::runtime_error("--api-key-file has no keys");
    }
    config.cors_origins = cors_origins;
    stlrefine::server::Daemon daemon(config);
    const int bound = daemon.bind(host, port);
    // The one line on stdout: scripts and tests read the port from it.
    std::cout << "listening on " << stlrefine::server::listen_url(host, bound) << std::endl;

    std::atomic<bool> done{false};
    std::thread watcher(watch_signals, std::ref(daemon), std::cref(done));
    daemon.run();
    done = true;
    watcher.join();
    std::cerr << "stlrefined: stopped" << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "stlrefined: " << e.what() << std::endl;
    return 1;
  }
}
