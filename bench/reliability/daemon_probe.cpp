// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "daemon_probe.h"

#include <signal.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>

namespace stlrefine::bench {

using namespace std::chrono_literals;

DaemonProbe::DaemonProbe(const std::string& binary, const std::vector<std::string>& args) {
  std::vector<std::string> argv{binary, "--port", "0"};
  argv.insert(argv.end(), args.begin(), args.end());
  child_ = std::make_unique<test::Child>(argv);
  const std::string line = child_->read_line(20s);
  std::smatch m;
  if (!std::regex_match(line, m, std::regex(R"(^listening on http://127\.0\.0\.1:([0-9]+)$)")))
    throw std::runtime_error("stlrefined did not start: " + line + "\n" + child_->stderr_text());
  port_ = std::stoi(m[1]);
}

DaemonProbe::~DaemonProbe() {
  child_->signal(SIGTERM);
  child_->wait(30s);
}

pid_t DaemonProbe::pid() const {
  return child_->pid();
}

long long DaemonProbe::status_bytes(const std::string& key) const {
  std::ifstream in("/proc/" + std::to_string(pid()) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key + ":", 0) == 0) return std::stoll(line.substr(key.size() + 1)) * 1024;
  return -1;
}

void DaemonProbe::reset_peak() const {
  std::ofstream("/proc/" + std::to_string(pid()) + "/clear_refs") << "5";
}

std::size_t DaemonProbe::open_fds() const {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& entry :
       std::filesystem::directory_iterator("/proc/" + std::to_string(pid()) + "/fd"))
    ++n;
  return n;
}

std::string DaemonProbe::stderr_text() const {
  return child_->stderr_text();
}

std::string read_input(const std::string& path) {
  if (path.size() > 3 && path.ends_with(".gz")) {
    std::FILE* pipe = ::popen(("gzip -dc '" + path + "'").c_str(), "r");
    if (!pipe) return {};
    std::string out;
    char buffer[1 << 16];
    for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;)
      out.append(buffer, n);
    ::pclose(pipe);
    return out;
  }
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace stlrefine::bench
