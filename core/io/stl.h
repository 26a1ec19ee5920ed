// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "core/mesh/indexed_soup.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

enum class StlFormat { Binary, Ascii };
const char* to_string(StlFormat format);

//! Limits and choices for reading untrusted STL bytes.
struct StlReadOptions {
  //! Binary files with bytes after the last facet: false = MalformedStl "trailing_bytes";
  //! true = ignore them and count them in TriangleSoup::trailing_bytes.
  bool allow_trailing_bytes = false;
  std::size_t max_triangles = 100'000'000;     //!< refuse larger files ("too_many_triangles")
  std::size_t max_ascii_line_length = 4096;    //!< bytes per ASCII line ("line_too_long")
  std::size_t max_ascii_name_length = 1024;    //!< solid name ("name_too_long")
};

//! Triangles exactly as stored: 9 floats per facet (normals are ignored: we recompute).
struct TriangleSoup {
  StlFormat format = StlFormat::Binary;
  std::string name;  //!< ASCII solid name or binary header (printable prefix)
  std::vector<float> coords;
  std::uint64_t trailing_bytes = 0;
  std::size_t triangle_count() const { return coords.size() / 9; }
};

//! Parses binary or ASCII STL, telling them apart by the size rule (84 + 50 n) and
//! content, never by the "solid" prefix alone.
//! \throw Error(MalformedStl) with a reason slug and the byte offset (binary) or line
//! (ASCII): too_small, truncated, count_mismatch, trailing_bytes, zero_triangles,
//! non_finite, line_too_long, name_too_long, syntax, not_stl, too_many_triangles.
TriangleSoup read_stl(std::span<const std::uint8_t> bytes, const StlReadOptions& options = {});
TriangleSoup read_stl_file(const std::filesystem::path& path,
                           const StlReadOptions& options = {});

//! Merges corners into shared vertices. tolerance == 0: bit-identical float positions
//! (exact, the default). tolerance > 0: corners closer than tolerance are merged.
IndexedSoup weld(const TriangleSoup& soup, double tolerance = 0.0);

//! STL bytes for a mesh (positions rounded to float). Binary by default.
std::string write_stl(const Mesh& mesh, StlFormat format = StlFormat::Binary,
                      std::string_view solid_name = "stlrefine");
void write_stl_file(const std::filesystem::path& path, const Mesh& mesh,
                    StlFormat format = StlFormat::Binary, std::string_view solid_name = "stlrefine");

}  // namespace stlrefine
