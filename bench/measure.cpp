// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/measure.h"

#include <malloc.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <iostream>
#include <string>

#include "bench/machine.h"

namespace stlrefine::bench {
namespace {

double cpu_seconds_now() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const auto to_s = [](const timeval& t) { return double(t.tv_sec) + 1e-6 * double(t.tv_usec); };
  return to_s(usage.ru_utime) + to_s(usage.ru_stime);
}

long ru_maxrss_kb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

//! Linux >= 4.0: writing 5 to clear_refs resets the peak RSS (VmHWM, and with it
//! ru_maxrss) to the current RSS. Returns false where that is not supported.
bool reset_peak_rss() {
  {
    std::ofstream clear("/proc/self/clear_refs");
    if (!clear) return false;
    clear << "5";
    clear.flush();
    if (!clear) return false;
  }
  const long hwm = proc_status_kb("VmHWM:");
  const long rss = proc_status_kb("VmRSS:");
  return hwm >= 0 && rss >= 0 && hwm <= rss + 1024;
}

void prefault(std::size_t bytes) {
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) return;
  ::madvise(p, bytes, MADV_HUGEPAGE);
  volatile char* memory = static_cast<volatile char*>(p);
  for (std::size_t i = 0; i < bytes; i += 4096) memory[i] = 1;
  ::munmap(p, bytes);
}

//! What the child writes to the pipe.
struct Message {
  int status = 0;  // 0 = ok, 1 = exception
  Sample sample;
  char error[512] = {};
};

bool write_all(int fd, const void* data, std::size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= std::size_t(n);
  }
  return true;
}

}  // namespace

double now_seconds() {
  using clock = std::chrono::steady_clock;
  return std::chrono::duration<double>(clock::now().time_since_epoch()).count();
}

long proc_status_kb(const char* key) {
  std::ifstream status("/proc/self/status");
  std::string line;
  const std::size_t key_length = std::strlen(key);
  while (std::getline(status, line)) {
    if (line.compare(0, key_length, key) == 0) return std::stol(line.substr(key_length));
  }
  return -1;
}

double median(std::vector<double> values) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

void copy_note(Sample& sample, const std::string& text) {
  const std::size_t n = std::min(text.size(), sizeof(sample.note) - 1);
  std::memcpy(sample.note, text.data(), n);
  sample.note[n] = '\0';
}

Sample measure_job(const JobFactory& make, const JobFactory& warm_up, std::size_t prefault_bytes,
                   double min_seconds, int max_runs) {
  Sample sample;
  if (warm_up) warm_up()->run();
  {
    std::unique_ptr<Job> job = make();
    sample.convert_seconds = job->convert_seconds();
    if (prefault_bytes > 0) prefault(prefault_bytes);
    malloc_trim(0);  // give back what loading freed, so the baseline is the live input
    sample.base_kb = proc_status_kb("VmRSS:");
    sample.peak_reset = reset_peak_rss();

    const double cpu0 = cpu_seconds_now();
    const double t0 = now_seconds();
    job->run();
    const double t1 = now_seconds();
    sample.cpu_seconds = cpu_seconds_now() - cpu0;
    sample.seconds = t1 - t0;

    sample.maxrss_kb = ru_maxrss_kb();
    sample.peak_kb = sample.peak_reset ? proc_status_kb("VmHWM:") : sample.maxrss_kb;
    sample.in_faces = job->in_faces();
    sample.out_faces = job->out_faces();
    sample.out_vertices = job->out_vertices();
    copy_note(sample, job->note());
  }
  std::vector<double> warm;
  double total = 0;
  while (sample.seconds < min_seconds && total < min_seconds && int(warm.size()) + 1 < max_runs) {
    std::unique_ptr<Job> job = make();
    const double t0 = now_seconds();
    job->run();
    const double t = now_seconds() - t0;
    warm.push_back(t);
    total += t;
  }
  sample.warm_runs = int(warm.size());
  sample.warm_seconds = median(warm);
  return sample;
}

Outcome run_in_child(const std::function<Sample()>& body, int timeout_seconds) {
  Outcome outcome;
  std::cout.flush();
  std::cerr.flush();
  std::fflush(nullptr);

  double idle0 = 0, total0 = 0;
  const bool have_times = cpu_times(idle0, total0);
  int fds[2];
  if (::pipe(fds) != 0) {
    outcome.failure = std::string("pipe: ") + std::strerror(errno);
    return outcome;
  }
  const pid_t pid = ::fork();
  if (pid < 0) {
    outcome.failure = std::string("fork: ") + std::strerror(errno);
    ::close(fds[0]);
    ::close(fds[1]);
    return outcome;
  }
  if (pid == 0) {
    ::close(fds[0]);
    if (timeout_seconds > 0) ::alarm(unsigned(timeout_seconds));
    static Message message;  // static: keeps a large struct off the child's stack
    try {
      message.sample = body();
      message.status = 0;
    } catch (const std::exception& e) {
      message.status = 1;
      std::snprintf(message.error, sizeof(message.error), "exception: %s", e.what());
    } catch (...) {
      message.status = 1;
      std::snprintf(message.error, sizeof(message.error), "unknown exception");
    }
    write_all(fds[1], &message, sizeof(message));
    ::close(fds[1]);
    std::fflush(nullptr);
    ::_exit(0);  // no atexit handlers or static destructors in the child
  }

  ::close(fds[1]);
  Message message;
  std::size_t got = 0;
  char* dst = reinterpret_cast<char*>(&message);
  while (got < sizeof(message)) {
    const ssize_t n = ::read(fds[0], dst + got, sizeof(message) - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += std::size_t(n);
  }
  ::close(fds[0]);
  int status = 0;
  rusage child{};
  while (::wait4(pid, &status, 0, &child) < 0 && errno == EINTR) {
  }
  double idle1 = 0, total1 = 0;
  // Only over half a CPU-second or more: /proc/stat counts in 10 ms ticks.
  if (have_times && cpu_times(idle1, total1) && total1 - total0 >= 0.5) {
    const auto to_s = [](const timeval& t) { return double(t.tv_sec) + 1e-6 * double(t.tv_usec); };
    const double child_cpu = to_s(child.ru_utime) + to_s(child.ru_stime);
    const double busy = (total1 - total0) - (idle1 - idle0);
    outcome.others_busy = std::max(0.0, (busy - child_cpu) / (total1 - total0));
  }

  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    if (sig == SIGALRM) {
      outcome.failure = "timeout (" + std::to_string(timeout_seconds) + " s)";
    } else if (sig == SIGKILL) {
      outcome.failure = "killed (SIGKILL; out of memory?)";
    } else {
      outcome.failure = "crashed (signal " + std::to_string(sig) + ", " + strsignal(sig) + ")";
    }
    return outcome;
  }
  if (got != sizeof(message)) {
    outcome.failure = "child exited without a report (status " +
                      std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")";
    return outcome;
  }
  if (message.status != 0) {
    outcome.failure = message.error;
    return outcome;
  }
  outcome.ok = true;
  outcome.sample = message.sample;
  return outcome;
}

}  // namespace stlrefine::bench
