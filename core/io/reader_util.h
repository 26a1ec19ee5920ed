// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// What the OBJ, PLY and 3MF readers share (internal to core/io): the error they throw, a
// line reader with the line-length cap, number parsing and the coordinate checks, so that
// every format refuses the same things with the same reasons as read_stl.

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <string_view>

#include "core/error.h"
#include "core/io/stl.h"

namespace stlrefine::io_detail {

inline Error malformed(const char* reason, const std::string& message) {
  return Error(ErrorCode::MalformedStl, reason, message);
}

inline bool is_blank(char c) {
  return c == ' ' || c == '\t' || c == '\v' || c == '\f';
}

//! Up to 40 bytes of `s` for a message, non-printable bytes as '?'.
inline std::string quoted(std::string_view s) {
  std::string out = "'";
  for (std::size_t i = 0; i < std::min<std::size_t>(s.size(), 40); ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    out.push_back((c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?');
  }
  if (s.size() > 40) out.append("...");
  out.push_back('\'');
  return out;
}

//! Lines of a text (\n, \r\n or \r), each at most `max_length` bytes ("line_too_long").
class LineReader {
 public:
  LineReader(std::span<const std::uint8_t> bytes, std::size_t max_length)
      : text_(reinterpret_cast<const char*>(bytes.data()), bytes.size()), max_(max_length) {}

  //! The next line without its break; false at the end.
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    ++line_;
    const std::size_t start = pos_;
    const std::size_t stop = std::min(text_.size(), start + max_ + 1);
    std::size_t end = start;
    while (end < stop && text_[end] != '\n' && text_[end] != '\r') ++end;
    if (end - start > max_) {
      throw malformed("line_too_long", "line " + std::to_string(line_) + " is longer than " +
                                           "max_ascii_line_length " + std::to_string(max_) +
                                           " bytes")
          .at_line(line_)
          .with_field("max_ascii_line_length");
    }
    line = text_.substr(start, end - start);
    pos_ = end;
    if (pos_ < text_.size()) {
      const bool cr = text_[pos_] == '\r';
      ++pos_;
      if (cr && pos_ < text_.size() && text_[pos_] == '\n') ++pos_;
    }
    return true;
  }
  //! The line last read (1 before any: an empty input's errors are on line 1).
  std::uint64_t line() const { return std::max<std::uint64_t>(line_, 1); }
  //! Byte offset of what next() reads next.
  std::size_t offset() const { return pos_; }

 private:
  std::string_view text_;
  std::size_t max_;
  std::size_t pos_ = 0;
  std::uint64_t line_ = 0;
};

//! Splits off the next blank-separated token of `rest`; false when none is left.
inline bool next_word(std::string_view& rest, std::string_view& word) {
  std::size_t i = 0;
  while (i < rest.size() && is_blank(rest[i])) ++i;
  if (i == rest.size()) return false;
  std::size_t j = i;
  while (j < rest.size() && !is_blank(rest[j])) ++j;
  word = rest.substr(i, j - i);
  rest.remove_prefix(j);
  return true;
}

//! A decimal number (a leading '+' allowed); false when `tok` is not one. Overflow gives
//! +-inf (refused later as non_finite), underflow 0.
inline bool parse_double(std::string_view tok, double& v) {
  const char* b = tok.data();
  const char* e = b + tok.size();
  if (b < e && *b == '+') ++b;
  if (b == e) return false;
  const auto r = std::from_chars(b, e, v);
  if (r.ptr != e || r.ec == std::errc::invalid_argument) return false;
  if (r.ec == std::errc::result_out_of_range) {
    // from_chars leaves v unset: tell overflow from underflow by the exponent's sign.
    const std::string_view t(b, static_cast<std::size_t>(e - b));
    const std::size_t x = t.find_first_of("eE");
    const bool tiny = x != std::string_view::npos && x + 1 < t.size() && t[x + 1] == '-';
    const bool negative = *b == '-';
    v = tiny ? 0.0
             : (negative ? -std::numeric_limits<double>::infinity()
                         : std::numeric_limits<double>::infinity());
  }
  return true;
}

//! A coordinate as the soup keeps it (a float), or the refusal read_stl makes:
//! "non_finite" (NaN, inf, beyond float's range) or "coordinate_out_of_range".
//! `where` says which vertex and axis; the error is located by `locate`.
template <class Locate>
float checked_coordinate(double v, const StlReadOptions& options, const std::string& where,
                         Locate locate) {
  if (!std::isfinite(v) || std::fabs(v) > static_cast<double>(std::numeric_limits<float>::max())) {
    Error e = malformed("non_finite", where + " is not a finite float");
    locate(e);
    throw e;
  }
  if (std::fabs(v) > options.max_abs_coordinate) {
    Error e = malformed("coordinate_out_of_range", where + " = " + std::to_string(v) +
                                                       " exceeds max_abs_coordinate " +
                                                       std::to_string(options.max_abs_coordinate));
    e.with_field("max_abs_coordinate");
    locate(e);
    throw e;
  }
  return static_cast<float>(v);
}

//! "too_many_triangles" naming the option.
inline Error too_many_triangles(std::uint64_t count, const StlReadOptions& options) {
  return malformed("too_many_triangles", "the file makes " + std::to_string(count) +
                                             " triangles or more, more than max_triangles " +
                                             std::to_string(options.max_triangles))
      .with_field("max_triangles");
}

inline const char* axis_name(std::size_t k) {
  return k == 0 ? "x" : k == 1 ? "y" : "z";
}

}  // namespace stlrefine::io_detail
