// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/io/atomic_file.h"
#include "core/mesh/indexed_soup.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

enum class StlFormat { Binary, Ascii };
//! "binary" or "ascii".
const char* to_string(StlFormat format);

//! Limits and choices for reading untrusted STL bytes.
struct StlReadOptions {
  //! Bytes after the last facet of a binary file, fewer than one facet (1..49 bytes, e.g.
  //! exporter padding). false (default) = MalformedStl "trailing_bytes" (no field: its
  //! message speaks of the file, since the HTTP API and the CLI do not offer this option);
  //! true = ignore them and count them in TriangleSoup::trailing_bytes.
  //! Whole extra facets (50 bytes or more beyond the header count) are always
  //! "count_mismatch", whatever this says: reading only the announced facets would drop
  //! geometry silently, and the bureau would print a part with holes.
  bool allow_trailing_bytes = false;
  //! Refuse files with more facets ("too_many_triangles"); range [1, 1e9].
  std::size_t max_triangles = 100'000'000;
  //! Bytes per ASCII line, without the line break ("line_too_long"); range [64, 2^30].
  std::size_t max_ascii_line_length = 4096;
  //! Bytes of an ASCII `solid` name ("name_too_long"); range [0, 2^30].
  std::size_t max_ascii_name_length = 1024;
  //! Largest accepted |coordinate| ("coordinate_out_of_range"): nothing printable is a
  //! kilometre wide, whatever the unit. Must be > 0; infinity accepts every finite value.
  double max_abs_coordinate = 1e9;

  //! \throw Error(InvalidParameter) naming the field that is out of range.
  void validate() const;
};

//! Triangles exactly as stored: 9 floats per facet (normals are ignored: we recompute).
//! Every coordinate is finite and within StlReadOptions::max_abs_coordinate.
struct TriangleSoup {
  StlFormat format = StlFormat::Binary;
  std::string name;  //!< ASCII solid name or binary header (printable prefix)
  std::vector<float> coords;
  std::uint64_t trailing_bytes = 0;
  std::size_t triangle_count() const { return coords.size() / 9; }
};

//! Parses binary or ASCII STL, telling them apart by the size rule (84 + 50 n) and
//! content, never by the "solid" prefix alone:
//!  1. size == 84 + 50 n, n from the header: binary;
//!  2. else it starts with "solid" (after optional whitespace / UTF-8 BOM) and its first
//!     KiB is text: ASCII (errors are then ASCII errors with a line number);
//!  3. else a binary error with the precise reason.
//! Stored normals are ignored (a NaN normal is fine). Nothing is allocated from the
//! header count before it has been checked against the input size; ASCII parsing is a
//! flat loop with every line length capped.
//! \throw Error(MalformedStl) with a reason slug and the byte offset (binary) or line
//! (ASCII):
//!  - too_small: empty, or fewer than 84 bytes and not ASCII;
//!  - truncated: the file ends inside a facet;
//!  - count_mismatch: the header count disagrees with the file size (whole facets missing
//!    or surplus); the message gives both numbers and the count the size implies;
//!  - trailing_bytes: 1..49 bytes after the last facet (see allow_trailing_bytes);
//!  - zero_triangles: no facet at all;
//!  - non_finite: a NaN/inf coordinate, or an ASCII number that overflows float (1e999);
//!  - coordinate_out_of_range: |coordinate| > max_abs_coordinate (field names the option);
//!  - too_many_triangles: more than max_triangles (field names the option);
//!  - line_too_long, name_too_long: ASCII limits (field names the option);
//!  - syntax: ASCII grammar (missing endsolid, quads, bad keywords, bad numbers), with line;
//!  - not_stl: random bytes, PLY, OBJ, OFF, ZIP/3MF, gzip, ...
//! \throw Error(InvalidParameter) when the options are out of range.
TriangleSoup read_stl(std::span<const std::uint8_t> bytes, const StlReadOptions& options = {});
//! read_stl on the whole file.
//! \throw Error(InvalidParameter, field "path") when the file cannot be opened or read.
TriangleSoup read_stl_file(const std::filesystem::path& path, const StlReadOptions& options = {});

//! What an STL body is, read without parsing it into a mesh: one pass over the bytes, no
//! allocation. read_stl's rules tell binary from ASCII (the one sniffer: the memory model
//! predicts from this before any work).
struct StlShape {
  std::uint64_t bytes = 0;  //!< the body
  //! Facets the reader will see at most: the binary count when the size rule says binary
  //! (84 + 50 n bytes), else the "endfacet" keywords of an ASCII file; 0 for anything else
  //! (the reader refuses it).
  std::uint64_t faces = 0;
  bool binary = false;
  bool has_z = false;  //!< z_min / z_max were read (some finite corner)
  double z_min = 0, z_max = 0;
};

//! The shape of an STL body. O(bytes), no allocation.
StlShape stl_shape(std::span<const std::uint8_t> bytes);

//! Calls fn(z0, z1, z2) for every facet of `bytes` (of shape `shape`) whose three corner z
//! values are readable.
void for_each_facet_z(std::span<const std::uint8_t> bytes, const StlShape& shape,
                      const std::function<void(double, double, double)>& fn);

//! Merges corners into shared vertices; vertices are numbered in order of first
//! appearance and positions are the stored floats converted exactly to double.
//! -0.0 is read as +0.0 in both modes.
//!  - tolerance == 0 (default): bit-identical float positions (an open-addressing table
//!    over the 12-byte keys: ~50 ms for 871k triangles).
//!  - tolerance > 0: each corner joins the nearest existing vertex within `tolerance`
//!    (Euclidean, ties to the lower index), else starts a new one at its own position.
//!    Corners are visited in file order, so the result is deterministic, but not
//!    transitive: a chain of points 0.6 tolerance apart is not one vertex. Grid hashing,
//!    about 10 times slower than exact welding.
//! Degenerate triangles (two corners welded together) are kept: build_mesh decides.
//! \throw Error(InvalidParameter, field "tolerance") for a negative or non-finite tolerance.
IndexedSoup weld(const TriangleSoup& soup, double tolerance = 0.0);

//! STL bytes for a mesh (positions rounded to float, normals recomputed from the rounded
//! positions, unit length or zero for a degenerate face). Binary by default: the header
//! holds the name (printable ASCII, never starting with "solid"). ASCII uses shortest
//! round-trip floats, so reading the file back gives the same floats.
//! \throw Error(Internal) when a position is not finite as a float.
std::string write_stl(const Mesh& mesh, StlFormat format = StlFormat::Binary,
                      std::string_view solid_name = "stlrefine");
//! Bytes of a binary STL with `faces` facets: 84 + 50 faces.
constexpr std::uint64_t binary_stl_size(std::uint64_t faces) {
  return 84 + 50 * faces;
}

//! The binary STL of write_stl(mesh), byte for byte, given to `sink` in pieces of about
//! 1.6 MB as it is made (each piece on the TBB pool): the whole file is never in memory. A position
//! that is not finite as a float throws (Error(Internal)) when its facet is reached: pieces before
//! it were given. 	hrow Error(BudgetExceeded) over 2^32-1 faces, before any byte.
void write_binary_stl(const Mesh& mesh, const ByteSink& sink,
                      std::string_view solid_name = "stlrefine");

//! A mesh's binary STL, held as compactly as it can be made from: the positions rounded to
//! float and the corners (12 bytes a vertex, 12 a face, against the file's 50 a face), and
//! any range of the file's bytes made on demand. For answers written while they are sent:
//! the size is known up front and every check runs before the first byte.
class BinaryStl {
 public:
  //! 	hrow Error(Internal, "non_finite") as write_stl; Error(BudgetExceeded) over 2^32-1
  //! faces.
  explicit BinaryStl(const Mesh& mesh, std::string_view solid_name = "stlrefine");
  //! The same, taking the mesh apart as it goes (its double positions are freed before the
  //! corners are copied): the peak is the mesh and the float positions, not the mesh and
  //! all of this object. The mesh is gone afterwards.
  explicit BinaryStl(Mesh&& mesh, std::string_view solid_name = "stlrefine");
  //! 84 + 50 n.
  std::uint64_t size() const { return binary_stl_size(corners_.size() / 3); }
  //! Writes bytes [offset, offset + out.size()) of the file into `out`.
  //! \pre offset + out.size() <= size()
  void read(std::uint64_t offset, std::span<char> out) const;
  //! What this object holds.
  std::uint64_t memory_bytes() const {
    return sizeof(float) * positions_.size() + sizeof(std::uint32_t) * corners_.size();
  }

 private:
  //! The positions rounded to float; the mesh's own are freed when `release` is set.
  void take_positions(const Mesh& mesh, BigVector<Vec3>* release);
  //! The corners, checking that every corner's position is finite as a float.
  void take_corners(const Mesh& mesh);

  std::array<char, 84> header_;
  std::vector<float> positions_;        // 3 per vertex
  std::vector<std::uint32_t> corners_;  // 3 per face
};

//! An atomic replace of `path` (write_file_atomically) by the STL of `mesh`: binary
//! streamed (write_binary_stl), ASCII made as a whole (write_stl) first.
//! 	hrow FileError: InvalidParameter "cannot_create" (field "path") when the file cannot
//! be created; Internal "write_failed" when writing fails midway (disk full, I/O error).
void write_stl_file(const std::filesystem::path& path, const Mesh& mesh,
                    StlFormat format = StlFormat::Binary,
                    std::string_view solid_name = "stlrefine");

}  // namespace stlrefine
