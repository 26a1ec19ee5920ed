// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/geometry/vec3.h"
#include "core/mesh/big_vector.h"
#include "core/mesh/handles.h"

namespace stlrefine {

//! An oriented, manifold triangle mesh as a directed-edge (implicit half-edge) structure.
//!
//! Half-edge h = 3f + k runs from corner k of face f to corner k+1, so next/prev/face are
//! arithmetic and only `twin` is stored. A half-edge without a twin lies on a boundary
//! (a real hole, or a cut made by ingest to split a non-manifold edge). Every vertex is a
//! single fan; its stored outgoing half-edge is the most clockwise one, so a ccw walk from
//! it visits the whole fan even at a boundary.
//!
//! All arrays are struct-of-arrays indexed by handle. A Mesh is built once, by ingest
//! (build_mesh) or by a refinement host, and never edited afterwards: each subdivision
//! level makes a new Mesh from a const one.
class Mesh {
 public:
  Mesh() = default;

  //! Builds the derived arrays (edges, vertex half-edges) from positions, corners and twins.
  //! \pre twins are symmetric, opposite in direction, and every vertex is one fan.
  static Mesh from_parts(BigVector<Vec3> positions, BigVector<VertexId> corner_vertex,
                         BigVector<HalfedgeId> twin);

  //! Builds a mesh whose edges and vertex half-edges the caller already knows (hosts do:
  //! they derive them arithmetically from the coarse level).
  static Mesh from_parts_with_edges(BigVector<Vec3> positions, BigVector<VertexId> corner_vertex,
                                    BigVector<HalfedgeId> twin, BigVector<EdgeId> edge_of,
                                    BigVector<HalfedgeId> edge_halfedge,
                                    BigVector<HalfedgeId> vertex_halfedge);

  std::size_t num_vertices() const { return positions_.size(); }
  std::size_t num_faces() const { return corner_vertex_.size() / 3; }
  std::size_t num_halfedges() const { return corner_vertex_.size(); }
  std::size_t num_edges() const { return edge_halfedge_.size(); }

  // --- geometry
  const Vec3& position(VertexId v) const { return positions_[v.idx]; }
  std::span<const Vec3> positions() const { return positions_; }
  BigVector<Vec3>& mutable_positions() { return positions_; }
  //! Area-weighted (unnormalised) normal of face f; zero for a degenerate face.
  Vec3 face_normal(FaceId f) const;

  // --- connectivity of half-edges
  static HalfedgeId next(HalfedgeId h) {
    return HalfedgeId(h.idx % 3 == 2 ? h.idx - 2 : h.idx + 1);
  }
  static HalfedgeId prev(HalfedgeId h) {
    return HalfedgeId(h.idx % 3 == 0 ? h.idx + 2 : h.idx - 1);
  }
  static FaceId face(HalfedgeId h) { return FaceId(h.idx / 3); }
  static HalfedgeId halfedge(FaceId f, int k) { return HalfedgeId(3 * f.idx + k); }
  HalfedgeId twin(HalfedgeId h) const { return twin_[h.idx]; }
  VertexId from(HalfedgeId h) const { return corner_vertex_[h.idx]; }
  VertexId to(HalfedgeId h) const { return corner_vertex_[next(h).idx]; }
  //! The vertex of h's face that h does not touch.
  VertexId opposite(HalfedgeId h) const { return corner_vertex_[prev(h).idx]; }
  EdgeId edge(HalfedgeId h) const { return edge_of_[h.idx]; }
  bool is_boundary(HalfedgeId h) const { return !twin_[h.idx].valid(); }

  // --- edges
  //! The edge's canonical half-edge (the one with a face on the boundary).
  HalfedgeId halfedge(EdgeId e) const { return edge_halfedge_[e.idx]; }
  bool is_boundary(EdgeId e) const { return is_boundary(edge_halfedge_[e.idx]); }

  // --- vertices
  //! Most clockwise outgoing half-edge (has no twin iff the vertex is on a boundary).
  HalfedgeId halfedge(VertexId v) const { return vertex_halfedge_[v.idx]; }
  bool is_boundary(VertexId v) const { return is_boundary(vertex_halfedge_[v.idx]); }
  bool is_isolated(VertexId v) const { return !vertex_halfedge_[v.idx].valid(); }
  //! Next outgoing half-edge around from(h), counter-clockwise; invalid at a boundary.
  HalfedgeId ccw_rotated(HalfedgeId h) const { return twin_[prev(h).idx]; }
  //! Next outgoing half-edge around from(h), clockwise; invalid at a boundary.
  HalfedgeId cw_rotated(HalfedgeId h) const {
    const HalfedgeId t = twin_[h.idx];
    return t.valid() ? next(t) : HalfedgeId();
  }
  //! Number of edges at v (faces + 1 on a boundary).
  int valence(VertexId v) const;

  std::array<VertexId, 3> face_vertices(FaceId f) const {
    const std::uint32_t b = 3 * f.idx;
    return {corner_vertex_[b], corner_vertex_[b + 1], corner_vertex_[b + 2]};
  }

  // --- raw arrays, for hosts, writers and tests
  std::span<const VertexId> corner_vertices() const { return corner_vertex_; }
  std::span<const HalfedgeId> twins() const { return twin_; }
  std::span<const EdgeId> edge_of_halfedge() const { return edge_of_; }
  std::span<const HalfedgeId> edge_halfedges() const { return edge_halfedge_; }
  std::span<const HalfedgeId> vertex_halfedges() const { return vertex_halfedge_; }

  //! Checks every structural invariant; returns an empty string when the mesh is valid,
  //! otherwise a description of the first violation. For tests and debug builds.
  std::string check_invariants() const;

  std::size_t memory_bytes() const;

 private:
  BigVector<Vec3> positions_;
  BigVector<VertexId> corner_vertex_;
  BigVector<HalfedgeId> twin_;
  BigVector<EdgeId> edge_of_;
  BigVector<HalfedgeId> edge_halfedge_;
  BigVector<HalfedgeId> vertex_halfedge_;
};

//! Calls fn(h) for every outgoing half-edge of v, counter-clockwise from the most
//! clockwise one. On a boundary vertex the last call is for the half-edge that ends the fan;
//! the boundary edge closing the fan (incoming, with no twin) is not outgoing and is not
//! visited: use `last_ring_vertex` below to get its far end.
template <class Fn>
void for_each_outgoing(const Mesh& mesh, VertexId v, Fn&& fn) {
  const HalfedgeId start = mesh.halfedge(v);
  if (!start.valid()) return;
  HalfedgeId h = start;
  do {
    fn(h);
    h = mesh.ccw_rotated(h);
  } while (h.valid() && h != start);
}

}  // namespace stlrefine
