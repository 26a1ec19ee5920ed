// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "core/geometry/vec3.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

//! Global measurements of a mesh, for reports.
//! One connected body (a component over shared edges) of a mesh.
struct BodyStats {
  std::size_t faces = 0, vertices = 0, edges = 0;
  std::size_t boundary_edges = 0, boundary_loops = 0;
  bool watertight = false;         //!< no boundary edge
  std::optional<long long> genus;  //!< only when watertight: chi = 2 - 2g
  double area = 0;
  double volume = 0;  //!< signed; positive for outward normals
  Vec3 bbox_min, bbox_max;
};

struct MeshStats {
  std::size_t vertices = 0, edges = 0, faces = 0;
  std::size_t boundary_edges = 0;
  std::size_t boundary_loops = 0;
  std::size_t components = 0;
  std::size_t zero_area_faces = 0;
  long long euler_characteristic = 0;  //!< V - E + F
  bool watertight = false;             //!< no boundary edge
  std::optional<long long> genus;      //!< sum over components, only when watertight
  Vec3 bbox_min, bbox_max;
  double area = 0;
  double volume = 0;  //!< signed; positive for outward normals
  //! The largest bodies (most faces first; ties: lowest first face), at most the
  //! `max_bodies` compute_stats was asked for: a file of a million loose triangles has a
  //! million bodies, and the report lists a few.
  std::vector<BodyStats> bodies;
};

//! Counts, bounds, area, volume, genus of the whole mesh, and the same per body for the
//! `max_bodies` largest bodies. O(F) time, 8 bytes a face of scratch memory.
MeshStats compute_stats(const Mesh& mesh, std::size_t max_bodies = 10);

}  // namespace stlrefine
