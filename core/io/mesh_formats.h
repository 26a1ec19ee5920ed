// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Mesh files besides STL (issue 19 item 2): OBJ, PLY and 3MF in, 3MF out. Every reader
// gives what the STL reader gives (a TriangleSoup of float corners), so welding,
// build_mesh and everything after it are the same code whatever the file was; a file with
// several objects (3MF) keeps them apart as parts of the soup.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/io/stl.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

enum class MeshFormat { Stl, Obj, Ply, ThreeMf };
//! "stl", "obj", "ply", "3mf".
const char* to_string(MeshFormat format);

//! The format of `bytes`, by content alone (never a file name):
//!  - "PK\x03\x04" (a zip): 3MF;
//!  - "ply" then a line break: PLY;
//!  - text whose first statement is an OBJ one ("v ", "vn ", "f ", "o ", "#"...,
//!    "mtllib") and that does not start with "solid": OBJ;
//!  - anything else: STL (read_stl says precisely what is wrong with it).
MeshFormat sniff_mesh_format(std::span<const std::uint8_t> bytes);

//! One object of a file: its name and its triangles [first, first + count) in the soup.
struct MeshPart {
  std::string name;
  std::size_t first_triangle = 0;
  std::size_t triangle_count = 0;
};

//! A unit a file declares (3MF's model unit); STL, OBJ and PLY declare none.
struct DeclaredUnit {
  std::string name;  //!< as the file says it: "micron", "millimeter", ..., "meter"
  double mm = 1.0;   //!< one unit in mm
};

//! A mesh file read: every triangle (parts one after the other) and what the file says.
struct MeshInput {
  MeshFormat format = MeshFormat::Stl;
  //! The triangles. For STL exactly read_stl's soup; soup.format is meaningful for STL only.
  TriangleSoup soup;
  std::vector<MeshPart> parts;  //!< at least one; covers the soup in order
  std::optional<DeclaredUnit> unit;
  //! PLY's encoding ("ascii", "binary_little_endian", "binary_big_endian"); empty otherwise.
  std::string encoding;
};

//! Reads any supported format (sniff_mesh_format), with StlReadOptions' limits for all:
//! max_triangles (after fanning polygons), max_abs_coordinate, max_ascii_line_length (OBJ
//! and PLY lines). Refusals are Error(MalformedStl) with a reason slug and a byte offset
//! (binary PLY, 3MF) or line (OBJ, ASCII PLY):
//!  - the STL ones (read_stl);
//!  - OBJ: syntax (bad number, a face with fewer than 3 corners, an unknown corner form),
//!    bad_index (0, or beyond the vertices defined so far, negative ones included),
//!    zero_triangles, too_many_triangles, too_many_vertices (over 3 max_triangles),
//!    non_finite, coordinate_out_of_range, line_too_long;
//!  - PLY: bad_header (no end_header, unknown format, type or element, no x/y/z, a list
//!    where a number should be, counts over the limits: before allocating), truncated
//!    (the body ends before the header's counts), syntax (ASCII body), bad_index,
//!    bad_face (fewer than 3 corners), trailing_bytes (binary data after the last
//!    element), zero_triangles, non_finite, coordinate_out_of_range, too_many_triangles;
//!  - 3MF: not_3mf (not a readable zip, no _rels/.rels, the model part it names missing,
//!    XML not well-formed or with a DOCTYPE, an element out of place, a missing or bad
//!    attribute, an unknown unit, an object id defined twice or used before it is
//!    defined, components nested over 32 deep; the message names the part and line),
//!    too_large (over kMax3mfParts parts, parts declaring or really inflating to over
//!    kMax3mfUncompressedBytes, too many objects, components or build items, one XML
//!    token over 16 MiB, a build whose expansion would cost over 8 max_triangles + 1024
//!    instances, used vertices and triangles: field max_triangles, checked before
//!    expanding), zero_triangles, bad_index, non_finite, coordinate_out_of_range (after
//!    the build transforms, of the vertices triangles use), too_many_triangles (stored, or
//!    once components are expanded: checked before expanding), too_many_vertices.
MeshInput read_mesh(std::span<const std::uint8_t> bytes, const StlReadOptions& options = {});

//! The readers read_mesh dispatches to (each checks its own format only).
MeshInput read_obj(std::span<const std::uint8_t> bytes, const StlReadOptions& options = {});
MeshInput read_ply(std::span<const std::uint8_t> bytes, const StlReadOptions& options = {});
MeshInput read_3mf(std::span<const std::uint8_t> bytes, const StlReadOptions& options = {});

//! Most bytes a 3MF's parts may inflate to (and see kMax3mfInflateRatio): declared (refused
//! before inflating) and as really inflated (counted while streaming; the XML is never
//! held whole).
inline constexpr std::uint64_t kMax3mfUncompressedBytes = std::uint64_t{4} << 30;
//! Most parts (zip entries) a 3MF may have: a model, its relationships, content types,
//! thumbnails and a few attachments fit many times over.
inline constexpr std::int64_t kMax3mfParts = 256;
//! What a 3MF's parts may really inflate to is also bounded by its size: at most
//! max(kMax3mfInflateFloor, kMax3mfInflateRatio x the package's bytes). Deflated mesh XML
//! shrinks ~3-10x (bench/results-issue19-s5-tmf-web.md); a bomb shrinks ~1000x and would
//! cost seconds of parsing per request for nothing.
inline constexpr std::uint64_t kMax3mfInflateRatio = 100;
inline constexpr std::uint64_t kMax3mfInflateFloor = std::uint64_t{64} << 20;

//! A mesh to write and the name its 3MF object gets.
struct NamedMesh {
  std::string name;
  const Mesh* mesh = nullptr;
};

//! A 3MF package (lib3mf) with one object and one build item per mesh, positions rounded
//! to float, in `unit` ("millimeter" unless told).
//! \throw Error(Internal) when a position is not finite as a float or lib3mf fails;
//! Error(BudgetExceeded) over 2^32-1 vertices or faces in one mesh.
std::string write_3mf(std::span<const NamedMesh> meshes, const std::string& unit = "millimeter");

}  // namespace stlrefine
