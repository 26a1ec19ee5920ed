// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The centroid of a cubic PN triangle (Vlachos et al. 2001): what three corners' surface
// normals say the surface over a triangle's centroid does. The face-point counterpart of
// hermite.h's edge midpoint, for the sqrt3 schemes' normal check (issue 17).

#include <array>

#include "core/geometry/vec3.h"

namespace stlrefine {

//! The PN triangle's point at barycentric (1/3, 1/3, 1/3) from corners p and unit normals n,
//! relative to the flat centroid: with the edge control points (2 p_i + p_j - w_ij n_i) / 3,
//! w_ij = (p_j - p_i) . n_i, and the centre point E + (E - V) / 2, the cubic's centroid is
//! V - (1/18) sum_i n_i sum_{j != i} w_ij. On a sphere or a cylinder with their true normals it
//! is the surface's offset to second order in the edge lengths; zero on a plane.
inline Vec3 pn_centroid_offset(const std::array<Vec3, 3>& p, const std::array<Vec3, 3>& n) {
  Vec3 offset;
  for (int i = 0; i < 3; ++i) {
    const double w = dot(p[(i + 1) % 3] - p[i], n[i]) + dot(p[(i + 2) % 3] - p[i], n[i]);
    offset += (-w / 18.0) * n[i];
  }
  return offset;
}

}  // namespace stlrefine
