// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "api/units.h"
#include "core/io/mesh_formats.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/mesh/mesh_stats.h"
#include "repair/hole_filling.h"

namespace stlrefine::api {

//! A mesh file (STL, OBJ, PLY, 3MF) read, welded and turned into a Mesh (steps 1-2 of the
//! request path), with what the report needs to know about the file itself.
struct Ingested {
  MeshFormat file_format = MeshFormat::Stl;
  StlFormat format = StlFormat::Binary;  //!< STL: binary or ASCII; PLY: its encoding's kind
  std::size_t triangles = 0;             //!< facets in the file
  std::uint64_t trailing_bytes = 0;      //!< ignored bytes after the last binary facet
  std::size_t welded_vertices = 0;       //!< distinct positions after welding
  double weld_tolerance = 0;
  IngestResult result;  //!< the mesh (in mm) and what ingest repaired
  UnitsReport units;    //!< the units assumed and the size in mm
  //! The file's objects (a 3MF's build items; one for the other formats); with a part
  //! selected (ingest_input), that part alone.
  std::vector<MeshPart> parts;
  double seconds = 0;  //!< wall time of read + weld + build
  // Set by repair_ingested (api/repair_step.h), after ingest:
  repair::RepairMode repair_mode = repair::RepairMode::None;
  repair::HoleFillReport repair;  //!< what repair=fill_holes did
  MeshStats stats;                //!< of the mesh worked on (after repair): bodies, boundaries
};

//! bytes -> read_mesh (any format, sniffed by content) -> weld -> build_mesh -> apply_units
//! (weld_tolerance is in the file's units; a 3MF's declared unit is applied as it says).
//! All of a file's objects make one mesh.
//! \throw Error(MalformedStl) with byte offset or line; Error(NotTriangleMesh), with field
//! "weld_tolerance" (reason "weld_collapsed") when the tolerance merged two corners of every
//! triangle of a file that has a proper one; Error(InvalidParameter) for a bad tolerance.
Ingested ingest_mesh(std::span<const std::uint8_t> bytes, double weld_tolerance,
                     const StlReadOptions& options = {}, const UnitOptions& units = {});
inline Ingested ingest_mesh(std::span<const std::uint8_t> bytes, double weld_tolerance,
                            const UnitOptions& units) {
  return ingest_mesh(bytes, weld_tolerance, StlReadOptions{}, units);
}

//! ingest_mesh of a file already read; `part`: that object alone (an index into
//! input.parts), else all of them.
Ingested ingest_input(const MeshInput& input, double weld_tolerance, const UnitOptions& units,
                      std::optional<std::size_t> part = std::nullopt);

//! ingest_mesh under its older name (it read STL only; callers pass STL).
inline Ingested ingest_stl(std::span<const std::uint8_t> bytes, double weld_tolerance,
                           const StlReadOptions& options = {}, const UnitOptions& units = {}) {
  return ingest_mesh(bytes, weld_tolerance, options, units);
}
inline Ingested ingest_stl(std::span<const std::uint8_t> bytes, double weld_tolerance,
                           const UnitOptions& units) {
  return ingest_mesh(bytes, weld_tolerance, StlReadOptions{}, units);
}

}  // namespace stlrefine::api
