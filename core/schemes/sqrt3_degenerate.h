// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "core/geometry/vec3.h"

namespace stlrefine {

//! How thin a fine face may be, in float32 ulps of its largest coordinate (epsilon times the
//! coordinate: 1-2 ulps). The binary STL rounds every coordinate by up to half an ulp, which
//! moves a corner's distance from the opposite edge by up to sqrt 3 ulps: a thinner face can
//! turn over in the output although it faces the right way in double precision (issue 17:
//! slivers of height 1e-6 mm beside the plate's trisected creases, 180 degrees off in the STL).
//! At 4 the rounding tilts a face by at most about atan(sqrt 3 / 4) = 23 degrees. Such a face
//! counts as a fold where the coarse faces it comes from are not that thin themselves (their
//! 1-to-3 split at the centroid keeps a third of their height; a thin input face cannot be
//! helped): the guard then keeps the edge instead of flipping it into the sliver, or moves the
//! face point on to its next stage.
inline constexpr double kSqrt3ThinFloatUlps = 4.0;
//! The float grid alone leaves chains: a flip whose quad is nearly flat at one end made a child
//! 1e-4 times as thin as its parents (plate 9502, step 3; 9501, step 6), whose own children,
//! a third as thin each step, fell below the grid three steps later. So a fine face thinner
//! (height over longest edge) than this fraction of the thinner of the coarse faces it comes
//! from is degenerate too. Below 1/9, every split the guard falls back to passes: the centroid
//! keeps at least a third of the coarse face's thinness, the stages towards the largest-angle
//! corner at least 2/9 and 1/9 (sqrt3_guard_stage_point); a flip past it is kept instead.
inline constexpr double kSqrt3ThinParentFraction = 0.1;

//! A triangle's height (twice its area over its longest edge), its thinness (the height over
//! the longest edge: 0 flat, sqrt 3 / 2 equilateral), and the float grid at it
//! (kSqrt3ThinFloatUlps float epsilons of its largest coordinate). Squared, from its cross
//! product n.
struct Sqrt3Shape {
  double height2 = 0, thinness2 = 0, grid2 = 0;
};

inline Sqrt3Shape sqrt3_shape(const std::array<Vec3, 3>& p, const Vec3& n) {
  double longest2 = 0, largest = 0;
  for (int k = 0; k < 3; ++k) {
    const Vec3 d = p[(k + 1) % 3] - p[k];
    longest2 = std::max(longest2, dot(d, d));
    largest = std::max({largest, std::abs(p[k].x), std::abs(p[k].y), std::abs(p[k].z)});
  }
  const double grid = kSqrt3ThinFloatUlps * std::numeric_limits<float>::epsilon() * largest;
  Sqrt3Shape s;
  s.grid2 = grid * grid;
  if (!(longest2 > 0)) return s;
  s.height2 = dot(n, n) / longest2;
  s.thinness2 = s.height2 / longest2;
  return s;
}

//! The sqrt3 fold guard's degenerate test (both hosts): fine triangle p (n its cross product)
//! is lower than the float grid, or thinner than kSqrt3ThinParentFraction of the thinner of
//! the coarse faces it comes from; unless one of those is below the grid itself (no split of
//! it can help). parents() gives the coarse faces' shapes as a pair (the same one twice for a
//! child of one face); it is called only for the few fine faces thin enough to ask.
template <class Parents>
bool sqrt3_degenerate(const std::array<Vec3, 3>& p, const Vec3& n, Parents&& parents) {
  constexpr double kFraction2 = kSqrt3ThinParentFraction * kSqrt3ThinParentFraction;
  const Sqrt3Shape child = sqrt3_shape(p, n);
  // Cheap first: no coarse face's thinness exceeds sqrt 3 / 2.
  if (child.height2 >= child.grid2 && child.thinness2 >= kFraction2 * 0.75) return false;
  const auto [f, g] = parents();
  if (f.height2 < f.grid2 || g.height2 < g.grid2) return false;
  return child.height2 < child.grid2 ||
         child.thinness2 < kFraction2 * std::min(f.thinness2, g.thinness2);
}

}  // namespace stlrefine
