// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>

#include "core/mesh/indexed_soup.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

//! What ingest found in the input and what it repaired. Nothing is dropped silently:
//! every change to the input's topology is counted here.
struct IngestReport {
  std::size_t input_triangles = 0;
  std::size_t input_vertices = 0;  //!< distinct positions after welding
  //! Facets with two identical corners: they have no area and no edge structure, so they
  //! are removed (the only facets ever removed).
  std::size_t index_degenerate_removed = 0;
  std::size_t zero_area_faces = 0;  //!< kept: they are part of the topology
  std::size_t isolated_vertices_removed = 0;
  //! Edges shared by more than two facets; their facets are cut apart (the edge becomes
  //! a sharp boundary on each sheet).
  std::size_t non_manifold_edges = 0;
  //! Vertices whose facets form more than one fan; each extra fan gets its own copy.
  std::size_t non_manifold_vertices = 0;
  std::size_t vertices_duplicated = 0;
  //! Facets whose winding was reversed to agree with their neighbours (majority wins).
  std::size_t faces_reoriented = 0;
  //! Edges cut because a sheet is not orientable (Moebius-like).
  std::size_t non_orientable_cuts = 0;
  //! Edges with 2 facets of equal winding before repair.
  std::size_t inconsistent_edges = 0;
};

struct IngestResult {
  Mesh mesh;
  IngestReport report;
};

//! Builds an oriented manifold Mesh from welded triangles: drops index-degenerate
//! facets and unreferenced vertices, orients each connected sheet consistently, cuts
//! non-manifold edges and splits non-manifold vertices into one copy per fan.
//! Vertex positions are copied unchanged (bit-identical).
//! \throw Error(NotTriangleMesh) when no facet is left.
IngestResult build_mesh(const IndexedSoup& soup);

}  // namespace stlrefine
