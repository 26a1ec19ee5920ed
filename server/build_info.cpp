// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/build_info.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "core/schemes/registry.h"

#ifndef STLREFINE_VERSION
#error "STLREFINE_VERSION is set by server/CMakeLists.txt"
#endif
#ifndef STLREFINE_BUILD_TYPE
#define STLREFINE_BUILD_TYPE "unknown"
#endif

namespace stlrefine::server {

namespace {

std::string compiler_name() {
#if defined(__clang__)
  return "clang " __clang_version__;
#elif defined(__GNUC__)
  return "gcc " __VERSION__;
#else
  return "unknown";
#endif
}

// The fields of /proc/self/stat after the command name (which may hold spaces and
// parentheses: everything up to the last ')' is skipped). Field 3 (state) is index 0.
std::vector<std::string> stat_fields() {
  std::ifstream in("/proc/self/stat");
  std::string line;
  std::getline(in, line);
  const std::size_t close = line.rfind(')');
  std::vector<std::string> fields;
  if (close == std::string::npos) return fields;
  std::istringstream rest(line.substr(close + 1));
  for (std::string f; rest >> f;) fields.push_back(f);
  return fields;
}

double boot_time_seconds() {
  std::ifstream in("/proc/stat");
  for (std::string key; in >> key;) {
    if (key == "btime") {
      double t = 0;
      in >> t;
      return t;
    }
    in.ignore(1 << 20, '\n');
  }
  return 0;
}

std::size_t open_fds() {
  std::error_code ec;
  std::size_t n = 0;
  for (std::filesystem::directory_iterator it("/proc/self/fd", ec), end; !ec && it != end;
       it.increment(ec))
    ++n;
  return n > 0 ? n - 1 : 0;  // the iterator's own descriptor
}

std::string label(const std::string& v) {
  std::string out;
  for (char c : v) {
    if (c == '\\' || c == '"') out.push_back('\\');
    if (c == '\n') {
      out.append("\\n");
      continue;
    }
    out.push_back(c);
  }
  return out;
}

void gauge(std::ostringstream& out, const char* name, const char* type, const char* help,
           double value) {
  char number[40];
  std::snprintf(number, sizeof number, "%.17g", value);
  out << "# HELP " << name << ' ' << help << "\n# TYPE " << name << ' ' << type << '\n'
      << name << ' ' << number << '\n';
}

}  // namespace

const BuildInfo& build_info() {
  static const BuildInfo info{STLREFINE_VERSION, "v1", compiler_name(), STLREFINE_BUILD_TYPE};
  return info;
}

std::string version_document() {
  const BuildInfo& b = build_info();
  nlohmann::json doc{
      {"name", "stlrefine"},    {"version", b.version},       {"api", b.api},
      {"compiler", b.compiler}, {"build_type", b.build_type}, {"schemes", scheme_names()}};
  return doc.dump(2) + "\n";
}

std::string process_metrics() {
  std::ostringstream out;
  const BuildInfo& b = build_info();
  // No compiler here: /metrics needs no key, and the compiler only helps fingerprinting
  // (GET /v1/version, behind the key, has it).
  out << "# HELP stlrefine_build_info The build: version and API version (always 1).\n"
         "# TYPE stlrefine_build_info gauge\nstlrefine_build_info{version=\""
      << label(b.version) << "\",api=\"" << label(b.api) << "\"} 1\n";

  // /proc/self/stat (proc(5)): utime 14, stime 15, starttime 22, vsize 23, rss 24, counted
  // from 1 with the pid; stat_fields() starts at field 3.
  const std::vector<std::string> f = stat_fields();
  if (f.size() > 21) {
    const double ticks = static_cast<double>(::sysconf(_SC_CLK_TCK));
    const double page = static_cast<double>(::sysconf(_SC_PAGESIZE));
    const double cpu = (std::stod(f[11]) + std::stod(f[12])) / ticks;
    gauge(out, "process_cpu_seconds_total", "counter",
          "Total user and system CPU time spent in seconds.", cpu);
    gauge(out, "process_start_time_seconds", "gauge",
          "Start time of the process since unix epoch in seconds.",
          boot_time_seconds() + std::stod(f[19]) / ticks);
    gauge(out, "process_virtual_memory_bytes", "gauge", "Virtual memory size in bytes.",
          std::stod(f[20]));
    gauge(out, "process_resident_memory_bytes", "gauge", "Resident memory size in bytes.",
          std::stod(f[21]) * page);
  }
  gauge(out, "process_open_fds", "gauge", "Number of open file descriptors.",
        static_cast<double>(open_fds()));
  rlimit limit{};
  if (::getrlimit(RLIMIT_NOFILE, &limit) == 0)
    gauge(out, "process_max_fds", "gauge", "Maximum number of open file descriptors.",
          static_cast<double>(limit.rlim_cur));
  return out.str();
}

}  // namespace stlrefine::server
