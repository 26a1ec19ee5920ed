// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// How far a refined mesh is from the true surface it approximates, measured on the
// piecewise-linear surface itself (samples inside every face), not only at its vertices.

#include <cstddef>

#include "bench/fidelity/true_surface.h"
#include "core/mesh/mesh.h"

namespace stlrefine::fidelity {

struct Metrics {
  std::size_t faces = 0, vertices = 0;
  //! Distance to the true surface over the whole mesh: area-weighted RMS (sub-triangle
  //! centroids, k x k per face) and the maximum (barycentric lattice points, which include
  //! the vertices and edges).
  double rms = 0, max = 0;
  //! Angle between each face's normal and the true normal of the surface piece (side,
  //! cap, ...) nearest to the face's centroid, at the sample's nearest point on that piece;
  //! area-weighted RMS and maximum, in degrees.
  double normal_rms_deg = 0, normal_max_deg = 0;
  //! Vertices of flat caps (all their faces lie on a cap): largest |z - z_cap|. Negative
  //! when the shape has no cap.
  double cap_max = -1;
  std::size_t cap_vertices = 0;
  //! Vertices on a rim (a boundary, or where faces of two different surface pieces meet):
  //! largest distance from the rim circle. Negative when the shape has no rim.
  double rim_max = -1;
  std::size_t rim_vertices = 0;
  //! Faces whose normal is more than 90 degrees from the true normal at their centroid.
  std::size_t folds = 0;
  std::size_t degenerate_faces = 0;
  //! Edges whose dihedral angle exceeds the crease angle (the rims should stay sharp).
  std::size_t sharp_edges = 0;
  //! Where the largest distance was found, and in which face.
  Vec3 worst_point;
  FaceId worst_face;
};

//! \param samples about this many RMS samples in total (k per face edge chosen from it).
Metrics measure(const Mesh& mesh, const TrueSurface& surface, double crease_angle_deg,
                std::size_t samples = 200'000);

}  // namespace stlrefine::fidelity
