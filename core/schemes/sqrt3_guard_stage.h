// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <array>

#include "core/geometry/vec3.h"

namespace stlrefine {

//! The sqrt3 fold guard's retreat of a face point, one stage at a time (the uniform host and
//! the adaptive hierarchy share it): the stencil's point (stage 0), 1/2 and 1/4 of the way
//! from the face's centroid (1, 2), the centroid (3: the linear split), then 1/3 and 2/3 of
//! the way towards the face's largest-angle corner (4, 5). Even the linear split folds where
//! the flipped edge's quad is not convex: beside an obtuse face the centroids' segment misses
//! the edge, and points nearer the obtuse corner keep their projections inside its edges.
inline Vec3 sqrt3_guard_stage_point(const std::array<Vec3, 3>& corners, const Vec3& stencil,
                                    int stage) {
  const Vec3 centroid = (corners[0] + corners[1] + corners[2]) * (1.0 / 3.0);
  constexpr std::array<double, 4> kScale = {1.0, 0.5, 0.25, 0.0};
  if (stage < 4) return centroid + kScale[stage] * (stencil - centroid);
  int obtuse = 0;
  double best = -2;
  for (int k = 0; k < 3; ++k) {
    const Vec3 u = normalized(corners[(k + 1) % 3] - corners[k]),
               v = normalized(corners[(k + 2) % 3] - corners[k]);
    const double cosine = -dot(u, v);  // larger for a larger angle
    if (cosine > best) best = cosine, obtuse = k;
  }
  return centroid + (stage == 4 ? 1.0 / 3.0 : 2.0 / 3.0) * (corners[obtuse] - centroid);
}

}  // namespace stlrefine
