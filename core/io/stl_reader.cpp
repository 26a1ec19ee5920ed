// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

#include "core/error.h"
#include "core/io/huge_pages.h"
#include "core/io/stl.h"

namespace stlrefine {

const char* to_string(StlFormat format) {
  switch (format) {
    case StlFormat::Binary:
      return "binary";
    case StlFormat::Ascii:
      return "ascii";
  }
  return "binary";
}

void StlReadOptions::validate() const {
  require_in_range("max_triangles", max_triangles, std::size_t{1}, std::size_t{1'000'000'000});
  require_in_range("max_ascii_line_length", max_ascii_line_length, std::size_t{64},
                   std::size_t{1} << 30);
  require_in_range("max_ascii_name_length", max_ascii_name_length, std::size_t{0},
                   std::size_t{1} << 30);
  if (!(max_abs_coordinate > 0)) {  // also catches NaN
    throw Error(ErrorCode::InvalidParameter, "out_of_range",
                "max_abs_coordinate = " + std::to_string(max_abs_coordinate) +
                    " must be > 0 (use infinity for no limit)")
        .with_field("max_abs_coordinate");
  }
}

namespace {

constexpr std::size_t kHeaderBytes = 80;
constexpr std::size_t kPreambleBytes = 84;  // header + uint32 count
constexpr std::size_t kFacetBytes = 50;     // normal, 3 vertices (12 floats), uint16 attribute
constexpr std::size_t kCoordOffset = 12;    // the stored normal comes first and is skipped
// How much of the start is inspected to decide "this is text".
constexpr std::size_t kSniffBytes = 1024;

Error malformed(const char* reason, const std::string& message) {
  return Error(ErrorCode::MalformedStl, reason, message);
}

std::uint32_t load_u32le(const std::uint8_t* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap32(v);
  return v;
}

float load_f32le(const std::uint8_t* p) {
  return std::bit_cast<float>(load_u32le(p));
}

bool is_space(unsigned char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}
// Bytes that occur in text files: printable ASCII, whitespace, and UTF-8 (>= 0x80).
bool is_text_byte(unsigned char c) {
  return c >= 0x20 ? c != 0x7f : is_space(c);
}

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    char c = a[i];
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
    if (c != b[i]) return false;
  }
  return true;
}

bool starts_with(std::span<const std::uint8_t> bytes, std::string_view prefix) {
  return bytes.size() >= prefix.size() &&
         std::memcmp(bytes.data(), prefix.data(), prefix.size()) == 0;
}

std::size_t bom_length(std::span<const std::uint8_t> bytes) {
  return starts_with(bytes, "\xEF\xBB\xBF") ? 3 : 0;
}

//! "solid" (any case) after an optional BOM and whitespace, followed by whitespace or EOF.
bool starts_with_solid(std::span<const std::uint8_t> bytes) {
  std::size_t i = bom_length(bytes);
  while (i < bytes.size() && is_space(bytes[i])) ++i;
  if (bytes.size() - i < 5) return false;
  const std::string_view word(reinterpret_cast<const char*>(bytes.data() + i), 5);
  return iequals(word, "solid") && (i + 5 == bytes.size() || is_space(bytes[i + 5]));
}

//! The first KiB has no control bytes. A binary STL fails this: its count has a zero high
//! byte below 2^24 facets, and its floats are full of control bytes.
bool looks_textual(std::span<const std::uint8_t> bytes) {
  const std::size_t n = std::min(bytes.size(), kSniffBytes);
  return std::all_of(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n),
                     [](std::uint8_t c) { return is_text_byte(c); });
}

//! Names well-known other formats, for a helpful not_stl message; nullptr if unknown.
const char* foreign_format(std::span<const std::uint8_t> bytes, bool textual) {
  if (starts_with(bytes, "ply\n") || starts_with(bytes, "ply\r")) return "a PLY file";
  if (starts_with(bytes, "PK\x03\x04")) return "a ZIP archive (3MF?)";
  if (starts_with(bytes, "\x1f\x8b")) return "gzip-compressed data (unpack it first)";
  if (starts_with(bytes, "glTF")) return "a binary glTF file";
  if (!textual) return nullptr;
  if (starts_with(bytes, "OFF")) return "an OFF file";
  if (starts_with(bytes, "<?xml")) return "an XML file (AMF or 3MF model?)";
  for (const char* obj : {"#", "v ", "vn ", "vt ", "f ", "o ", "g ", "mtllib", "usemtl"}) {
    if (starts_with(bytes, obj)) return "an OBJ file";
  }
  return nullptr;
}

//! Up to 40 bytes of `s` for a message, non-printable bytes as '?'.
std::string quoted(std::string_view s) {
  std::string out = "'";
  for (std::size_t i = 0; i < std::min<std::size_t>(s.size(), 40); ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (s.size() > 40) out += "...";
  return out + "'";
}

//! The printable prefix of the 80-byte header, trimmed.
std::string header_name(std::span<const std::uint8_t> bytes) {
  std::size_t end = 0;
  while (end < kHeaderBytes && bytes[end] >= 0x20 && bytes[end] < 0x7f) ++end;
  std::size_t begin = 0;
  while (begin < end && bytes[begin] == ' ') ++begin;
  while (end > begin && bytes[end - 1] == ' ') --end;
  return std::string(reinterpret_cast<const char*>(bytes.data() + begin), end - begin);
}

const char* axis_name(std::size_t k) {
  return k == 0 ? "x" : k == 1 ? "y" : "z";
}

std::string format_double(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

//! Abs-value bit pattern of the largest float <= limit: abs bits above it are too large,
//! NaN or infinite (IEEE 754 orders non-negative floats like their bit patterns).
std::uint32_t coordinate_limit_bits(double limit) {
  if (limit >= static_cast<double>(std::numeric_limits<float>::max())) return 0x7f7fffffu;
  float f = static_cast<float>(limit);
  if (static_cast<double>(f) > limit) f = std::nextafter(f, 0.0f);
  return std::bit_cast<std::uint32_t>(f);
}

// ---------------------------------------------------------------------------------------
// Binary

[[noreturn]] void reject_binary_coordinate(std::span<const std::uint8_t> bytes, std::size_t facet,
                                           const StlReadOptions& options) {
  const std::size_t base = kPreambleBytes + kFacetBytes * facet + kCoordOffset;
  for (std::size_t k = 0; k < 9; ++k) {
    const float v = load_f32le(bytes.data() + base + 4 * k);
    const std::string where = "facet " + std::to_string(facet) + ", vertex " +
                              std::to_string(k / 3) + ": " + axis_name(k % 3) + " (byte " +
                              std::to_string(base + 4 * k) + ")";
    if (!std::isfinite(v)) {
      const char* what = std::isnan(v) ? "NaN" : v > 0 ? "+inf" : "-inf";
      throw malformed("non_finite", where + " is " + what).at_byte(base + 4 * k);
    }
    if (std::fabs(static_cast<double>(v)) > options.max_abs_coordinate) {
      throw malformed("coordinate_out_of_range", where + " = " + format_double(v) +
                                                     " exceeds max_abs_coordinate " +
                                                     format_double(options.max_abs_coordinate))
          .at_byte(base + 4 * k)
          .with_field("max_abs_coordinate");
    }
  }
  throw Error(ErrorCode::Internal, "internal", "coordinate check disagrees with itself");
}

//! Reads n facets; the caller has checked that the input holds 84 + 50 n bytes.
TriangleSoup read_binary(std::span<const std::uint8_t> bytes, std::uint32_t n,
                         std::uint64_t trailing, const StlReadOptions& options) {
  if (n == 0) {
    throw malformed("zero_triangles", "the header count is 0 and the file holds no facet")
        .at_byte(kHeaderBytes);
  }
  if (n > options.max_triangles) {
    throw malformed("too_many_triangles", "the file holds " + std::to_string(n) +
                                              " triangles, more than max_triangles " +
                                              std::to_string(options.max_triangles))
        .at_byte(kHeaderBytes)
        .with_field("max_triangles");
  }
  TriangleSoup soup;
  soup.format = StlFormat::Binary;
  soup.name = header_name(bytes);
  soup.trailing_bytes = trailing;
  io_detail::reserve_huge(soup.coords, std::size_t{9} * n);
  soup.coords.resize(std::size_t{9} * n);

  // Copy the 9 vertex floats of each facet and check them in the same pass: the max of the
  // abs bit patterns flags NaN, inf and out-of-range values with one compare per facet.
  const std::uint32_t limit_bits = coordinate_limit_bits(options.max_abs_coordinate);
  const std::uint8_t* in = bytes.data() + kPreambleBytes + kCoordOffset;
  float* out = soup.coords.data();
  for (std::size_t f = 0; f < n; ++f, in += kFacetBytes, out += 9) {
    std::uint32_t bits[9];
    std::memcpy(bits, in, sizeof bits);
    if constexpr (std::endian::native == std::endian::big) {
      for (auto& b : bits) b = __builtin_bswap32(b);
    }
    std::uint32_t worst = 0;
    for (const std::uint32_t b : bits) worst = std::max(worst, b & 0x7fffffffu);
    if (worst > limit_bits) [[unlikely]]
      reject_binary_coordinate(bytes, f, options);
    std::memcpy(out, bits, sizeof bits);
  }
  return soup;
}

//! A float that a real facet could hold: finite, not astronomically large, and not
//! absurdly tiny. Deliberately looser than max_abs_coordinate: this only tells facets from
//! noise, so that a bad size is reported as a count problem rather than as not_stl.
bool plausible_coordinate(float v) {
  const double a = std::fabs(static_cast<double>(v));
  return std::isfinite(v) && a <= 1e12 && (a == 0 || a >= 1e-30);
}

//! Looks at the first facets' vertex floats. Random bytes give implausible values
//! (NaN, 1e30, 1e-35) in about 45% of floats; real facets, even truncated, almost never.
bool plausible_facet_stream(std::span<const std::uint8_t> bytes) {
  std::size_t samples = 0, bad = 0;
  for (std::size_t f = 0; f < 64; ++f) {
    for (std::size_t k = 0; k < 9; ++k) {
      const std::size_t off = kPreambleBytes + kFacetBytes * f + kCoordOffset + 4 * k;
      if (off + 4 > bytes.size()) return samples == 0 || 4 * bad <= samples;
      ++samples;
      bad += !plausible_coordinate(load_f32le(bytes.data() + off));
    }
  }
  return 4 * bad <= samples;
}

//! Not binary by the size rule and not ASCII: say precisely why.
[[noreturn]] void reject_not_binary(std::span<const std::uint8_t> bytes) {
  const std::uint64_t size = bytes.size();
  const bool textual = looks_textual(bytes);
  if (const char* other = foreign_format(bytes, textual)) {
    throw malformed("not_stl", std::string("this is not an STL file: it looks like ") + other)
        .at_byte(0);
  }
  if (textual) {
    throw malformed("not_stl", "this is text, but not an ASCII STL: it does not start with 'solid'")
        .at_byte(0);
  }
  if (size < kPreambleBytes) {
    throw malformed("too_small", "the file has " + std::to_string(size) +
                                     " bytes; a binary STL needs at least 84 (80-byte "
                                     "header and 4-byte triangle count)")
        .at_byte(size);
  }
  if (!plausible_facet_stream(bytes)) {
    throw malformed("not_stl",
                    "this is not an STL file: the size does not fit the header count and the "
                    "data after the header does not look like facets")
        .at_byte(kPreambleBytes);
  }
  const std::uint32_t n = load_u32le(bytes.data() + kHeaderBytes);
  const std::uint64_t expected = kPreambleBytes + std::uint64_t{kFacetBytes} * n;
  const std::uint64_t body = size - kPreambleBytes;
  const std::uint64_t whole = body / kFacetBytes;
  const std::uint64_t rest = body % kFacetBytes;
  const std::string says = "the header says " + std::to_string(n) + " triangles (" +
                           std::to_string(expected) + " bytes), but the file has " +
                           std::to_string(size) + " bytes";
  if (size < expected && rest != 0) {
    const std::uint64_t at = kPreambleBytes + kFacetBytes * whole;
    throw malformed("truncated", "the file ends inside facet " + std::to_string(whole) +
                                     " (which starts at byte " + std::to_string(at) + "): " + says +
                                     ", only " + std::to_string(whole) + " whole facets")
        .at_byte(at);
  }
  if (size < expected || size - expected >= kFacetBytes) {
    std::string implied = ", which implies " + std::to_string(whole) + " triangles";
    if (rest != 0) implied += " and " + std::to_string(rest) + " extra bytes";
    throw malformed("count_mismatch", says + implied).at_byte(kHeaderBytes);
  }
  // No field: the file is at fault, not a parameter. (StlReadOptions::allow_trailing_bytes
  // is the library's opt-in; neither the HTTP API nor the CLI offers it.)
  throw malformed("trailing_bytes",
                  std::to_string(size - expected) + " stray bytes after the last of " +
                      std::to_string(n) + " facets (from byte " + std::to_string(expected) +
                      "): a binary STL ends with its last facet, so the file is padded or "
                      "damaged; re-export it")
      .at_byte(expected);
}

// ---------------------------------------------------------------------------------------
// ASCII

//! A flat token loop over the bytes: no recursion, no copies, every line capped at
//! max_ascii_line_length, so the work is linear and bounded whatever the input.
class AsciiReader {
 public:
  AsciiReader(std::span<const std::uint8_t> bytes, const StlReadOptions& options)
      : p_(reinterpret_cast<const char*>(bytes.data())),
        end_(p_ + bytes.size()),
        line_start_(p_),
        options_(options) {}

  TriangleSoup parse() {
    p_ += bom_length(
        {reinterpret_cast<const std::uint8_t*>(p_), static_cast<std::size_t>(end_ - p_)});
    line_start_ = p_;
    TriangleSoup soup;
    soup.format = StlFormat::Ascii;
    // A facet takes ~250 bytes of text; start from that guess (capped: the input may be
    // anything) and let the vector grow geometrically.
    soup.coords.reserve(9 * std::min<std::size_t>(static_cast<std::size_t>(end_ - p_) / 256 + 1,
                                                  std::size_t{1} << 14));

    std::string_view tok;
    if (!next_token(tok) || !iequals(tok, "solid")) syntax("expected 'solid'");
    soup.name = read_solid_name();
    std::size_t facets = 0;
    for (;;) {
      if (!next_token(tok)) {
        syntax("missing 'endsolid': the file ends after " + std::to_string(facets) + " facets");
      }
      if (iequals(tok, "facet")) {
        if (facets == options_.max_triangles) {
          throw malformed("too_many_triangles",
                          "more than max_triangles " + std::to_string(options_.max_triangles) +
                              " facets (line " + std::to_string(tok_line_) + ")")
              .at_line(tok_line_)
              .with_field("max_triangles");
        }
        parse_facet(soup, facets);
        ++facets;
      } else if (iequals(tok, "endsolid")) {
        if (!rest_of_line(line_budget())) line_too_long();  // the name is ignored
        if (!next_token(tok)) break;
        // Several solids in one file occur in multi-body exports: read them all.
        if (!iequals(tok, "solid")) syntax("unexpected " + quoted(tok) + " after 'endsolid'");
        read_solid_name();
      } else {
        syntax("expected 'facet' or 'endsolid', found " + quoted(tok));
      }
    }
    if (facets == 0) throw malformed("zero_triangles", "the solid has no facet").at_line(1);
    return soup;
  }

 private:
  void parse_facet(TriangleSoup& soup, std::size_t facet) {
    expect("normal", facet);
    for (int k = 0; k < 3; ++k) check_normal_component(expect_token(facet), facet);
    expect("outer", facet);
    expect("loop", facet);
    for (std::size_t v = 0; v < 3; ++v) {
      const std::string_view tok = expect_token(facet);
      if (iequals(tok, "endloop")) {
        syntax("facet " + std::to_string(facet) + " has only " + std::to_string(v) +
               " vertices; a facet needs 3");
      }
      if (!iequals(tok, "vertex")) {
        syntax("expected 'vertex' in facet " + std::to_string(facet) + ", found " + quoted(tok));
      }
      for (std::size_t k = 0; k < 3; ++k) {
        soup.coords.push_back(parse_coordinate(expect_token(facet), facet, v, k));
      }
    }
    const std::string_view tok = expect_token(facet);
    if (iequals(tok, "vertex")) {
      syntax("facet " + std::to_string(facet) +
             " has more than 3 vertices (a quad or polygon); STL facets must be triangles");
    }
    if (!iequals(tok, "endloop")) {
      syntax("expected 'endloop' in facet " + std::to_string(facet) + ", found " + quoted(tok));
    }
    expect("endfacet", facet);
  }

  //! The rest of the `solid` line, trimmed; governed by the name limit, not the line limit.
  std::string read_solid_name() {
    const std::size_t limit = options_.max_ascii_name_length;
    // Leave room for whitespace around the name; the scan stays bounded either way.
    const std::optional<std::string_view> name =
        rest_of_line(limit + options_.max_ascii_line_length);
    if (!name || name->size() > limit) {
      const std::string size = name ? " (" + std::to_string(name->size()) + " bytes)" : "";
      throw malformed("name_too_long", "the solid name on line " + std::to_string(line_) + size +
                                           " is longer than max_ascii_name_length " +
                                           std::to_string(limit))
          .at_line(line_)
          .with_field("max_ascii_name_length");
    }
    return std::string(*name);
  }

  std::size_t column() const { return static_cast<std::size_t>(p_ - line_start_); }
  std::size_t line_budget() const {
    return options_.max_ascii_line_length > column() ? options_.max_ascii_line_length - column()
                                                     : 0;
  }

  [[noreturn]] void line_too_long() const {
    throw malformed("line_too_long", "line " + std::to_string(line_) + " is longer than " +
                                         "max_ascii_line_length " +
                                         std::to_string(options_.max_ascii_line_length) + " bytes")
        .at_line(line_)
        .with_field("max_ascii_line_length");
  }

  [[noreturn]] void syntax(const std::string& message) const {
    throw malformed("syntax", message + " (line " + std::to_string(tok_line_) + ")")
        .at_line(tok_line_);
  }

  //! Skips whitespace (counting \n, \r\n and \r as line breaks) and returns the next
  //! token; false at the end of the input.
  bool next_token(std::string_view& tok) {
    while (p_ < end_) {
      const char c = *p_;
      if (c == '\n' || c == '\r') {
        if (c == '\r' && p_ + 1 < end_ && p_[1] == '\n') ++p_;
        ++line_;
        line_start_ = ++p_;
        continue;
      }
      if (!is_space(static_cast<unsigned char>(c))) break;
      if (column() >= options_.max_ascii_line_length) line_too_long();
      ++p_;
    }
    tok_line_ = line_;
    if (p_ == end_) return false;
    const char* start = p_;
    const char* stop = p_ + std::min<std::size_t>(line_budget(), end_ - p_);
    while (p_ < stop && !is_space(static_cast<unsigned char>(*p_))) ++p_;
    if (p_ < end_ && !is_space(static_cast<unsigned char>(*p_))) line_too_long();
    tok = std::string_view(start, static_cast<std::size_t>(p_ - start));
    return true;
  }

  std::string_view expect_token(std::size_t facet) {
    std::string_view tok;
    if (!next_token(tok)) {
      syntax("the file ends inside facet " + std::to_string(facet) + " (missing 'endsolid')");
    }
    return tok;
  }

  void expect(std::string_view keyword, std::size_t facet) {
    const std::string_view tok = expect_token(facet);
    if (!iequals(tok, keyword)) {
      syntax("expected '" + std::string(keyword) + "' in facet " + std::to_string(facet) +
             ", found " + quoted(tok));
    }
  }

  //! The rest of the current line, trimmed, not consuming the line break; nullopt when the
  //! line runs on for more than `budget` bytes.
  std::optional<std::string_view> rest_of_line(std::size_t budget) {
    const char* start = p_;
    const char* stop = p_ + std::min<std::size_t>(budget, end_ - p_);
    while (p_ < stop && *p_ != '\n' && *p_ != '\r') ++p_;
    if (p_ < end_ && *p_ != '\n' && *p_ != '\r') return std::nullopt;
    const char* end = p_;
    while (start < end && is_space(static_cast<unsigned char>(*start))) ++start;
    while (end > start && is_space(static_cast<unsigned char>(end[-1]))) --end;
    return std::string_view(start, static_cast<std::size_t>(end - start));
  }

  //! Stored normals are ignored, but must look like numbers so that a missing normal does
  //! not shift the grammar. Anything from_chars accepts (nan, inf too) or that starts like
  //! a number (old exporters write "-1.#IND00") is fine.
  void check_normal_component(std::string_view tok, std::size_t facet) const {
    const char c = tok[0];
    if ((c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.') return;
    float v;
    const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (r.ec == std::errc::invalid_argument || r.ptr != tok.data() + tok.size()) {
      syntax("bad normal component " + quoted(tok) + " in facet " + std::to_string(facet));
    }
  }

  float parse_coordinate(std::string_view tok, std::size_t facet, std::size_t vertex,
                         std::size_t axis) const {
    const char* b = tok.data();
    const char* e = b + tok.size();
    // from_chars takes no '+' sign; exporters write "+1.0e+00" now and then.
    if (*b == '+' && b + 1 < e && ((b[1] >= '0' && b[1] <= '9') || b[1] == '.')) ++b;
    const auto where = [&] {
      return "facet " + std::to_string(facet) + ", vertex " + std::to_string(vertex) + ": " +
             axis_name(axis) + " " + quoted(tok) + " (line " + std::to_string(tok_line_) + ")";
    };
    float v = 0;
    const auto r = std::from_chars(b, e, v);
    if (r.ec == std::errc::invalid_argument || r.ptr != e) {
      throw malformed("syntax", where() + " is not a number").at_line(tok_line_);
    }
    if (r.ec == std::errc::result_out_of_range) {
      const std::optional<float> underflow = underflowed_value(b, e);
      if (!underflow) {
        throw malformed("non_finite", where() + " overflows float").at_line(tok_line_);
      }
      v = *underflow;
    }
    if (!std::isfinite(v)) {
      throw malformed("non_finite", where() + " is not finite").at_line(tok_line_);
    }
    if (std::fabs(static_cast<double>(v)) > options_.max_abs_coordinate) {
      throw malformed("coordinate_out_of_range", where() + " exceeds max_abs_coordinate " +
                                                     format_double(options_.max_abs_coordinate))
          .at_line(tok_line_)
          .with_field("max_abs_coordinate");
    }
    return v;
  }

  //! For a number outside float's range: its value rounded to float when it is tiny
  //! (1e-50 is a legitimate way to write 0), nullopt when it overflows (1e999).
  static std::optional<float> underflowed_value(const char* b, const char* e) {
    double d = 0;
    const auto r = std::from_chars(b, e, d);
    if (r.ec == std::errc()) {
      if (std::fabs(d) > static_cast<double>(std::numeric_limits<float>::max())) {
        return std::nullopt;
      }
      return static_cast<float>(d);
    }
    // Outside double's range too: a negative exponent means tiny.
    const char* x = std::find_if(b, e, [](char c) { return c == 'e' || c == 'E'; });
    if (x + 1 < e && x[1] == '-') return *b == '-' ? -0.0f : 0.0f;
    return std::nullopt;
  }

  const char* p_;
  const char* end_;
  const char* line_start_;
  std::uint64_t line_ = 1;
  std::uint64_t tok_line_ = 1;  // line of the last token, for messages
  const StlReadOptions& options_;
};

}  // namespace

namespace {

//! Whitespace-separated tokens of an ASCII STL, in order (the shape's one pass; the reader
//! proper is AsciiReader).
class Tokens {
 public:
  explicit Tokens(std::span<const std::uint8_t> bytes)
      : text_(reinterpret_cast<const char*>(bytes.data()), bytes.size()) {}
  bool next(std::string_view& token) {
    while (pos_ < text_.size() && is_space(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    if (pos_ == text_.size()) return false;
    const std::size_t start = pos_;
    while (pos_ < text_.size() && !is_space(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    token = text_.substr(start, pos_ - start);
    return true;
  }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
};

}  // namespace

StlShape stl_shape(std::span<const std::uint8_t> bytes) {
  StlShape s;
  s.bytes = bytes.size();
  // read_stl's rules 1 and 2.
  if (bytes.size() >= kPreambleBytes) {
    const std::uint64_t n = load_u32le(bytes.data() + kHeaderBytes);
    if (bytes.size() == kPreambleBytes + kFacetBytes * n) {
      s.binary = true;
      s.faces = n;
    }
  }
  if (!s.binary && starts_with_solid(bytes) && looks_textual(bytes)) {
    Tokens tokens(bytes);
    std::string_view token;
    while (tokens.next(token))
      if (iequals(token, "endfacet")) ++s.faces;
  }
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for_each_facet_z(bytes, s, [&](double a, double b, double c) {
    for (const double z : {a, b, c}) {
      if (!std::isfinite(z)) continue;
      lo = std::min(lo, z);
      hi = std::max(hi, z);
    }
  });
  if (lo <= hi) {
    s.has_z = true;
    s.z_min = lo;
    s.z_max = hi;
  }
  return s;
}

void for_each_facet_z(std::span<const std::uint8_t> bytes, const StlShape& shape,
                      const std::function<void(double, double, double)>& fn) {
  if (shape.binary) {
    for (std::uint64_t f = 0; f < shape.faces; ++f) {
      const std::uint8_t* facet = bytes.data() + kPreambleBytes + f * kFacetBytes;
      // normal (12 bytes), then three corners of 3 floats: z at +8 of each
      fn(double(load_f32le(facet + kCoordOffset + 8)), double(load_f32le(facet + 24 + 8)),
         double(load_f32le(facet + 36 + 8)));
    }
    return;
  }
  if (shape.faces == 0) return;
  Tokens tokens(bytes);
  std::string_view token;
  double z[3];
  int corner = 0;
  while (tokens.next(token)) {
    if (iequals(token, "endfacet")) {
      if (corner == 3) fn(z[0], z[1], z[2]);
      corner = 0;
      continue;
    }
    if (!iequals(token, "vertex")) continue;
    std::string_view coordinate;
    bool ok = true;
    double value = 0;
    for (int k = 0; k < 3 && ok; ++k) {
      ok = tokens.next(coordinate);
      if (!ok) break;
      const auto [end, ec] =
          std::from_chars(coordinate.data(), coordinate.data() + coordinate.size(), value);
      ok = ec == std::errc() && end == coordinate.data() + coordinate.size();
    }
    if (ok && corner < 3) z[corner++] = value;
  }
}

TriangleSoup read_stl(std::span<const std::uint8_t> bytes, const StlReadOptions& options) {
  options.validate();
  const std::uint64_t size = bytes.size();
  if (size == 0) throw malformed("too_small", "the input is empty").at_byte(0);

  // 1. The size rule decides binary, whatever the header says ("solid..." included).
  std::uint32_t n = 0;
  std::uint64_t expected = 0;
  if (size >= kPreambleBytes) {
    n = load_u32le(bytes.data() + kHeaderBytes);
    expected = kPreambleBytes + std::uint64_t{kFacetBytes} * n;
    if (size == expected) return read_binary(bytes, n, 0, options);
  }
  // 2. ASCII: "solid" and text. A binary file with a "solid" header fails the text test.
  if (starts_with_solid(bytes) && looks_textual(bytes)) {
    return AsciiReader(bytes, options).parse();
  }
  // 3. Binary with less than one facet of padding, when the caller accepts that.
  if (options.allow_trailing_bytes && size >= kPreambleBytes && size > expected &&
      size - expected < kFacetBytes) {
    return read_binary(bytes, n, size - expected, options);
  }
  reject_not_binary(bytes);
}

namespace {

struct FreeDeleter {
  void operator()(std::uint8_t* p) const { std::free(p); }
};
using FileBuffer = std::unique_ptr<std::uint8_t, FreeDeleter>;

//! An uninitialised buffer; large ones are 2 MiB-aligned and asked to use huge pages, which
//! makes read() into them ~20 times faster than into fresh 4 KiB pages (see huge_pages.h).
FileBuffer allocate_file_buffer(std::size_t bytes) {
  void* p = nullptr;
  if (bytes >= io_detail::kHugePage) {
    const std::size_t rounded =
        (bytes + io_detail::kHugePage - 1) / io_detail::kHugePage * io_detail::kHugePage;
    p = std::aligned_alloc(io_detail::kHugePage, rounded);
    if (p != nullptr) io_detail::advise_huge_pages(p, rounded);
  } else {
    p = std::malloc(std::max<std::size_t>(bytes, 1));
  }
  if (p == nullptr) throw std::bad_alloc();
  return FileBuffer(static_cast<std::uint8_t*>(p));
}

struct FdCloser {
  int fd;
  ~FdCloser() { ::close(fd); }
};

}  // namespace

TriangleSoup read_stl_file(const std::filesystem::path& path, const StlReadOptions& options) {
  const auto fail = [&](const char* reason, const char* what) {
    const std::string why = std::error_code(errno, std::generic_category()).message();
    return Error(ErrorCode::InvalidParameter, reason,
                 std::string(what) + " '" + path.string() + "': " + why)
        .with_field("path");
  };
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw fail("cannot_open", "cannot open");
  const FdCloser closer{fd};

  struct stat st {};
  if (::fstat(fd, &st) != 0) throw fail("cannot_read", "cannot stat");
  // A regular file is read into a buffer of its size (if it grows meanwhile, the rest is
  // ignored); pipes and other streams into a growing one.
  const bool regular = S_ISREG(st.st_mode);
  std::size_t capacity = regular ? static_cast<std::size_t>(st.st_size) : std::size_t{1} << 20;
  FileBuffer buffer = allocate_file_buffer(capacity);
  std::size_t used = 0;
  for (;;) {
    if (used == capacity) {
      if (regular) break;
      FileBuffer bigger = allocate_file_buffer(2 * capacity);
      std::memcpy(bigger.get(), buffer.get(), used);
      buffer = std::move(bigger);
      capacity *= 2;
    }
    const ssize_t got = ::read(fd, buffer.get() + used, capacity - used);
    if (got < 0) {
      if (errno == EINTR) continue;
      throw fail("cannot_read", "cannot read");
    }
    if (got == 0) break;
    used += static_cast<std::size_t>(got);
  }
  return read_stl(std::span<const std::uint8_t>(buffer.get(), used), options);
}

}  // namespace stlrefine
