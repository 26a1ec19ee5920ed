// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// read_stl + weld on untrusted bytes, with the postconditions both parser harnesses check.

#include <cmath>
#include <cstdint>
#include <optional>
#include <span>

#include "core/io/stl.h"
#include "fuzz/fuzz_check.h"

namespace stlrefine::fuzz {

//! Reads `bytes` and welds (exactly, or within `tolerance`); on success checks what
//! TriangleSoup and weld promise and returns the soup, on a refusal checks the error's
//! precision and returns nullopt.
inline std::optional<TriangleSoup> read_checked(std::span<const std::uint8_t> bytes,
                                                const StlReadOptions& options,
                                                double tolerance = 0.0) {
  TriangleSoup soup;
  try {
    soup = read_stl(bytes, options);
  } catch (const Error& e) {
    check_stl_refusal(e, bytes.size());
    return std::nullopt;
  }
  const std::size_t n = soup.triangle_count();
  check(soup.coords.size() == 9 * n, "coords is not 9 floats per triangle");
  check(n >= 1, "a soup without triangles was accepted");
  check(n <= options.max_triangles, "more than max_triangles accepted");
  for (const float v : soup.coords) {
    check(std::isfinite(v), "a non-finite coordinate was accepted");
    check(std::fabs(static_cast<double>(v)) <= options.max_abs_coordinate,
          "a coordinate above max_abs_coordinate was accepted");
  }
  if (soup.format == StlFormat::Binary) {
    // The size rule: 84 + 50 n bytes, plus fewer than 50 ignored ones when allowed.
    check(bytes.size() == 84 + 50 * n + soup.trailing_bytes, "binary size rule broken");
    check(soup.trailing_bytes < 50, "a whole facet of trailing bytes was ignored");
    check(soup.trailing_bytes == 0 || options.allow_trailing_bytes,
          "trailing bytes accepted without allow_trailing_bytes");
  } else {
    check(soup.trailing_bytes == 0, "trailing bytes in an ASCII soup");
    check(soup.name.size() <= options.max_ascii_name_length, "solid name over the limit");
  }

  const IndexedSoup welded = weld(soup, tolerance);
  check(welded.triangles.size() == n, "weld changed the triangle count");
  check(welded.positions.size() <= 3 * n, "weld made more vertices than corners");
  for (const auto& t : welded.triangles)
    for (const auto v : t) check(v < welded.positions.size(), "weld index out of range");
  return soup;
}

}  // namespace stlrefine::fuzz
