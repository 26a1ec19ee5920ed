// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// The cubic Hermite midpoint of an edge from its ends' surface normals: what the normals say
// the surface between two of its points does. Shared by the edge-point checks of the
// interpolatory schemes (issue 17).

#include <algorithm>
#include <cmath>

#include "core/geometry/vec3.h"

namespace stlrefine {

//! The midpoint of the cubic Hermite curve from a to b whose tangents are the chord projected
//! onto the tangent planes of the unit normals n_a and n_b, relative to the chord midpoint.
//! `chord` is b - a, `length` its norm. Exact on every circular arc (a sphere's or a
//! cylinder's cross-section), the same to third order elsewhere; zero when a normal has no
//! direction or lies within about 6 degrees of the chord (nothing to say), and on a plane.
[[gnu::always_inline]] inline Vec3 hermite_midpoint_offset(const Vec3& chord, double length,
                                                           const Vec3& na, const Vec3& nb) {
  if (!(length > 0)) return {};
  const Vec3 ta = chord - dot(chord, na) * na, tb = chord - dot(chord, nb) * nb;
  const double la2 = dot(ta, ta), lb2 = dot(tb, tb), min2 = 0.01 * (length * length);
  if (!(la2 > min2) || !(lb2 > min2)) return {};
  // The cubic Hermite midpoint's offset (length / 8) d, with |d| = 2 sin(alpha) for the angle
  // alpha between the chord and each end's tangent on a circular arc, whose sagitta is
  // (length / 2) tan(alpha / 2): divided by cos^2(alpha / 2) it is exact on every arc.
  const Vec3 d = (1.0 / std::sqrt(la2)) * ta - (1.0 / std::sqrt(lb2)) * tb;
  const double sin2 = std::min(0.25 * dot(d, d), 1.0);
  const double cos2_half = 0.5 * (1.0 + std::sqrt(1.0 - sin2));
  return (length / (8.0 * cos2_half)) * d;
}

}  // namespace stlrefine
