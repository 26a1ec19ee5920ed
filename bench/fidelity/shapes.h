// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Coarse, deliberately irregular triangulations of known surfaces (the paper's Fig. 5 kind
// of input): every vertex lies exactly on the true surface, the triangulation is not.

#include <optional>
#include <string>
#include <vector>

#include "bench/fidelity/true_surface.h"
#include "core/mesh/indexed_soup.h"

namespace stlrefine::fidelity {

struct Shape {
  std::string name;
  std::string description;  //!< one line for the report
  IndexedSoup soup;         //!< outward winding
  TrueSurface surface;
  //! Height of the horizontal section plane for the undulation test (cylinder only).
  std::optional<double> section_z;
  double section_radius = 0;  //!< the radius of the true section circle
};

//! Capped cylinder (radius 10, height 20, 16 sides): one intermediate ring at z = 5, side
//! quads split "union jack" (valence 4 and 8 alternating on the middle ring, long thin
//! triangles in the 15 mm upper row), bottom cap a fan from one rim vertex, top cap a fan around a
//! centre vertex. Cap-rim edges are 90 degree creases.
Shape irregular_cylinder();
//! UV sphere (radius 10, 16 longitudes x 8 latitude bands), union-jack diagonals, poles of
//! valence 16 with thin triangles.
Shape uv_sphere();
//! Torus (R = 10, r = 4), 24 x 12 quads, union-jack diagonals (valence 4 and 8).
Shape irregular_torus();
//! Open tube (radius 10, height 20, 16 sides, ring at z = 5), union-jack sides; the two
//! rims are boundaries.
Shape open_tube();

std::vector<Shape> all_shapes();

}  // namespace stlrefine::fidelity
