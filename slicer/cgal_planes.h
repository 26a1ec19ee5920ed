// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The one place the slicer's planes and predicates are defined. Internal to slicer/ (and the
// benchmark, which gives CGAL's own slicer the very same planes): it includes CGAL.

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include "core/geometry/vec3.h"

namespace stlrefine::slicer::cgal {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;

//! The horizontal plane z = height, oriented so that +z is its positive side.
inline Kernel::Plane_3 layer_plane(double height) {
  return Kernel::Plane_3(0, 0, 1, -height);
}

//! The slicer's one classification rule: a point exactly on the plane counts as above it
//! (a symbolic perturbation of the plane downwards), so no vertex is ever "on" a plane and
//! every crossing lies on an edge with one end strictly below and one end (on or) above.
inline bool on_or_above(const Kernel::Plane_3& plane, const Vec3& p) {
  return plane.oriented_side(Kernel::Point_3(p.x, p.y, p.z)) != CGAL::ON_NEGATIVE_SIDE;
}

}  // namespace stlrefine::slicer::cgal
