// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/features/features.h"
#include "core/mesh/mesh.h"
#include "primitives/primitive.h"

namespace stlrefine::primitives {

//! How regions are recognised.
struct RegionParams {
  //! Every input vertex of a recognised region lies within this fraction of the bounding
  //! box diagonal of its primitive, (0, 1e-2], default 1e-6.
  double tolerance = 1e-6;
};

//! A region of the input one primitive fits.
struct Region {
  Primitive primitive;
  std::size_t faces = 0;
  std::size_t vertices = 0;
  double max_residual = 0;  //!< model units (mm): the farthest input vertex of the region
  //! False: a whole crease-bounded region; true: a plane grown across smooth edges inside a
  //! crease-bounded region no single primitive fits (e.g. a flat face next to a fillet).
  bool grown = false;
};

//! The recognised regions of an input mesh.
struct RegionMap {
  std::vector<Region> regions;
  //! Per face of the input: its region's index, or -1 when it is in none.
  std::vector<std::int32_t> face_region;
  double bbox_diagonal = 0;
  double tolerance = 0;  //!< model units: RegionParams::tolerance * bbox_diagonal
};

//! Recognises regions on the input mesh (after weld and build, before refinement):
//! 1. the crease-bounded regions (faces connected across edges `features` does not mark
//!    sharp) that a plane fits (every vertex within the tolerance) are planes;
//! 2. the others, largest first, are fitted with a cylinder, a cone, a sphere and a torus;
//!    each fit absorbs the neighbouring regions (across sharp edges) whose vertices all lie
//!    on it, and the one that absorbs the most faces is taken, refitted on the union as the
//!    first type in that order that fits it (points on two coaxial circles fit a sphere as
//!    well as the cylinder they came from); a curved region needs 12 vertices (sphere,
//!    cylinder), 14 (cone) or 18 (torus), as a few points fit any curved surface;
//! 3. in a region none fits, planes are grown from its largest faces across smooth edges
//!    (every vertex of a face within the tolerance of the seed's plane, refitted at the end);
//!    a grown plane is kept when it has 2 faces or more and at least 5% of the region's
//!    area, so that the coplanar triangle pairs of a faceted smooth surface are not taken for
//!    flat faces.
//! Deterministic (faces are visited in index order, seeds by area then index).
RegionMap detect_regions(const Mesh& mesh, const Features& features, const RegionParams& params);

}  // namespace stlrefine::primitives
