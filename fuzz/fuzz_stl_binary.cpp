// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors

// libFuzzer harness: the binary STL reader (read_stl's size rule, header count checks,
// facet loop, binary error reporting) and exact / tolerance welding.

#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#include "fuzz/stl_read_check.h"

using namespace stlrefine;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);

  // 1. As received, with the daemon's defaults.
  fuzz::read_checked(bytes, StlReadOptions{});

  // 2. Lenient about padding, strict about size, welding within a tolerance.
  StlReadOptions lenient;
  lenient.allow_trailing_bytes = true;
  lenient.max_abs_coordinate = 1000.0;
  fuzz::read_checked(bytes, lenient, 1e-3);

  // 3. The same facets with the header count made to fit the size, so every input, not
  //    only those with a consistent count, reaches the facet loop: the size rule then says
  //    binary, and only a zero count or a bad coordinate may refuse it.
  if (size >= 84) {
    const std::size_t n = (size - 84) / 50;
    std::vector<std::uint8_t> fitted(data, data + 84 + 50 * n);
    const auto count = static_cast<std::uint32_t>(n);
    for (int i = 0; i < 4; ++i) fitted[80 + i] = static_cast<std::uint8_t>(count >> (8 * i));
    const auto soup = fuzz::read_checked(fitted, StlReadOptions{});
    if (soup) {
      fuzz::check(soup->format == StlFormat::Binary, "a size-rule binary read as ASCII");
      fuzz::check(soup->triangle_count() == n, "binary triangle count differs from the header");
    }
  }
  return 0;
}
