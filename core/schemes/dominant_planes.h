// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstdint>
#include <vector>

#include "core/features/features.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

//! Where a counter-clockwise walk around v's crease sectors starts: its most clockwise
//! half-edge on a boundary, else at a sharp edge if there is one (so that sectors do not
//! wrap around). Invalid for an isolated vertex.
HalfedgeId sector_walk_start(const Mesh& m, const Features& features, VertexId v);

//! A face's plane: unit normal n through p, its longest edge and its area.
struct FacePlane {
  Vec3 n, p;
  double size = 0;
  double area = 0;
};

//! The flat faces of a CAD part among the faces of a level (issue 17 items 2 and 6), for
//! the hosts' plane rules (split4: edge points, sqrt3: face points).
struct DominantPlanes {
  std::vector<FacePlane> plane;  //!< per face
  //! Per corner (the half-edge leaving the corner's vertex): the corner's face's plane
  //! dominates the vertex's crease sector: its faces (coplanar to the rounding of their
  //! coordinates) hold at least half of the sector's face area, and its largest face there
  //! is at least twice as large as any face off it (a flat face beside the thin strips of
  //! a fillet, not a flat net with one vertex lifted nor the equal, pairwise coplanar
  //! halves of a ruled height field's quads).
  std::vector<std::uint8_t> dominant;

  //! q lies on face f's plane to the rounding of the coordinates: 1e-6 of the larger of
  //! f's longest edge and `size`, plus about four float32 ulps of their magnitude (an STL's
  //! vertices are floats).
  bool on_plane(std::uint32_t f, const Vec3& q, double size) const;
  //! Every corner of face g lies on face f's plane.
  bool coplanar(const Mesh& m, std::uint32_t f, std::uint32_t g) const;
  //! q moved onto face f's plane.
  Vec3 project(std::uint32_t f, const Vec3& q) const;
};

DominantPlanes dominant_planes(const Mesh& m, const Features& features);

//! What dominant_planes allocates (a plane and three flags per face).
std::uint64_t dominant_planes_bytes(const Mesh& m);

}  // namespace stlrefine
