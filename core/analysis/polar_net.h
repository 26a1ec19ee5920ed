// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The polar net of spec 6 (numerical recipe, step 1): one vertex of valence n and rings of
// regular triangle lattice around it. Used to build local subdivision matrices and, by the
// spectral schemes, to collect the rings around an extraordinary vertex of a real mesh.

#include <cstddef>
#include <vector>

#include "core/features/features.h"
#include "core/mesh/mesh.h"

namespace stlrefine::analysis {

//! Polar addressing: the centre, then per sector k = 0..n-1 the lattice points (k, a, b)
//! with a >= 1, b >= 0, a + b <= rings, at a u_k + b u_k+1 (u_k the k-th spoke). Point
//! (k, 0, b) is (k+1, b, 0). Positions p of one sector are ordered by ring, then by b:
//! (1,0); (2,0), (1,1); (3,0), (2,1), (1,2); ... The flat index of (k, p) is 1 + p n + k
//! (position-major), so every position's n copies are adjacent: the layout of the
//! block-circulant structure.
struct PolarLayout {
  int valence = 0;
  int rings = 0;

  //! Positions per sector: rings (rings + 1) / 2.
  int positions() const { return rings * (rings + 1) / 2; }
  //! 1 + n * positions().
  int size() const { return 1 + valence * positions(); }
  int index(int position, int sector) const {
    return 1 + position * valence + ((sector % valence) + valence) % valence;
  }
  //! Position of lattice point (a, b), a >= 1, b >= 0, a + b <= rings.
  static int position(int a, int b) {
    const int r = a + b;
    return (r - 1) * r / 2 + b;
  }
  //! Ring (a + b) of position p.
  static int ring_of(int position);
  //! Lattice coordinates (a, b) of position p.
  static void lattice(int position, int& a, int& b);
};

//! A planar polar net: the centre at the origin, spoke k along angle 2 pi k / n, every
//! sector an affine image of a 60-degree wedge of the unit triangle lattice, z = 0. The
//! outer ring is the boundary. `ids[i]` is the vertex of flat index i (PolarLayout of
//! `rings`); the mesh has `rings` rings in total.
struct PolarNet {
  PolarLayout layout;
  Mesh mesh;
  std::vector<VertexId> ids;
};

//! \pre valence >= 3, rings >= 1.
PolarNet make_polar_net(int valence, int rings);

//! A mesh from counter-clockwise triangles over `positions` (twins found by vertex pairs).
//! \pre the triangles form an oriented manifold in which every vertex is one fan.
Mesh mesh_from_triangles(BigVector<Vec3> positions, BigVector<VertexId> corners);

//! Walks `rings` rings of regular lattice around from(spoke0) on any mesh and returns the
//! vertices in PolarLayout order (spoke k is spoke0 turned k times counter-clockwise).
//! Returns an empty vector when the neighbourhood is not such a net: the centre's valence
//! is not n, a vertex in rings 1..rings is not interior with valence 6, or two lattice
//! points land on the same vertex (a mesh too small to hold the rings).
std::vector<VertexId> walk_polar_net(const Mesh& mesh, HalfedgeId spoke0, int rings);

}  // namespace stlrefine::analysis
