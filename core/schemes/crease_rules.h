// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Stencil walks that respect sharp edges, shared by every stencil (spec section 0):
// walks stop at sharp edges and a missing stencil point is replaced by its lattice
// extrapolation (a "virtual" or reflected point), so each side of a crease is refined as
// its own patch.

#include <array>

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

//! The lattice extrapolation of the neighbour of p beyond p, seen from q: 2p - q (spec
//! section 0: "second neighbours" and curve ends).
inline Vec3 reflected_through(const Vec3& p, const Vec3& q) {
  return 2.0 * p - q;
}

//! Along the sharp polyline through edge (x, other): the curve vertex beyond x, or the
//! end condition 2x - other when x ends the polyline (corner or dart; spec section 0).
inline Vec3 curve_point_beyond(const Mesh& mesh, const Features& features, VertexId x,
                               VertexId other) {
  const VertexId beyond = features.curve_beyond(x, other);
  if (beyond.valid()) return mesh.position(beyond);
  return reflected_through(mesh.position(x), mesh.position(other));
}

//! The four curve vertices around sharp half-edge h, in order along its polyline: the one
//! before from(h) (or the end condition), from(h), to(h), and the one after to(h).
inline std::array<Vec3, 4> curve_window(const Mesh& mesh, const Features& features, HalfedgeId h) {
  const VertexId a = mesh.from(h), b = mesh.to(h);
  return {curve_point_beyond(mesh, features, a, b), mesh.position(a), mesh.position(b),
          curve_point_beyond(mesh, features, b, a)};
}

//! The next outgoing half-edge around from(h) counter-clockwise, crossing the edge of
//! prev(h); invalid when that edge is sharp (another patch) or a boundary.
inline HalfedgeId ccw_within_patch(const Mesh& mesh, const Features& features, HalfedgeId h) {
  const HalfedgeId p = Mesh::prev(h);
  return features.is_sharp(mesh.edge(p)) ? HalfedgeId() : mesh.twin(p);
}

//! The next outgoing half-edge around from(h) clockwise, crossing the edge of h; invalid
//! when that edge is sharp or a boundary.
inline HalfedgeId cw_within_patch(const Mesh& mesh, const Features& features, HalfedgeId h) {
  return features.is_sharp(mesh.edge(h)) ? HalfedgeId() : mesh.cw_rotated(h);
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
