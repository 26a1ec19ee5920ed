// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// repair=fill_holes (issue 19 item 5): close the open boundaries of a part before it is
// refined or sliced, with CGAL's hole filling (Liepa: minimal-area triangulation, refined
// to the density of the rim, then faired). CGAL stays private to this module, as in
// slicer/ and primitives/.

#include <atomic>
#include <cstddef>
#include <string_view>

#include "core/mesh/build_mesh.h"
#include "core/mesh/mesh.h"

namespace stlrefine::repair {

enum class RepairMode { None, FillHoles };
std::string_view to_string(RepairMode mode);

struct HoleFillOptions {
  //! A hole with more rim edges than this is left open (the Delaunay search space and the
  //! fairing's system grow with it): counted in HoleFillReport::left_open.
  std::size_t max_hole_edges = 10000;
  //! Holes with at most this many rim edges are refined to the rim's density and faired;
  //! longer ones get the rim's own triangulation (n - 2 faces, flat).
  std::size_t max_refined_rim = 200;
  //! The faces refining may add over all holes of a request (estimated 0.2 n^2 + n per
  //! refined hole before it is filled): past it, holes are triangulated flat. Together
  //! with max_refined_rim this bounds the repair's memory and time by the input's size.
  std::size_t max_added_faces = 200000;
};

struct HoleFillReport {
  std::size_t holes = 0;           //!< boundary loops found
  std::size_t filled = 0;          //!< closed (triangulated, refined, faired)
  std::size_t fairing_failed = 0;  //!< closed, but the fairing's solver failed: left flat
  std::size_t flat = 0;       //!< closed by the rim's own triangulation (long rim or budget spent)
  std::size_t left_open = 0;  //!< rim longer than max_hole_edges, or no triangulation found
  std::size_t largest_hole_edges = 0;
  //! Not run: the mesh has edges cut apart by ingest (two boundary edges between the same
  //! two vertices), which CGAL's Surface_mesh cannot hold; every hole stays open.
  bool skipped = false;
  std::size_t faces_added = 0;
  std::size_t vertices_added = 0;
  double seconds = 0;
};

//! The mesh with its holes closed. Every input vertex keeps its index and its position bit
//! for bit (new vertices come after them); the input's faces come first, in their order.
//! A mesh without a boundary comes back as it is (report.holes == 0).
//! \throw Error(Cancelled) when *cancel is set (checked before each hole).
IngestResult fill_holes(const Mesh& mesh, const HoleFillOptions& options, HoleFillReport& report,
                        const std::atomic<bool>* cancel = nullptr);

}  // namespace stlrefine::repair
