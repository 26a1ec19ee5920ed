// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The heap the primitives tests allocate, for the memory prediction's check: every global
// operator new and delete of this test binary goes through here and is counted (live bytes
// by malloc_usable_size, and their peak). Not under AddressSanitizer (heap_meter_active()):
// a replaced operator new would hand ASan's malloc blocks to operator delete without its
// new/delete mismatch and sized-delete checks, and the figures would include its redzones.
#include "tests/primitives/heap_meter.h"

#ifndef STLREFINE_HEAP_METER_OFF

#include <malloc.h>

#include <atomic>
#include <cstddef>
#include <cstdlib>
#include <new>

namespace {

std::atomic<std::uint64_t> g_live{0}, g_peak{0};

void* counted(std::size_t size, std::size_t align) {
  void* p = nullptr;
  if (align <= alignof(std::max_align_t)) {
    p = std::malloc(size ? size : 1);
  } else if (posix_memalign(&p, align, size ? size : 1) != 0) {
    p = nullptr;
  }
  if (!p) return nullptr;
  const std::uint64_t now = g_live.fetch_add(malloc_usable_size(p)) + malloc_usable_size(p);
  std::uint64_t peak = g_peak.load();
  while (now > peak && !g_peak.compare_exchange_weak(peak, now)) {
  }
  return p;
}

void release(void* p) {
  if (!p) return;
  g_live.fetch_sub(malloc_usable_size(p));
  std::free(p);
}

void* or_throw(void* p) {
  if (!p) throw std::bad_alloc();
  return p;
}

}  // namespace

namespace stlrefine::test {

std::uint64_t heap_live_bytes() {
  return g_live.load();
}

std::uint64_t heap_reset_peak() {
  const std::uint64_t live = g_live.load();
  g_peak.store(live);
  return live;
}

std::uint64_t heap_peak_bytes() {
  return g_peak.load();
}

}  // namespace stlrefine::test

void* operator new(std::size_t n) {
  return or_throw(counted(n, 0));
}
void* operator new[](std::size_t n) {
  return or_throw(counted(n, 0));
}
void* operator new(std::size_t n, std::align_val_t a) {
  return or_throw(counted(n, static_cast<std::size_t>(a)));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return or_throw(counted(n, static_cast<std::size_t>(a)));
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  return counted(n, 0);
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  return counted(n, 0);
}
void operator delete(void* p) noexcept {
  release(p);
}
void operator delete[](void* p) noexcept {
  release(p);
}
void operator delete(void* p, std::size_t) noexcept {
  release(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  release(p);
}
void operator delete(void* p, std::align_val_t) noexcept {
  release(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  release(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  release(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  release(p);
}
void operator delete(void* p, const std::nothrow_t&) noexcept {
  release(p);
}
void operator delete[](void* p, const std::nothrow_t&) noexcept {
  release(p);
}

#else  // STLREFINE_HEAP_METER_OFF

namespace stlrefine::test {

std::uint64_t heap_live_bytes() {
  return 0;
}
std::uint64_t heap_reset_peak() {
  return 0;
}
std::uint64_t heap_peak_bytes() {
  return 0;
}

}  // namespace stlrefine::test

#endif  // STLREFINE_HEAP_METER_OFF
