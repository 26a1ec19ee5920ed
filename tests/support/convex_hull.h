// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The convex hull of points in convex position (points on a sphere, an ellipsoid, the unit
// sphere of a star-shaped surface's directions), as the test generators need it: every
// point must end up a hull vertex. Incremental (Clarkson-Shor without conflict lists,
// O(n * faces): meant for a few thousand points at most).

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/geometry/vec3.h"

namespace stlrefine::test {

//! Triangles of the convex hull of `points`, wound counter-clockwise seen from outside;
//! every point is a vertex of it.
//!
//! Robustness: the combinatorial decisions (which side of a face plane a point lies on) are
//! made exactly, on copies of the points snapped to an integer grid of 2^40 steps across
//! their bounding box (128-bit integer determinants, no rounding). The positions themselves
//! are not changed. Where snapping changes an orientation (four points cocircular to about
//! 1e-12 of the box), the result is the hull of the snapped points: a valid triangulation of
//! the same vertices whose edge there is within that tolerance of flat.
//! \throw std::runtime_error when there are fewer than 4 points, they are coplanar, two
//! points snap to the same grid point, a point lies exactly in the plane of a face it
//! meets (a degenerate configuration), or a point is not a hull vertex: callers that
//! generate random points draw new ones.
std::vector<std::array<std::uint32_t, 3>> convex_hull(std::span<const Vec3> points);

}  // namespace stlrefine::test
