// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Stencil walks that respect sharp edges, shared by every stencil (spec section 0):
// walks stop at sharp edges and a missing stencil point is replaced by its lattice
// extrapolation (a "virtual" or reflected point), so each side of a crease is refined as
// its own patch.

#include "core/features/features.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

//! The tip of the triangle across the edge of h, seen from h's face (a, b, c):
//! the real vertex when the edge is not sharp, else the virtual point a + b - c.
//!
//!        c                 c = opposite(h)
//!       / \                a = from(h), b = to(h)
//!      a---b  h
//!       \ /
//!        d   <- d, or a + b - c when a-b is sharp
inline Vec3 tip_across(const Mesh& mesh, const Features& features, HalfedgeId h) {
  const HalfedgeId t = mesh.twin(h);
  if (t.valid() && !features.is_sharp(mesh.edge(h))) return mesh.position(mesh.opposite(t));
  return mesh.position(mesh.from(h)) + mesh.position(mesh.to(h)) - mesh.position(mesh.opposite(h));
}

//! Along the sharp polyline through edge (x, other): the curve vertex beyond x, or the
//! end condition 2x - other when x ends the polyline (corner or dart; spec section 0).
inline Vec3 curve_point_beyond(const Mesh& mesh, const Features& features, VertexId x,
                               VertexId other) {
  const VertexId beyond = features.curve_beyond(x, other);
  if (beyond.valid()) return mesh.position(beyond);
  return 2.0 * mesh.position(x) - mesh.position(other);
}

//! Outgoing half-edge of v that ends at w (invalid if none). O(valence).
inline HalfedgeId halfedge_to(const Mesh& mesh, VertexId v, VertexId w) {
  HalfedgeId found;
  for_each_outgoing(mesh, v, [&](HalfedgeId h) {
    if (mesh.to(h) == w) found = h;
  });
  return found;
}

//! Calls fn(j, ring_vertex) for the closed 1-ring of an interior vertex, starting with the
//! far end of `first` (j = 0) and going counter-clockwise. Returns the valence.
template <class Fn>
int for_each_ring_vertex_from(const Mesh& mesh, HalfedgeId first, Fn&& fn) {
  int j = 0;
  HalfedgeId h = first;
  do {
    fn(j++, mesh.to(h));
    h = mesh.ccw_rotated(h);
  } while (h.valid() && h != first);
  return j;
}

}  // namespace stlrefine
