// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <algorithm>
#include <cmath>

#include "core/geometry/vec3.h"

namespace stlrefine {

//! Closest distance from p to triangle (a, b, c) (Ericson, Real-Time Collision Detection
//! 5.1.5); a degenerate triangle gives the distance to its nearest corner.
inline double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return distance(p, a);
  const Vec3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return distance(p, b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return distance(p, a + (d1 / (d1 - d3)) * ab);
  const Vec3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return distance(p, c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return distance(p, a + (d2 / (d2 - d6)) * ac);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return distance(p, b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b));
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) return std::min({distance(p, a), distance(p, b), distance(p, c)});
  return distance(p, a + (vb / denom) * ab + (vc / denom) * ac);
}

}  // namespace stlrefine
