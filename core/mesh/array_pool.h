// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>

namespace stlrefine::array_pool {

// Mesh arrays from 4 KiB up to 2 MiB live in 2 MiB transparent huge pages ("slabs")
// that the process keeps and reuses. Why: a fresh 4 KiB page costs a page fault when first
// touched, and on virtual machines a fault is dear (13 us on the benchmark VM, where a whole
// 2 MiB huge page costs ~0.1 ms). A refinement with a 39k-triangle output spent ~85% of its
// time faulting in its ~2.5 MB of arrays, in a fresh process and again on every request of
// the daemon, because malloc hands freed memory of that size back to the kernel. Arrays of
// 2 MiB and more get huge pages of their own (HugePageAllocator); smaller ones than a page
// stay with malloc. Small jobs then share one slab: after the first, no faults at all. The pool
// never holds more than limit_bytes() of slabs; past that, allocate() says no and the caller falls
// back to operator new.

constexpr std::size_t kMinBytes = std::size_t{4} << 10;
constexpr std::size_t kSlabBytes = std::size_t{2} << 20;
constexpr std::size_t kDefaultLimitBytes = std::size_t{64} << 20;

//! A block of at least `bytes`, page-aligned, or nullptr when bytes is outside
//! [kMinBytes, kSlabBytes) or the pool is at its limit. Thread-safe.
void* allocate(std::size_t bytes) noexcept;

//! Takes back a block allocate(bytes) gave (true); false, doing nothing, for any other
//! pointer. `bytes` must be the size it was allocated with.
bool deallocate(void* block, std::size_t bytes) noexcept;

//! The size of the block allocate(bytes) gives (its size class): bytes rounded up to
//! 4, 8, 12, 16, 24, ... KiB (at most half more, or one page), 0 outside [kMinBytes, kSlabBytes).
std::size_t block_bytes(std::size_t bytes) noexcept;

struct Stats {
  std::size_t slabs = 0;          //!< slabs taken from the kernel (never given back)
  std::size_t blocks_in_use = 0;  //!< blocks handed out and not yet returned
  std::size_t bytes_in_use = 0;   //!< their block sizes
};
Stats stats();

//! Slabs stop being added once they would pass this many bytes (rounded down to whole
//! slabs); slabs already taken stay. Default kDefaultLimitBytes.
void set_limit_bytes(std::size_t bytes);
std::size_t limit_bytes();

}  // namespace stlrefine::array_pool
