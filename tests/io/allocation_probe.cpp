// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "tests/io/allocation_probe.h"

#include <atomic>
#include <cstdlib>
#include <new>

namespace {

std::atomic<bool> g_armed{false};
std::atomic<bool> g_refused{false};
std::atomic<std::size_t> g_cap{0};
std::atomic<std::size_t> g_largest{0};

void* allocate(std::size_t n) {
  if (g_armed.load(std::memory_order_relaxed)) {
    std::size_t seen = g_largest.load(std::memory_order_relaxed);
    while (n > seen && !g_largest.compare_exchange_weak(seen, n)) {
    }
    if (n > g_cap.load(std::memory_order_relaxed)) {
      g_refused.store(true);
      throw std::bad_alloc();
    }
  }
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}

}  // namespace

void* operator new(std::size_t n) {
  return allocate(n);
}
void* operator new[](std::size_t n) {
  return allocate(n);
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  std::free(p);
}

namespace stlrefine::test {

AllocationProbe::AllocationProbe(std::size_t cap) {
  g_cap.store(cap);
  g_largest.store(0);
  g_refused.store(false);
  g_armed.store(true);
}

AllocationProbe::~AllocationProbe() {
  g_armed.store(false);
}

std::size_t AllocationProbe::largest() const {
  return g_largest.load();
}
bool AllocationProbe::refused() const {
  return g_refused.load();
}

}  // namespace stlrefine::test
