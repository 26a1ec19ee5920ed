// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>

// A replacement global operator new for io_tests that can watch single allocations: while
// armed it records the largest request and refuses (std::bad_alloc) any request above the
// cap, so a test can prove that untrusted counts never drive an allocation without the
// machine ever attempting it.

namespace stlrefine::test {

//! RAII: arms the probe with `cap` bytes; largest() is the biggest request seen so far.
class AllocationProbe {
 public:
  explicit AllocationProbe(std::size_t cap);
  ~AllocationProbe();
  AllocationProbe(const AllocationProbe&) = delete;
  AllocationProbe& operator=(const AllocationProbe&) = delete;

  std::size_t largest() const;
  //! True when a request above the cap was refused.
  bool refused() const;
};

}  // namespace stlrefine::test
