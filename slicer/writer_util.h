// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Number formatting and text sanitising shared by the writers. Internal to slicer/.

#include <charconv>
#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "slicer/writers.h"

namespace stlrefine::slicer::detail {

//! Shortest text that reads back to the same double (std::to_chars): JSON and SVG.
inline void append_number(std::string& out, double x) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof(buf), x);
  out.append(buf, r.ptr);
}

//! Shortest round-trip text without an exponent: CLI readers expect plain decimals.
inline void append_fixed(std::string& out, double x) {
  char buf[400];  // |x| <= 1e9 keeps it short; tiny values may need ~330 digits
  const auto r = std::to_chars(buf, buf + sizeof(buf), x, std::chars_format::fixed);
  out.append(buf, r.ptr);
}

inline void append_uint(std::string& out, std::size_t n) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof(buf), n);
  out.append(buf, r.ptr);
}

//! Printable ASCII only (and not `extra`), at most 256 bytes; anything else becomes '_'.
inline std::string sanitize_label(std::string_view label, std::string_view extra) {
  std::string s(label.substr(0, 256));
  for (char& c : s) {
    if (c < 0x20 || c > 0x7e || extra.find(c) != std::string_view::npos) c = '_';
  }
  return s;
}

std::unique_ptr<LayerWriter> make_json_writer(const WriterOptions& options);
std::unique_ptr<LayerWriter> make_svg_writer(const WriterOptions& options);
std::unique_ptr<LayerWriter> make_cli_writer(const WriterOptions& options, bool binary);

}  // namespace stlrefine::slicer::detail
