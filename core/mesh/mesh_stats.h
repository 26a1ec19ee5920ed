// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>
#include <optional>

#include "core/geometry/vec3.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

//! Global measurements of a mesh, for reports.
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
};

MeshStats compute_stats(const Mesh& mesh);

}  // namespace stlrefine
