// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors

// libFuzzer harness: the ASCII STL reader (the token loop, numbers, line and name limits,
// several solids, BOM and line breaks, ASCII error reporting with line numbers) and
// welding. Seeds and dictionary are ASCII STL (fuzz/corpus/stl_ascii, fuzz/dict/stl_ascii.dict).

#include <cstdint>
#include <span>

#include "fuzz/stl_read_check.h"

using namespace stlrefine;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);

  // 1. The daemon's defaults.
  fuzz::read_checked(bytes, StlReadOptions{});

  // 2. The smallest limits the options allow, so that every limit is reached by small
  //    inputs: lines of 64 bytes, names of 8, 4 facets, coordinates up to 1000.
  StlReadOptions tight;
  tight.max_ascii_line_length = 64;
  tight.max_ascii_name_length = 8;
  tight.max_triangles = 4;
  tight.max_abs_coordinate = 1000.0;
  fuzz::read_checked(bytes, tight);
  return 0;
}
