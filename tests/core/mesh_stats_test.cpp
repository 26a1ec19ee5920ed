// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/mesh/mesh_stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/mesh/build_mesh.h"
#include "tests/core/test_util.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

TEST(MeshStats, CubeVolumeAreaGenus) {
  const MeshStats s = compute_stats(to_mesh(cube_soup(3.0)));
  EXPECT_EQ(s.vertices, 8u);
  EXPECT_EQ(s.edges, 18u);
  EXPECT_EQ(s.faces, 12u);
  EXPECT_EQ(s.boundary_edges, 0u);
  EXPECT_EQ(s.boundary_loops, 0u);
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.zero_area_faces, 0u);
  EXPECT_EQ(s.euler_characteristic, 2);
  EXPECT_TRUE(s.watertight);
  ASSERT_TRUE(s.genus.has_value());
  EXPECT_EQ(*s.genus, 0);
  EXPECT_NEAR(s.volume, 27.0, 1e-12);
  EXPECT_NEAR(s.area, 54.0, 1e-12);
  EXPECT_VEC_NEAR(s.bbox_min, (Vec3{0, 0, 0}), 0.0);
  EXPECT_VEC_NEAR(s.bbox_max, (Vec3{3, 3, 3}), 0.0);
}

TEST(MeshStats, TranslatedCubeKeepsVolume) {
  const MeshStats s = compute_stats(to_mesh(translated(cube_soup(2.0), {10, -20, 30})));
  EXPECT_NEAR(s.volume, 8.0, 1e-9);
  EXPECT_NEAR(s.area, 24.0, 1e-9);
  EXPECT_VEC_NEAR(s.bbox_min, (Vec3{10, -20, 30}), 0.0);
  EXPECT_VEC_NEAR(s.bbox_max, (Vec3{12, -18, 32}), 0.0);
}

TEST(MeshStats, TetrahedronVolume) {
  // Regular tetrahedron with circumradius 1: edge a = sqrt(8/3), V = a^3 / (6 sqrt 2).
  const double a = std::sqrt(8.0 / 3.0);
  const MeshStats s = compute_stats(to_mesh(tetrahedron_soup()));
  EXPECT_NEAR(s.volume, a * a * a / (6.0 * std::sqrt(2.0)), 1e-12);
  EXPECT_NEAR(s.area, std::sqrt(3.0) * a * a, 1e-12);
}

TEST(MeshStats, TorusHasGenusOne) {
  const MeshStats s = compute_stats(to_mesh(torus_soup(16, 8, 3, 1)));
  EXPECT_TRUE(s.watertight);
  EXPECT_EQ(s.euler_characteristic, 0);
  ASSERT_TRUE(s.genus.has_value());
  EXPECT_EQ(*s.genus, 1);
  EXPECT_EQ(s.components, 1u);
  EXPECT_GT(s.volume, 0);
  // Inscribed polyhedron: a bit under the smooth torus volume 2 pi^2 R r^2.
  EXPECT_LT(s.volume, 2 * std::numbers::pi * std::numbers::pi * 3);
  EXPECT_GT(s.volume, 0.8 * 2 * std::numbers::pi * std::numbers::pi * 3);
}

TEST(MeshStats, OpenGridIsNotWatertight) {
  const MeshStats s = compute_stats(to_mesh(grid_soup(4, 3)));
  EXPECT_FALSE(s.watertight);
  EXPECT_FALSE(s.genus.has_value());
  EXPECT_EQ(s.boundary_edges, 14u);
  EXPECT_EQ(s.boundary_loops, 1u);
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.euler_characteristic, 1);
  EXPECT_NEAR(s.area, 12.0, 1e-12);
}

TEST(MeshStats, CylinderWithoutCapsHasTwoBoundaryLoops) {
  IndexedSoup soup = cylinder_soup(12, 1, 2);
  // Keep the side triangles only (every 4 triangles: 2 side, 2 caps).
  IndexedSoup side;
  side.positions = soup.positions;
  for (std::size_t i = 0; i < soup.triangles.size(); i += 4) {
    side.triangles.push_back(soup.triangles[i]);
    side.triangles.push_back(soup.triangles[i + 1]);
  }
  const MeshStats s = compute_stats(to_mesh(side));
  EXPECT_EQ(s.boundary_loops, 2u);
  EXPECT_EQ(s.boundary_edges, 24u);
  EXPECT_EQ(s.vertices, 24u);  // the cap centres are unreferenced and dropped
  EXPECT_EQ(s.euler_characteristic, 0);
}

TEST(MeshStats, TwoComponentsAddGenus) {
  const IndexedSoup soup =
      merged(torus_soup(12, 6, 3, 1), translated(torus_soup(12, 6, 3, 1), {20, 0, 0}));
  const MeshStats s = compute_stats(to_mesh(soup));
  EXPECT_EQ(s.components, 2u);
  ASSERT_TRUE(s.genus.has_value());
  EXPECT_EQ(*s.genus, 2);
  const MeshStats t =
      compute_stats(to_mesh(merged(cube_soup(1), translated(cube_soup(1), {5, 0, 0}))));
  EXPECT_EQ(t.components, 2u);
  EXPECT_EQ(t.euler_characteristic, 4);
  ASSERT_TRUE(t.genus.has_value());
  EXPECT_EQ(*t.genus, 0);
  EXPECT_NEAR(t.volume, 2.0, 1e-12);
}

TEST(MeshStats, InwardCubeHasNegativeVolume) {
  IndexedSoup soup = cube_soup(1.0);
  for (auto& t : soup.triangles) std::swap(t[1], t[2]);
  const MeshStats s = compute_stats(to_mesh(soup));
  EXPECT_NEAR(s.volume, -1.0, 1e-12);
}

}  // namespace
}  // namespace stlrefine::test
