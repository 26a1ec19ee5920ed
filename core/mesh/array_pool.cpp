// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/mesh/array_pool.h"

#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <mutex>
#include <new>
#include <vector>

#if defined(__SANITIZE_ADDRESS__)
#define STLREFINE_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define STLREFINE_ASAN 1
#endif
#endif
#ifdef STLREFINE_ASAN
#include <sanitizer/asan_interface.h>
#endif

namespace stlrefine::array_pool {
namespace {

// Size classes: 4, 8, 12, 16, 24, 32, 48, ... KiB up to a whole slab. Every class is a
// multiple of 4 KiB, so blocks carved one after another from a 2 MiB-aligned slab are
// page-aligned, and a slab's tail that fits no request is < 4 KiB.
constexpr std::size_t kKiB = 1024;
constexpr std::array<std::size_t, 18> kClassBytes{
    4 * kKiB,   8 * kKiB,   12 * kKiB,  16 * kKiB,   24 * kKiB,   32 * kKiB,
    48 * kKiB,  64 * kKiB,  96 * kKiB,  128 * kKiB,  192 * kKiB,  256 * kKiB,
    384 * kKiB, 512 * kKiB, 768 * kKiB, 1024 * kKiB, 1536 * kKiB, 2048 * kKiB};
static_assert(kClassBytes.front() == kMinBytes && kClassBytes.back() == kSlabBytes);

int class_of(std::size_t bytes) {
  return int(std::lower_bound(kClassBytes.begin(), kClassBytes.end(), bytes) - kClassBytes.begin());
}

// ASan: a block is addressable only while handed out, and only its requested bytes, so the
// sanitizer build still catches overruns and use-after-free in pooled arrays.
void set_addressable(void* p, std::size_t bytes, bool addressable) {
#ifdef STLREFINE_ASAN
  if (addressable)
    ASAN_UNPOISON_MEMORY_REGION(p, bytes);
  else
    ASAN_POISON_MEMORY_REGION(p, bytes);
#else
  (void)p, (void)bytes, (void)addressable;
#endif
}

//! A 2 MiB-aligned 2 MiB mapping marked for a transparent huge page, or nullptr.
std::byte* map_slab() {
  void* raw =
      ::mmap(nullptr, 2 * kSlabBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) return nullptr;
  const auto begin = reinterpret_cast<std::uintptr_t>(raw);
  const std::uintptr_t base = (begin + kSlabBytes - 1) & ~(kSlabBytes - 1);
  if (base > begin) ::munmap(raw, base - begin);
  const std::uintptr_t end = begin + 2 * kSlabBytes;
  if (end > base + kSlabBytes)
    ::munmap(reinterpret_cast<void*>(base + kSlabBytes), end - base - kSlabBytes);
  ::madvise(reinterpret_cast<void*>(base), kSlabBytes, MADV_HUGEPAGE);  // a hint
  return reinterpret_cast<std::byte*>(base);
}

struct Pool {
  std::mutex mutex;
  std::array<std::vector<void*>, kClassBytes.size()> free_blocks;
  std::vector<std::uintptr_t> slabs;  // sorted bases
  std::byte* current = nullptr;       // the newest slab, carved from the front
  std::size_t carved = 0;             // bytes of `current` handed out or put on free lists
  std::size_t limit = kDefaultLimitBytes;
  Stats stats;

  //! Free lists never allocate when a block comes back (deallocate is noexcept): each can
  //! already hold every block of its class that the slabs could contain.
  bool reserve_for_slabs(std::size_t slab_count) {
    try {
      for (std::size_t c = 0; c < kClassBytes.size(); ++c)
        free_blocks[c].reserve(slab_count * kSlabBytes / kClassBytes[c]);
      slabs.reserve(slab_count);
    } catch (const std::bad_alloc&) {
      return false;
    }
    return true;
  }

  //! Puts the rest of `current` on the free lists, largest classes first.
  void retire_current() {
    while (current && kSlabBytes - carved >= kMinBytes) {
      const std::size_t rest = kSlabBytes - carved;
      const int c = int(std::upper_bound(kClassBytes.begin(), kClassBytes.end(), rest) -
                        kClassBytes.begin()) -
                    1;
      free_blocks[std::size_t(c)].push_back(current + carved);
      carved += kClassBytes[std::size_t(c)];
    }
  }

  void* carve(std::size_t size) {
    if (!current || kSlabBytes - carved < size) {
      if ((slabs.size() + 1) * kSlabBytes > limit) return nullptr;
      if (!reserve_for_slabs(slabs.size() + 1)) return nullptr;
      std::byte* slab = map_slab();
      if (!slab) return nullptr;
      set_addressable(slab, kSlabBytes, false);
      retire_current();
      slabs.insert(std::upper_bound(slabs.begin(), slabs.end(), std::uintptr_t(slab)),
                   std::uintptr_t(slab));
      ++stats.slabs;
      current = slab;
      carved = 0;
    }
    void* block = current + carved;
    carved += size;
    return block;
  }
};

Pool& pool() {
  static Pool* instance = new Pool;  // never destroyed: arrays may be freed at exit
  return *instance;
}

}  // namespace

std::size_t block_bytes(std::size_t bytes) noexcept {
  if (bytes < kMinBytes || bytes >= kSlabBytes) return 0;
  return kClassBytes[std::size_t(class_of(bytes))];
}

void* allocate(std::size_t bytes) noexcept {
  if (bytes < kMinBytes || bytes >= kSlabBytes) return nullptr;
  const auto c = std::size_t(class_of(bytes));
  Pool& p = pool();
  std::lock_guard lock(p.mutex);
  void* block = nullptr;
  if (!p.free_blocks[c].empty()) {
    block = p.free_blocks[c].back();
    p.free_blocks[c].pop_back();
  } else {
    block = p.carve(kClassBytes[c]);
    if (!block) return nullptr;
  }
  ++p.stats.blocks_in_use;
  p.stats.bytes_in_use += kClassBytes[c];
  set_addressable(block, bytes, true);
  return block;
}

bool deallocate(void* block, std::size_t bytes) noexcept {
  if (!block || bytes < kMinBytes || bytes >= kSlabBytes) return false;
  const std::uintptr_t base = reinterpret_cast<std::uintptr_t>(block) & ~(kSlabBytes - 1);
  Pool& p = pool();
  std::lock_guard lock(p.mutex);
  if (!std::binary_search(p.slabs.begin(), p.slabs.end(), base)) return false;
  const auto c = std::size_t(class_of(bytes));
  set_addressable(block, kClassBytes[c], false);
  p.free_blocks[c].push_back(block);  // capacity reserved when the slab was added
  --p.stats.blocks_in_use;
  p.stats.bytes_in_use -= kClassBytes[c];
  return true;
}

Stats stats() {
  Pool& p = pool();
  std::lock_guard lock(p.mutex);
  return p.stats;
}

void set_limit_bytes(std::size_t bytes) {
  Pool& p = pool();
  std::lock_guard lock(p.mutex);
  p.limit = bytes;
}

std::size_t limit_bytes() {
  Pool& p = pool();
  std::lock_guard lock(p.mutex);
  return p.limit;
}

}  // namespace stlrefine::array_pool
