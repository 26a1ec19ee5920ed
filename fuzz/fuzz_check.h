// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// What every harness treats as a finding besides the sanitizers' reports: an Error that
// says "bug" (Internal), an error without the precision the API promises, or a broken
// postcondition. Each of these aborts, so libFuzzer saves the input as a crash.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string_view>

#include "core/error.h"

namespace stlrefine::fuzz {

[[noreturn]] inline void fail(const char* what, const char* detail = "") {
  std::fprintf(stderr, "fuzz check failed: %s %s\n", what, detail);
  std::abort();
}

inline void check(bool ok, const char* what, const char* detail = "") {
  if (!ok) fail(what, detail);
}

//! Any refusal is fine except Internal, which means a broken invariant (HTTP 500).
inline void check_refusal(const Error& e) {
  check(e.code() != ErrorCode::Internal, "Internal error:", e.what());
  check(!e.reason().empty(), "error without a reason slug:", e.what());
}

//! A reader's refusal: a MalformedStl error with one of `reasons` that locates the problem,
//! a byte offset inside the input (binary) or a line (text).
inline void check_located_refusal(const Error& e, std::size_t input_size,
                                  std::span<const std::string_view> reasons) {
  check_refusal(e);
  check(e.code() == ErrorCode::MalformedStl, "a reader threw a non-MalformedStl error:", e.what());
  check(std::find(reasons.begin(), reasons.end(), e.reason()) != reasons.end(),
        "undocumented reason:", e.reason().c_str());
  check(e.byte_offset().has_value() != e.line().has_value(),
        "a MalformedStl error needs exactly one of byte offset and line:", e.what());
  if (e.byte_offset()) check(*e.byte_offset() <= input_size, "byte offset past the end:", e.what());
  if (e.line())
    check(*e.line() >= 1 && *e.line() <= input_size + 1, "line out of range:", e.what());
}

//! A MalformedStl error must name one of read_stl's documented reasons and locate the
//! problem.
inline void check_stl_refusal(const Error& e, std::size_t input_size) {
  if (e.code() == ErrorCode::InvalidParameter) fail("read_stl refused its own options:", e.what());
  static constexpr std::string_view kReasons[] = {"too_small",
                                                  "truncated",
                                                  "count_mismatch",
                                                  "trailing_bytes",
                                                  "zero_triangles",
                                                  "non_finite",
                                                  "coordinate_out_of_range",
                                                  "too_many_triangles",
                                                  "line_too_long",
                                                  "name_too_long",
                                                  "syntax",
                                                  "not_stl"};
  check_located_refusal(e, input_size, kReasons);
}

}  // namespace stlrefine::fuzz
