// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/machine.h"

#include <sched.h>
#include <sys/mman.h>
#include <sys/utsname.h>
#include <tbb/version.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "bench/jobs.h"
#include "bench/measure.h"

#ifndef STLREFINE_BENCH_BUILD_TYPE
#define STLREFINE_BENCH_BUILD_TYPE "unknown"
#endif
#ifndef STLREFINE_BENCH_CXX_FLAGS
#define STLREFINE_BENCH_CXX_FLAGS ""
#endif

namespace stlrefine::bench {
namespace {

//! Value of the first "key : value" line in a /proc file.
std::string proc_field(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.compare(0, key.size(), key) != 0) continue;
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    const auto start = line.find_first_not_of(" \t", colon + 1);
    return start == std::string::npos ? std::string() : line.substr(start);
  }
  return "?";
}

long meminfo_kb(const std::string& key) {
  const std::string value = proc_field("/proc/meminfo", key);
  try {
    return std::stol(value);
  } catch (...) {
    return -1;
  }
}

std::string compiler() {
#if defined(__clang__)
  return std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
  return std::string("GCC ") + __VERSION__;
#else
  return "unknown";
#endif
}

std::string first_line(const char* file) {
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  return in || !line.empty() ? line : "?";
}

//! Microseconds per first touch of a 4 KiB page of fresh anonymous memory (64 MiB, best
//! of 3). On virtual machines this can dominate everything that allocates.
double page_fault_us() {
  constexpr std::size_t kBytes = std::size_t{64} << 20;
  double best = 1e9;
  for (int i = 0; i < 3; ++i) {
    void* p = ::mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) return -1;
    volatile char* bytes = static_cast<volatile char*>(p);
    const double t0 = now_seconds();
    for (std::size_t k = 0; k < kBytes; k += 4096) bytes[k] = 1;
    best = std::min(best, (now_seconds() - t0) * 1e6 / double(kBytes / 4096));
    ::munmap(p, kBytes);
  }
  return best;
}

}  // namespace

std::string load_averages() {
  std::ifstream in("/proc/loadavg");
  double a = -1, b = -1, c = -1;
  in >> a >> b >> c;
  char text[64];
  std::snprintf(text, sizeof(text), "%.2f %.2f %.2f", a, b, c);
  return text;
}

double load_average_1min() {
  std::ifstream in("/proc/loadavg");
  double a = -1;
  in >> a;
  return a;
}

bool cpu_times(double& idle_seconds, double& total_seconds) {
  std::ifstream in("/proc/stat");
  std::string cpu;
  in >> cpu;
  if (cpu != "cpu") return false;
  double idle = 0, total = 0;
  for (int i = 0; i < 8; ++i) {  // user nice system idle iowait irq softirq steal
    double v = 0;
    if (!(in >> v)) return false;
    total += v;
    if (i == 3 || i == 4) idle += v;
  }
  const double hz = double(::sysconf(_SC_CLK_TCK));
  idle_seconds = idle / hz;
  total_seconds = total / hz;
  return true;
}

double cpu_idle_fraction(double seconds) {
  double idle0 = 0, total0 = 0, idle1 = 0, total1 = 0;
  if (!cpu_times(idle0, total0)) return -1;
  ::usleep(useconds_t(seconds * 1e6));
  if (!cpu_times(idle1, total1) || total1 <= total0) return -1;
  return (idle1 - idle0) / (total1 - total0);
}

long mem_available_kb() {
  return meminfo_kb("MemAvailable");
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%d %H:%M:%S UTC", &tm);
  return text;
}

std::string machine_markdown() {
  std::ostringstream out;
  cpu_set_t set;
  CPU_ZERO(&set);
  const int usable = sched_getaffinity(0, sizeof(set), &set) == 0 ? CPU_COUNT(&set) : -1;
  utsname uts{};
  uname(&uts);
  const long total_kb = meminfo_kb("MemTotal");
  const long available_kb = meminfo_kb("MemAvailable");

  out << "- CPU: " << proc_field("/proc/cpuinfo", "model name") << " ("
      << proc_field("/proc/cpuinfo", "cpu MHz") << " MHz, cache "
      << proc_field("/proc/cpuinfo", "cache size") << ")\n";
  out << "- cores: " << std::thread::hardware_concurrency() << " logical, " << usable
      << " usable by this process\n";
  out << "- RAM: " << (total_kb / 1024) << " MiB total, " << (available_kb / 1024)
      << " MiB available at start\n";
  out << "- kernel: " << uts.sysname << ' ' << uts.release << ' ' << uts.machine << '\n';
  out << "- compiler: " << compiler() << "; build " << STLREFINE_BENCH_BUILD_TYPE << " ("
      << STLREFINE_BENCH_CXX_FLAGS << ")\n";
  out << "- libraries: CGAL " << cgal_version() << ", OpenMesh " << openmesh_version()
      << ", oneTBB " << TBB_VERSION_MAJOR << '.' << TBB_VERSION_MINOR << '\n';
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  char fault[32];
  std::snprintf(fault, sizeof(fault), "%.2f", page_fault_us());
  out << "- memory: transparent huge pages `"
      << first_line("/sys/kernel/mm/transparent_hugepage/enabled") << "`, GLIBC_TUNABLES `"
      << (tunables ? tunables : "") << "`; first touch of fresh memory " << fault
      << " µs per 4 KiB page\n";
  out << "- date: " << utc_now() << '\n';
  out << "- load average at start: " << load_averages() << '\n';
  return out.str();
}

}  // namespace stlrefine::bench
