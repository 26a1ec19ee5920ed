// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "core/features/features.h"
#include "core/mesh/mesh.h"

namespace stlrefine {

//! Curvatures of the LSF quadric fitted at a vertex (spec 5 gap 4): from the first and
//! second fundamental forms of s(u, v) at (0, 0). Smooth and dart vertices use the whole
//! ring; crease and boundary vertices the sector before their first sharp edge (one side
//! of the crease); corners and degenerate fits are invalid.
struct VertexCurvature {
  double gaussian = 0;    //!< K = k1 k2 (1/mm^2)
  double mean = 0;        //!< H = (k1 + k2)/2 (1/mm), sign by the ring's orientation
  double k1 = 0, k2 = 0;  //!< principal curvatures, k1 >= k2
  bool valid = false;
};

//! One entry per vertex, computed in parallel.
std::vector<VertexCurvature> vertex_curvatures(const Mesh& mesh, const Features& features);

//! Order statistics of one quantity over the valid vertices.
struct Distribution {
  double min = 0, p05 = 0, p50 = 0, p95 = 0, max = 0;
};

struct CurvatureSummary {
  std::size_t valid = 0, invalid = 0;
  Distribution gaussian, mean, k1, k2;
  //! max(|k1|, |k2|): what bounds the chordal error of an edge, kappa l^2 / 8.
  Distribution abs_max;
};

CurvatureSummary summarize(std::span<const VertexCurvature> curvatures);

}  // namespace stlrefine
