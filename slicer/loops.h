// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Closed chains of one layer -> classified, oriented loops. Internal to slicer/.

#include <span>
#include <vector>

#include "slicer/slice.h"

namespace stlrefine::slicer::detail {

//! The signed (shoelace) area of a closed polygon, > 0 when counter-clockwise.
double signed_area(std::span<const Point2> points);

//! Drops chains with fewer than 3 points or zero area (counted in layer.degenerate_loops),
//! finds each loop's parent (the smallest loop containing it, by exact point-in-polygon
//! tests), classifies by depth (even = outer, odd = hole), reverses loops whose winding
//! disagrees (counted in layer.reversed_loops), and stores them in layer.loops in pre-order
//! of the nesting tree (roots and siblings in chain order). Sets layer.area.
void assemble_loops(std::vector<std::vector<Point2>>& chains, Layer& layer);

}  // namespace stlrefine::slicer::detail
