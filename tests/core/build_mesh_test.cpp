// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/mesh/build_mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "core/error.h"
#include "core/mesh/mesh_stats.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

// Every position the mesh uses must be one of the input positions, bit for bit.
void expect_positions_from(const Mesh& m, const IndexedSoup& soup) {
  std::set<std::tuple<double, double, double>> in;
  for (const Vec3& p : soup.positions) in.insert({p.x, p.y, p.z});
  for (const Vec3& p : m.positions()) EXPECT_TRUE(in.count({p.x, p.y, p.z})) << str(p);
}

// Undirected edges used by exactly two facets that run along them in the same direction.
std::size_t count_inconsistent_edges(const IndexedSoup& soup) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<bool>> uses;  // forward?
  for (const auto& t : soup.triangles)
    for (int k = 0; k < 3; ++k) {
      const auto a = t[k], b = t[(k + 1) % 3];
      uses[std::minmax(a, b)].push_back(a < b);
    }
  std::size_t n = 0;
  for (const auto& [e, dirs] : uses) n += dirs.size() == 2 && dirs[0] == dirs[1];
  return n;
}

bool all_twinned(const Mesh& m) {
  for (std::uint32_t h = 0; h < m.num_halfedges(); ++h)
    if (m.is_boundary(HalfedgeId(h))) return false;
  return true;
}

void expect_single_flip_repaired(std::size_t bad);
void expect_majority_wins(std::size_t first);

IndexedSoup flipped(IndexedSoup soup, const std::vector<std::size_t>& faces) {
  for (std::size_t f : faces) std::swap(soup.triangles[f][1], soup.triangles[f][2]);
  return soup;
}

TEST(BuildMesh, ReportsInputCounts) {
  const IndexedSoup soup = icosahedron_soup();
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.report.input_triangles, 20u);
  EXPECT_EQ(r.report.input_vertices, 12u);
  EXPECT_EQ(r.report.zero_area_faces, 0u);
  EXPECT_EQ(r.report.non_orientable_cuts, 0u);
  EXPECT_EQ(r.report.vertices_duplicated, 0u);
  expect_positions_from(r.mesh, soup);
}

TEST(BuildMesh, FlippedFacetIsReorientedAndCounted) {
  for (std::size_t bad : {0u, 5u, 11u}) {  // 0: whichever facet a walk may start from
    SCOPED_TRACE("flipped facet " + std::to_string(bad));
    expect_single_flip_repaired(bad);
  }
}

void expect_single_flip_repaired(std::size_t bad) {
  const IndexedSoup good = cube_soup(2.0);
  const IndexedSoup soup = flipped(good, {bad});
  ASSERT_EQ(count_inconsistent_edges(soup), 3u);
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(r.report.faces_reoriented, 1u);
  EXPECT_EQ(r.report.inconsistent_edges, 3u);
  EXPECT_EQ(r.report.non_manifold_edges, 0u);
  EXPECT_TRUE(all_twinned(r.mesh));
  // The 11 agreeing facets win: the result is the outward cube.
  EXPECT_EQ(triangle_set(r.mesh, false), triangle_set(good.positions, good.triangles, false));
  EXPECT_DOUBLE_EQ(signed_volume(r.mesh), 8.0);
}

TEST(BuildMesh, MajorityOrientationWins) {
  // 15 of 20 facets inward: the 5 outward ones are the minority and get flipped, whether
  // or not facet 0 is among them.
  for (std::size_t first : {0u, 5u}) {
    SCOPED_TRACE("inward facets " + std::to_string(first) + ".." + std::to_string(first + 14));
    expect_majority_wins(first);
  }
}

void expect_majority_wins(std::size_t first) {
  const IndexedSoup good = icosahedron_soup();
  std::vector<std::size_t> many;
  for (std::size_t f = first; f < first + 15; ++f) many.push_back(f);
  const IndexedSoup soup = flipped(good, many);
  std::vector<std::size_t> all;
  for (std::size_t f = 0; f < 20; ++f) all.push_back(f);
  const IndexedSoup inward = flipped(good, all);
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(r.report.faces_reoriented, 5u);
  EXPECT_EQ(r.report.inconsistent_edges, count_inconsistent_edges(soup));
  EXPECT_TRUE(all_twinned(r.mesh));
  EXPECT_EQ(triangle_set(r.mesh, false), triangle_set(inward.positions, inward.triangles, false));
  EXPECT_LT(signed_volume(r.mesh), 0);
}

TEST(BuildMesh, FinOnCubeEdgeIsCutAndReported) {
  IndexedSoup soup = cube_soup(1.0);
  // A third facet on the cube edge (0,0,1)-(1,0,1) (vertices 4 and 5).
  soup.positions.push_back({0.5, -0.5, 1.5});
  soup.triangles.push_back({4, 5, 8});
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(r.report.non_manifold_edges, 1u);
  EXPECT_EQ(r.report.index_degenerate_removed, 0u);
  ASSERT_EQ(r.mesh.num_faces(), 13u);  // no triangle lost
  EXPECT_EQ(triangle_set(r.mesh, true), triangle_set(soup.positions, soup.triangles, true));
  expect_positions_from(r.mesh, soup);
  // The cut leaves boundary edges; the mesh is no longer closed.
  EXPECT_FALSE(compute_stats(r.mesh).watertight);
}

TEST(BuildMesh, TwoCubesSharingAnEdge) {
  const IndexedSoup a = cube_soup(1.0);
  const IndexedSoup b = translated(cube_soup(1.0), {1, 1, 0});
  const IndexedSoup soup = merged(a, b);
  ASSERT_EQ(soup.positions.size(), 14u);  // the shared edge's two corners are welded
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(r.report.non_manifold_edges, 1u);
  ASSERT_EQ(r.mesh.num_faces(), 24u);
  EXPECT_EQ(triangle_set(r.mesh, true), triangle_set(soup.positions, soup.triangles, true));
  EXPECT_EQ(r.report.faces_reoriented, 0u);
  // Both cubes keep their outward orientation.
  EXPECT_NEAR(signed_volume(r.mesh), 2.0, 1e-12);
}

TEST(BuildMesh, PinchVertexIsSplitIntoCopies) {
  const IndexedSoup a = tetrahedron_soup();
  // The second tetrahedron touches the first only at a's vertex 0 (b's vertex 3).
  const IndexedSoup b = translated(tetrahedron_soup(), a.positions[0] - a.positions[3]);
  const IndexedSoup soup = merged(a, b);
  ASSERT_EQ(soup.positions.size(), 7u);
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(r.report.non_manifold_vertices, 1u);
  EXPECT_EQ(r.report.vertices_duplicated, 1u);
  EXPECT_EQ(r.report.non_manifold_edges, 0u);
  EXPECT_EQ(r.mesh.num_vertices(), 8u);
  EXPECT_EQ(r.mesh.num_faces(), 8u);
  EXPECT_EQ(triangle_set(r.mesh, false), triangle_set(soup.positions, soup.triangles, false));
  // Two copies sit at the pinch position, each a closed fan of valence 3.
  int copies = 0;
  for (std::uint32_t v = 0; v < r.mesh.num_vertices(); ++v) {
    if (r.mesh.position(VertexId(v)) != a.positions[0]) continue;
    ++copies;
    EXPECT_EQ(r.mesh.valence(VertexId(v)), 3);
    EXPECT_FALSE(r.mesh.is_boundary(VertexId(v)));
  }
  EXPECT_EQ(copies, 2);
  const MeshStats s = compute_stats(r.mesh);
  EXPECT_TRUE(s.watertight);
  EXPECT_EQ(s.components, 2u);
}

TEST(BuildMesh, BowtieVertexIsSplit) {
  IndexedSoup soup;
  soup.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0}, {-1, -1, 0}};
  soup.triangles = {{0, 1, 2}, {0, 3, 4}};
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(r.report.non_manifold_vertices, 1u);
  EXPECT_EQ(r.report.vertices_duplicated, 1u);
  EXPECT_EQ(r.mesh.num_vertices(), 6u);
  EXPECT_EQ(triangle_set(r.mesh, false), triangle_set(soup.positions, soup.triangles, false));
}

TEST(BuildMesh, IndexDegenerateFacetsAreRemovedAndCounted) {
  IndexedSoup soup = cube_soup(1.0);
  soup.triangles.push_back({0, 0, 1});
  soup.triangles.push_back({2, 2, 2});
  soup.triangles.push_back({3, 5, 3});
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(r.report.input_triangles, 15u);
  EXPECT_EQ(r.report.index_degenerate_removed, 3u);
  EXPECT_EQ(r.mesh.num_faces(), 12u);
  EXPECT_EQ(r.mesh.num_vertices(), 8u);
  EXPECT_TRUE(all_twinned(r.mesh));
}

TEST(BuildMesh, VertexOnlyUsedByDegenerateFacetIsDropped) {
  IndexedSoup soup = cube_soup(1.0);
  soup.positions.push_back({7, 7, 7});
  soup.triangles.push_back({8, 8, 1});
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.report.index_degenerate_removed, 1u);
  EXPECT_EQ(r.mesh.num_vertices(), 8u);
  for (std::uint32_t v = 0; v < r.mesh.num_vertices(); ++v)
    EXPECT_FALSE(r.mesh.is_isolated(VertexId(v)));
}

TEST(BuildMesh, IsolatedVerticesAreDropped) {
  IndexedSoup soup = cube_soup(1.0);
  soup.positions.insert(soup.positions.begin(), Vec3{9, 9, 9});  // shifts every index
  for (auto& t : soup.triangles)
    for (auto& i : t) ++i;
  soup.positions.push_back({-3, 0, 0});
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(r.report.input_vertices, 10u);
  EXPECT_EQ(r.report.isolated_vertices_removed, 2u);
  EXPECT_EQ(r.mesh.num_vertices(), 8u);
  for (std::uint32_t v = 0; v < r.mesh.num_vertices(); ++v)
    EXPECT_FALSE(r.mesh.is_isolated(VertexId(v)));
  EXPECT_EQ(triangle_set(r.mesh, false), triangle_set(soup.positions, soup.triangles, false));
}

TEST(BuildMesh, ZeroAreaFacetsAreKeptAndCounted) {
  // Square with a T-junction at M on the bottom edge, closed by the sliver (M, A, B).
  IndexedSoup soup;
  soup.positions = {{0, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}, {1, 0, 0}};
  const std::uint32_t A = 0, B = 1, C = 2, D = 3, M = 4;
  soup.triangles = {{A, M, D}, {M, B, C}, {M, C, D}, {M, A, B}};
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(r.report.zero_area_faces, 1u);
  EXPECT_EQ(r.report.index_degenerate_removed, 0u);
  EXPECT_EQ(r.report.faces_reoriented, 0u);
  EXPECT_EQ(r.mesh.num_faces(), 4u);
}

TEST(BuildMesh, EmptyInputThrowsNotTriangleMesh) {
  try {
    build_mesh(IndexedSoup{});
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::NotTriangleMesh);
  }
}

TEST(BuildMesh, OnlyDegenerateFacetsThrowsNotTriangleMesh) {
  IndexedSoup soup;
  soup.positions = {{0, 0, 0}, {1, 0, 0}};
  soup.triangles = {{0, 0, 1}, {1, 1, 1}};
  try {
    build_mesh(soup);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::NotTriangleMesh);
  }
}

TEST(BuildMesh, MoebiusStripIsCutToBeOrientable) {
  const IndexedSoup soup = moebius_soup(12);
  const IngestResult r = build_mesh(soup);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_GE(r.report.non_orientable_cuts, 1u);
  EXPECT_EQ(r.mesh.num_faces(), soup.triangles.size());
  EXPECT_EQ(triangle_set(r.mesh, true), triangle_set(soup.positions, soup.triangles, true));
}

TEST(BuildMesh, PositionsAreCopiedBitIdentically) {
  IndexedSoup soup = icosphere_soup(1, 3.0);
  soup = translated(soup, {0.1, 1e-7, -12345.678});
  const IngestResult r = build_mesh(soup);
  ASSERT_EQ(r.mesh.num_vertices(), soup.positions.size());
  expect_positions_from(r.mesh, soup);
}

}  // namespace
}  // namespace stlrefine::test
