// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Internal to core/io. On the machines we run on, a first-touch 4 KiB page fault costs
// ~12 us, so faulting in a 44 MB STL and its 70 MB of soup, table and output costs more
// than parsing and welding them. Transparent huge pages cut the faults 512-fold; these
// helpers ask for them on the 2 MiB-aligned interior of a fresh buffer. It is only a hint:
// if the kernel says no, we lose speed, nothing else.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/mesh/big_vector.h"

namespace stlrefine::io_detail {

using stlrefine::advise_huge_pages;
constexpr std::size_t kHugePage = HugePageAllocator<char>::kHugePage;

//! v.reserve(n), with huge pages asked for before anything touches the new memory.
template <class T>
void reserve_huge(std::vector<T>& v, std::size_t n) {
  if (n <= v.capacity()) return;
  v.reserve(n);
  advise_huge_pages(v.data(), n * sizeof(T));
}

}  // namespace stlrefine::io_detail
