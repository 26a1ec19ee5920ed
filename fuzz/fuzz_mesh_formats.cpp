// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors

// libFuzzer harness: the format sniffer and the OBJ, PLY and 3MF readers (core/io/
// mesh_formats.h) on untrusted bytes: read_mesh as the request path calls it, then each
// reader directly whatever the sniffer says, with the defaults and with the smallest limits.
// A refusal must be MalformedStl with a documented reason and a location; an accepted file
// must keep read_stl's promises (finite, in range, within max_triangles) and its parts must
// cover its triangles in order. Text starting with '<' also goes to the 3MF model parser
// directly (a mutated zip rarely passes its CRC, so the XML is fuzzed on its own).
// Seeds and dictionary: corpus/mesh_formats, dict/mesh_formats.dict.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <string_view>

#include "core/io/mesh_formats.h"
#include "core/io/threemf_model.h"
#include "fuzz/fuzz_check.h"

using namespace stlrefine;

namespace {

// The STL reasons and those the OBJ, PLY and 3MF readers add.
void check_refusal(const Error& e, std::size_t size) {
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
                                                  "not_stl",
                                                  "bad_index",
                                                  "too_many_vertices",
                                                  "bad_header",
                                                  "bad_face",
                                                  "not_3mf",
                                                  "too_large"};
  fuzz::check_located_refusal(e, size, kReasons);
}

void check_input(const MeshInput& in, const StlReadOptions& options) {
  const std::size_t n = in.soup.triangle_count();
  fuzz::check(in.soup.coords.size() == 9 * n, "coords is not 9 floats per triangle");
  fuzz::check(n >= 1 && n <= options.max_triangles, "triangle count outside [1, max_triangles]");
  for (const float v : in.soup.coords) {
    fuzz::check(std::isfinite(v), "a non-finite coordinate was accepted");
    fuzz::check(std::fabs(static_cast<double>(v)) <= options.max_abs_coordinate,
                "a coordinate above max_abs_coordinate was accepted");
  }
  fuzz::check(!in.parts.empty(), "no part");
  std::size_t next = 0;
  for (const MeshPart& p : in.parts) {
    fuzz::check(p.first_triangle == next && p.triangle_count > 0, "parts do not tile the soup");
    next += p.triangle_count;
  }
  fuzz::check(next == n, "parts do not cover the soup");
  if (in.unit) fuzz::check(in.unit->mm > 0, "a unit of no size");
  const IndexedSoup welded = weld(in.soup);
  fuzz::check(welded.triangles.size() == n, "weld changed the triangle count");
}

template <class Read>
void read_checked(std::span<const std::uint8_t> bytes, const StlReadOptions& options, Read read) {
  try {
    check_input(read(bytes, options), options);
  } catch (const Error& e) {
    check_refusal(e, bytes.size());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  StlReadOptions tight;
  tight.max_ascii_line_length = 64;
  tight.max_triangles = 4;
  tight.max_abs_coordinate = 1000.0;
  for (const StlReadOptions& options : {StlReadOptions{}, tight}) {
    read_checked(bytes, options, [](auto b, const auto& o) { return read_mesh(b, o); });
    // Each reader on every input, not only on what the sniffer hands it.
    read_checked(bytes, options, [](auto b, const auto& o) { return read_obj(b, o); });
    read_checked(bytes, options, [](auto b, const auto& o) { return read_ply(b, o); });
    if (size > 0 && data[0] == '<')
      read_checked(bytes, options,
                   [](auto b, const auto& o) { return io_detail::read_3mf_model(b, o); });
  }
  // read_mesh reached the 3MF reader with the defaults on a zip; the tight limits too.
  if (sniff_mesh_format(bytes) == MeshFormat::ThreeMf)
    read_checked(bytes, tight, [](auto b, const auto& o) { return read_3mf(b, o); });
  return 0;
}
