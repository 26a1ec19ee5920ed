// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// How far a mesh is from a CAD-like family's true surface (tests/support/true_surface.h),
// measured on the piecewise-linear surface itself, and how many of its faces turn away from
// the true normals (issue 17).

#include <cstddef>

#include "core/mesh/mesh.h"
#include "tests/support/cad_like.h"
#include "tests/support/true_surface.h"

namespace stlrefine::fidelity {

struct CadMetrics {
  std::size_t faces = 0, vertices = 0;
  //! Distance to the true surface: area-weighted RMS over k x k sub-triangle centroids per
  //! face, and the maximum over barycentric lattice points (vertices and edge points
  //! included).
  double rms = 0, max = 0;
  //! Per face: the angle between its normal and the true normal, the smallest at the
  //! closest points of its centroid and its corners (test::face_truth_angle_deg; at a
  //! crease, or within 1e-6 of the bbox diagonal of one, as float32 STL rounding leaves a
  //! face: the angle to the arc of normals there).
  std::size_t folded = 0;   //!< more than 90 degrees
  std::size_t over_60 = 0;  //!< more than 60 degrees (folded ones included)
  double worst_normal_deg = 0;
  double normal_rms_deg = 0;  //!< area-weighted
  std::size_t degenerate_faces = 0;
};

//! \param samples about this many RMS samples in total (k per face edge from 1 to 16).
CadMetrics measure_cad(const Mesh& mesh, const test::TrueSurface& surface,
                       std::size_t samples = 60'000);

//! The "ideal" refinement of a CAD-like shape: `levels` 1-to-4 splits whose new edge points
//! are the edges' midpoints moved onto the true surface (its closest point; for the
//! halves of a crease edge, onto the crease); old vertices kept.
Mesh ideal_refinement(const test::CadShape& shape, int levels);

}  // namespace stlrefine::fidelity
