// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Shape factories for the tests (pmp-library style `icosahedron()`): every shape is built
// as an IndexedSoup with outward (counter-clockwise seen from outside) winding, so tests
// can feed it to build_mesh directly or perturb it first (flip a facet, add a fin, ...).

#include <cstdint>
#include <functional>
#include <string>

#include "core/mesh/indexed_soup.h"
#include "core/mesh/mesh.h"

namespace stlrefine::test {

//! Regular tetrahedron with circumradius 1, centred at the origin.
IndexedSoup tetrahedron_soup();
//! The facets of a binary STL file (corners welded where they are bit-identical, as the
//! daemon's default ingest does), read without the io library; empty when it cannot be read.
IndexedSoup read_binary_stl_soup(const std::string& path);

//! Unit octahedron: vertices +-e_x, +-e_y, +-e_z.
IndexedSoup octahedron_soup();
//! Regular icosahedron with circumradius 1, centred at the origin.
IndexedSoup icosahedron_soup();
//! Axis-aligned cube [0, size]^3 as 12 triangles (each square face split by one diagonal).
IndexedSoup cube_soup(double size = 1.0);
//! Bipyramid over a regular n-gon of radius 1 in z = 0 with apexes at z = +-height.
//! Apexes have valence n, equator vertices valence 4.
IndexedSoup bipyramid_soup(int n, double height = 1.0);

//! A regular triangle lattice: vertex (i, j) (0 <= i <= nx, 0 <= j <= ny) sits at
//! origin + i*du + j*dv, has index j*(nx+1) + i, and each cell is split by the diagonal
//! (i, j)-(i+1, j+1). Interior vertices have valence 6. Winding is ccw around du x dv.
IndexedSoup grid_soup(int nx, int ny, Vec3 origin = {0, 0, 0}, Vec3 du = {1, 0, 0},
                      Vec3 dv = {0, 1, 0});
//! Index of lattice vertex (i, j) in grid_soup(nx, ...).
inline std::uint32_t grid_index(int nx, int i, int j) {
  return static_cast<std::uint32_t>(j * (nx + 1) + i);
}
//! grid_soup over the xy lattice (x0 + i*h, y0 + j*h) with z = f(x, y).
IndexedSoup height_field_soup(int nx, int ny, double x0, double y0, double h,
                              const std::function<double(double, double)>& f);

//! Planar fan: centre (index 0) at (0, 0, apex_height), ring vertices 1..n at
//! (cos(2 pi i/n), sin(2 pi i/n), 0). The centre is interior with valence n, the ring is
//! the boundary.
IndexedSoup fan_soup(int n, double apex_height = 0.0);

//! Closed cylinder of radius r around the z axis from z = 0 to z = height, with n side
//! segments (one quad = two triangles each) and a centre vertex on each flat cap.
//! Index layout: 0..n-1 bottom rim, n..2n-1 top rim, 2n bottom centre, 2n+1 top centre.
IndexedSoup cylinder_soup(int n, double radius, double height);

//! Icosahedron subdivided `subdivisions` times (1-to-4) and projected onto the sphere of
//! radius `radius`. Valences 5 (twelve vertices) and 6.
IndexedSoup icosphere_soup(int subdivisions, double radius = 1.0);

//! Torus of major radius R and minor radius r around the z axis, n_major x n_minor quads
//! each split into two triangles (every vertex has valence 6).
IndexedSoup torus_soup(int n_major, int n_minor, double R, double r);

//! Moebius strip with n segments (non-orientable, one boundary loop).
IndexedSoup moebius_soup(int n);

//! Both soups in one, with bit-identical positions welded (as STL welding would).
IndexedSoup merged(const IndexedSoup& a, const IndexedSoup& b);

//! Moves every position: p -> p + t.
IndexedSoup translated(IndexedSoup soup, Vec3 t);

//! build_mesh(soup).mesh; asserts nothing (tests check the report where it matters).
Mesh to_mesh(const IndexedSoup& soup);

}  // namespace stlrefine::test
