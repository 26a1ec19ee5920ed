// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "server/memory_budget.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <string>

namespace stlrefine::server {

std::uint64_t parse_byte_size(std::string_view text) {
  std::string quoted = "'";
  quoted.append(text.substr(0, 40));
  quoted.push_back('\'');
  std::string_view t = text;
  while (!t.empty() && t.front() == ' ') t.remove_prefix(1);
  while (!t.empty() && t.back() == ' ') t.remove_suffix(1);
  double number = 0;
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), number);
  if (ec != std::errc() || end == t.data() || !std::isfinite(number) || number < 0)
    throw std::invalid_argument("not a byte size: " + quoted + " (examples: 512M, 2G, 1073741824)");
  std::string_view suffix(end, static_cast<std::size_t>(t.data() + t.size() - end));
  while (!suffix.empty() && suffix.front() == ' ') suffix.remove_prefix(1);
  const auto lower = [](char c) {
    return static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  };
  if (!suffix.empty() && lower(suffix.back()) == 'b') suffix.remove_suffix(1);
  if (suffix.size() == 2 && lower(suffix.back()) == 'i') suffix.remove_suffix(1);
  double scale = 1;
  if (suffix.size() == 1) {
    switch (lower(suffix.front())) {
      case 'k':
        scale = 0x1p10;
        break;
      case 'm':
        scale = 0x1p20;
        break;
      case 'g':
        scale = 0x1p30;
        break;
      case 't':
        scale = 0x1p40;
        break;
      default:
        scale = 0;
    }
  }
  if (scale == 0 || suffix.size() > 1)
    throw std::invalid_argument("unknown size suffix in " + quoted + " (K, M, G or T)");
  const double bytes = std::floor(number * scale);
  if (!(bytes < 0x1p63)) throw std::invalid_argument("byte size too large: " + quoted);
  return static_cast<std::uint64_t>(bytes);
}

namespace {

// A cgroup limit file: a number, or "max" (none).
std::uint64_t cgroup_limit(const char* path) {
  std::ifstream in(path);
  std::string text;
  if (!(in >> text) || text == "max") return 0;
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  return ec == std::errc() ? value : 0;
}

}  // namespace

std::uint64_t default_memory_budget() {
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page = ::sysconf(_SC_PAGE_SIZE);
  std::uint64_t ram =
      pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page) : std::uint64_t{4} << 30;
  for (const char* path :
       {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {
    const std::uint64_t limit = cgroup_limit(path);
    if (limit > 0 && limit < ram) ram = limit;  // v1 reports "no limit" as a huge number
  }
  return ram / 2;
}

MemoryBudget::Reservation& MemoryBudget::Reservation::operator=(Reservation&& other) noexcept {
  if (this != &other) {
    release();
    budget_ = other.budget_;
    bytes_ = other.bytes_;
    other.budget_ = nullptr;
    other.bytes_ = 0;
  }
  return *this;
}

bool MemoryBudget::Reservation::grow_to(std::uint64_t total) {
  if (total <= bytes_) return true;
  if (!budget_ || !budget_->take(total - bytes_)) return false;
  bytes_ = total;
  return true;
}

void MemoryBudget::Reservation::shrink_to(std::uint64_t total) {
  if (!budget_ || total >= bytes_) return;
  budget_->give_back(bytes_ - total);
  bytes_ = total;
}

void MemoryBudget::Reservation::release() {
  if (budget_) budget_->give_back(bytes_);
  budget_ = nullptr;
  bytes_ = 0;
}

MemoryBudget::MemoryBudget(std::uint64_t budget, std::uint64_t reserve)
    : budget_(budget), capacity_(budget > reserve ? budget - reserve : 0) {}

std::optional<MemoryBudget::Reservation> MemoryBudget::try_reserve(std::uint64_t bytes) {
  if (!take(bytes)) return std::nullopt;
  return Reservation(this, bytes);
}

std::uint64_t MemoryBudget::reserved() const {
  std::lock_guard lock(mutex_);
  return used_;
}

bool MemoryBudget::take(std::uint64_t bytes) {
  std::lock_guard lock(mutex_);
  if (bytes > capacity_ - used_) return false;
  used_ += bytes;
  return true;
}

void MemoryBudget::give_back(std::uint64_t bytes) {
  std::lock_guard lock(mutex_);
  used_ -= std::min(bytes, used_);
}

}  // namespace stlrefine::server
