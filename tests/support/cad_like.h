// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Test meshes that look like CAD exports (issue 17), each with its exact true surface:
// long thin triangles, caps fanned from one rim vertex, strips zipped between two unevenly
// and differently sampled boundary curves, big triangles or fans on planes, random points
// plus a hull on freeform. Used by the tests (tests/support/cad_like_test.cpp) and by the
// fidelity benchmark (stlrefine_fidelity --cad-families).

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/mesh/indexed_soup.h"
#include "tests/support/true_surface.h"

namespace stlrefine::test {

enum class CadFamily {
  //! r ~10, h ~20 mm: side zipped between rims of ~23 and ~37 jittered vertices, each cap a
  //! fan from one rim vertex. Creases: both rims (every vertex).
  CappedCylinder,
  //! Frustum r ~10 -> ~5, h ~15 mm: rims of ~33 and ~19 vertices, zipped, caps fanned.
  Cone,
  //! R ~10, r ~3.5 mm: ~24 rings at jittered, warped angles, each with its own vertex count
  //! (~12, consecutive rings differ), phase and jitter, zipped ring to ring. No crease.
  Torus,
  //! Annulus r ~6 .. ~10, h ~15 mm: four rims of ~37, ~29, ~23, ~17 vertices; outer wall,
  //! inner wall and both annulus caps zipped. Creases: the four rims (every vertex).
  Tube,
  //! r ~10 mm: ~300 random points (a minimum spacing) and their convex hull. No crease.
  Sphere,
  //! Semi-axes ~12, 9, 6.5 mm: ~300 random points and their convex hull. No crease.
  Ellipsoid,
  //! A star-shaped r(d) d, r ~10 mm +-40% from seven low-order harmonics: the hull of ~300
  //! random directions, mapped out radially. No crease; no quadric or torus fits it.
  Blob,
  //! Box ~40 x 30 x 20 mm, every edge rounded by ~4 mm (tangent-continuous, no crease): flat
  //! faces as two big triangles or a fan, fillets zipped between their end arcs (sampled
  //! differently), sphere-octant corners fanned from an inner point.
  RoundedBox,
  //! The 203 x 305 x 12.7 mm plate: long sides rounded by arcs that meet the flat
  //! top and bottom at a 6-12 degree crease, tessellated as 305 mm slivers zipped between the
  //! two end sections (sampled differently); top and bottom two triangles each; the end
  //! sections fanned from one vertex. Creases everywhere (every vertex).
  Plate,
};

//! Every family, in declaration order.
std::span<const CadFamily> cad_families();
//! "cylinder", "cone", "torus", "tube", "sphere", "ellipsoid", "blob", "rounded-box", "plate".
std::string_view cad_family_name(CadFamily family);
std::optional<CadFamily> cad_family_from_name(std::string_view name);

struct CadParams {
  std::uint64_t seed = 1;  //!< any value; the same seed gives the same mesh everywhere
  //! [0.25, 4]: scales the typical edge length. 1 is the sampling (rims of ~23 and
  //! ~37 vertices, ~300 hull points); 2 halves the vertices along curves and quarters the
  //! hull points.
  double coarseness = 1.0;
};

struct CadShape {
  CadFamily family = CadFamily::CappedCylinder;
  std::string name;         //!< cad_family_name(family)
  std::string description;  //!< one line: dimensions and samplings
  //! Outward winding, closed, manifold, one connected sheet; every vertex on the surface.
  IndexedSoup soup;
  std::shared_ptr<const TrueSurface> surface;
  //! Per vertex of soup: 1 when the vertex lies on a crease of the surface (where its
  //! closest_point reports on_crease()).
  std::vector<std::uint8_t> on_crease;
  //! Edges of soup that are chords of a crease curve (consecutive samples of a rim, of an
  //! end section's outline, or a straight crease line), as vertex pairs (smaller first).
  std::vector<std::array<std::uint32_t, 2>> crease_edges;
  //! For every strip zipped between two sampled curves (rims, rings, end arcs), the number
  //! of vertices on each of the two curves, in the order they were made. The two always
  //! differ.
  std::vector<std::array<std::size_t, 2>> zipped_rims;
};

//! \throw std::invalid_argument when params.coarseness is outside [0.25, 4].
CadShape make_cad_shape(CadFamily family, const CadParams& params);

//! `mesh` with its positions rounded to float, as a binary STL stores them.
Mesh float_rounded(Mesh mesh);
//! What writing `mesh` as a float STL does to its faces: `reversed` turn over (their normal
//! against the double one), `below_grid` are lower than 2 float ulps of their largest
//! coordinate (a corner's distance to the opposite edge moves by up to sqrt 3 ulps).
struct FloatRounding {
  std::size_t reversed = 0;
  std::size_t below_grid = 0;
};
FloatRounding float_rounding(const Mesh& mesh);
//! The shape's mesh as a bureau's STL holds it: float positions.
Mesh float_mesh(const CadShape& shape);

}  // namespace stlrefine::test
