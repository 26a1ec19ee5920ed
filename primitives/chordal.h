// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <vector>

#include "core/features/features.h"
#include "core/mesh/mesh.h"

namespace stlrefine::primitives {

//! The centroid of a triangle inscribed in a sphere over its edges' midpoints, equilateral:
//! (circumradius / half an edge)^2 = 4/3 (the farthest point of a flat face from a surface
//! curving alike in every direction is its centroid, the edges' sagittas bound the midpoints).
inline constexpr double kCentroidOverEdge = 4.0 / 3.0;

//! The input's own chordal error as its geometry allows it, per input face f (mm): how far a
//! smooth surface through f's corners, whose normals are those of the faces around them, can
//! be from f. Each edge e = (a, b) of f (sharp or not: a crease is a chord of its curve) is
//! the chord, of length L and direction t, of a surface curve whose end normals are taken
//! as the normals of the faces of f's sector at a and at b (the faces around the corner
//! reached from f without crossing a sharp or boundary edge; for a sharp e, also the
//! sectors across it: a rim curving in a flat cap's plane shows only in the wall's normals).
//! A unit normal n tilted by
//! asin |n . t| towards the chord turns the curve by that much at that end, so the curve
//! turns by at most psi = asin max_a |n . t| + asin max_b |n . t| along e, and a circular
//! arc of chord L turning by psi has sagitta (L / 2) tan(psi / 4). Along a long straight
//! edge (a sliver on a cylinder or fillet) the normals around both ends are perpendicular
//! to it and its sagitta is 0; across the curving direction the neighbours' tilt shows.
//! The bound is kCentroidOverEdge times the largest sagitta of f's edges, at least `floor`
//! (mm; rounding: a face of a flat region gets the floor).
std::vector<double> chordal_bounds(const Mesh& mesh, const Features& features, double floor);

}  // namespace stlrefine::primitives
