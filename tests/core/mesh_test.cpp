// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/mesh/mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "core/mesh/build_mesh.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

struct Factory {
  std::string name;
  std::function<IndexedSoup()> make;
  long long euler;  // V - E + F of the built mesh
};

std::vector<Factory> factories() {
  return {
      {"tetrahedron", [] { return tetrahedron_soup(); }, 2},
      {"octahedron", [] { return octahedron_soup(); }, 2},
      {"icosahedron", [] { return icosahedron_soup(); }, 2},
      {"cube", [] { return cube_soup(2.0); }, 2},
      {"bipyramid5", [] { return bipyramid_soup(5, 1.2); }, 2},
      {"bipyramid7", [] { return bipyramid_soup(7, 0.8); }, 2},
      {"grid", [] { return grid_soup(5, 4); }, 1},
      {"skew_grid",
       [] {
         return grid_soup(3, 6, {1, 2, 3}, {1, 0.5, 0}, {0.25, 1, 0.5});
       },
       1},
      {"fan3", [] { return fan_soup(3, 0.2); }, 1},
      {"fan7", [] { return fan_soup(7); }, 1},
      {"cylinder", [] { return cylinder_soup(24, 10, 20); }, 2},
      {"icosphere", [] { return icosphere_soup(2); }, 2},
      {"torus", [] { return torus_soup(12, 8, 3, 1); }, 0},
      {"height_field",
       [] {
         return height_field_soup(6, 6, -1, -1, 1.0 / 3, [](double x, double y) {
           return x * x - x * y + 0.5 * y * y * y;
         });
       },
       1},
  };
}

class FactoryTest : public ::testing::TestWithParam<Factory> {};

TEST_P(FactoryTest, BuildsValidMeshWithoutRepairs) {
  const IndexedSoup soup = GetParam().make();
  const IngestResult r = build_mesh(soup);
  const Mesh& m = r.mesh;
  EXPECT_EQ(m.check_invariants(), "");
  EXPECT_EQ(m.num_faces(), soup.triangles.size());
  EXPECT_EQ(m.num_vertices(), soup.positions.size());
  EXPECT_EQ(r.report.faces_reoriented, 0u);
  EXPECT_EQ(r.report.inconsistent_edges, 0u);
  EXPECT_EQ(r.report.non_manifold_edges, 0u);
  EXPECT_EQ(r.report.non_manifold_vertices, 0u);
  EXPECT_EQ(r.report.index_degenerate_removed, 0u);
  EXPECT_EQ(r.report.isolated_vertices_removed, 0u);
  const long long chi = static_cast<long long>(m.num_vertices()) -
                        static_cast<long long>(m.num_edges()) +
                        static_cast<long long>(m.num_faces());
  EXPECT_EQ(chi, GetParam().euler);
  // The factories wind every facet consistently, so ingest must keep the exact oriented
  // triangle set (and bit-identical positions).
  EXPECT_EQ(triangle_set(m, false), triangle_set(soup.positions, soup.triangles, false));
}

TEST_P(FactoryTest, HalfedgeIsThreeFacePlusCorner) {
  const Mesh m = to_mesh(GetParam().make());
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto fv = m.face_vertices(FaceId(f));
    for (int k = 0; k < 3; ++k) {
      const HalfedgeId h = Mesh::halfedge(FaceId(f), k);
      ASSERT_EQ(h.idx, 3 * f + k);
      EXPECT_EQ(Mesh::face(h), FaceId(f));
      EXPECT_EQ(m.from(h), fv[k]);
      EXPECT_EQ(m.to(h), fv[(k + 1) % 3]);
      EXPECT_EQ(m.opposite(h), fv[(k + 2) % 3]);
      EXPECT_EQ(Mesh::next(Mesh::next(Mesh::next(h))), h);
      EXPECT_EQ(Mesh::prev(Mesh::next(h)), h);
      EXPECT_EQ(m.to(h), m.from(Mesh::next(h)));
    }
  }
}

TEST_P(FactoryTest, TwinsAreSymmetricAndOpposite) {
  const Mesh m = to_mesh(GetParam().make());
  for (std::uint32_t i = 0; i < m.num_halfedges(); ++i) {
    const HalfedgeId h(i);
    const HalfedgeId t = m.twin(h);
    if (!t.valid()) {
      EXPECT_TRUE(m.is_boundary(h));
      continue;
    }
    EXPECT_FALSE(m.is_boundary(h));
    EXPECT_EQ(m.twin(t), h);
    EXPECT_EQ(m.from(t), m.to(h));
    EXPECT_EQ(m.to(t), m.from(h));
    EXPECT_EQ(m.edge(t), m.edge(h));
    EXPECT_NE(Mesh::face(t), Mesh::face(h));
  }
}

TEST_P(FactoryTest, EdgesHaveOneIdForBothHalves) {
  const Mesh m = to_mesh(GetParam().make());
  std::size_t boundary_halfedges = 0;
  for (std::uint32_t i = 0; i < m.num_halfedges(); ++i)
    boundary_halfedges += m.is_boundary(HalfedgeId(i)) ? 1 : 0;
  EXPECT_EQ(2 * m.num_edges(), m.num_halfedges() + boundary_halfedges);
  std::vector<int> uses(m.num_edges(), 0);
  for (std::uint32_t i = 0; i < m.num_halfedges(); ++i) ++uses[m.edge(HalfedgeId(i)).idx];
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    const HalfedgeId h = m.halfedge(EdgeId(e));
    EXPECT_EQ(m.edge(h), EdgeId(e));
    EXPECT_EQ(uses[e], m.is_boundary(EdgeId(e)) ? 1 : 2) << "edge " << e;
    EXPECT_EQ(m.is_boundary(EdgeId(e)), m.is_boundary(h));
  }
}

TEST_P(FactoryTest, OutgoingWalkVisitsEveryCornerOnce) {
  const Mesh m = to_mesh(GetParam().make());
  std::vector<int> corners(m.num_vertices(), 0);
  for (VertexId v : m.corner_vertices()) ++corners[v.idx];
  for (std::uint32_t i = 0; i < m.num_vertices(); ++i) {
    const VertexId v(i);
    std::set<std::uint32_t> faces;
    int visits = 0;
    for_each_outgoing(m, v, [&](HalfedgeId h) {
      EXPECT_EQ(m.from(h), v);
      faces.insert(Mesh::face(h).idx);
      ++visits;
    });
    EXPECT_EQ(visits, corners[i]) << "vertex " << i;
    EXPECT_EQ(faces.size(), static_cast<std::size_t>(corners[i]));
    EXPECT_EQ(m.valence(v), corners[i] + (m.is_boundary(v) ? 1 : 0)) << "vertex " << i;
    // The stored half-edge is the most clockwise: it has no twin exactly on a boundary.
    const HalfedgeId first = m.halfedge(v);
    ASSERT_TRUE(first.valid());
    EXPECT_EQ(m.from(first), v);
    EXPECT_EQ(m.is_boundary(first), m.is_boundary(v));
  }
}

TEST_P(FactoryTest, ClockwiseRotationUndoesCounterClockwise) {
  const Mesh m = to_mesh(GetParam().make());
  for (std::uint32_t i = 0; i < m.num_halfedges(); ++i) {
    const HalfedgeId h(i);
    const HalfedgeId c = m.ccw_rotated(h);
    if (!c.valid()) continue;
    EXPECT_EQ(m.from(c), m.from(h));
    EXPECT_EQ(m.cw_rotated(c), h);
  }
}

INSTANTIATE_TEST_SUITE_P(Shapes, FactoryTest, ::testing::ValuesIn(factories()),
                         [](const auto& info) { return info.param.name; });

TEST(Mesh, PlatonicValences) {
  for (const auto& [soup, valence] : std::vector<std::pair<IndexedSoup, int>>{
           {tetrahedron_soup(), 3}, {octahedron_soup(), 4}, {icosahedron_soup(), 5}}) {
    const Mesh m = to_mesh(soup);
    for (std::uint32_t v = 0; v < m.num_vertices(); ++v) {
      EXPECT_EQ(m.valence(VertexId(v)), valence);
      EXPECT_FALSE(m.is_boundary(VertexId(v)));
    }
  }
}

TEST(Mesh, BipyramidApexValence) {
  const IndexedSoup soup = bipyramid_soup(7);
  const Mesh m = to_mesh(soup);
  const VertexId top = find_vertex(m, soup.positions[7]);
  const VertexId bottom = find_vertex(m, soup.positions[8]);
  EXPECT_EQ(m.valence(top), 7);
  EXPECT_EQ(m.valence(bottom), 7);
  for (int i = 0; i < 7; ++i) EXPECT_EQ(m.valence(find_vertex(m, soup.positions[i])), 4);
}

TEST(Mesh, GridValencesAndBoundary) {
  const int nx = 5, ny = 4;
  const IndexedSoup soup = grid_soup(nx, ny);
  const Mesh m = to_mesh(soup);
  std::size_t boundary_vertices = 0;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      const VertexId v = find_vertex(m, soup.positions[grid_index(nx, i, j)]);
      ASSERT_TRUE(v.valid());
      const bool on_border = i == 0 || j == 0 || i == nx || j == ny;
      EXPECT_EQ(m.is_boundary(v), on_border) << i << "," << j;
      boundary_vertices += m.is_boundary(v) ? 1 : 0;
      int expected = 6;
      if ((i == 0 && j == 0) || (i == nx && j == ny)) {
        expected = 3;  // the diagonal runs into these corners
      } else if ((i == nx && j == 0) || (i == 0 && j == ny)) {
        expected = 2;
      } else if (on_border) {
        expected = 4;
      }
      EXPECT_EQ(m.valence(v), expected) << i << "," << j;
    }
  }
  EXPECT_EQ(boundary_vertices, static_cast<std::size_t>(2 * (nx + ny)));
  std::size_t boundary_edges = 0;
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) boundary_edges += m.is_boundary(EdgeId(e));
  EXPECT_EQ(boundary_edges, static_cast<std::size_t>(2 * (nx + ny)));
}

TEST(Mesh, InteriorRingIsCounterClockwise) {
  const int nx = 4, ny = 4;
  const IndexedSoup soup = grid_soup(nx, ny);
  const Mesh m = to_mesh(soup);
  const VertexId v = find_vertex(m, soup.positions[grid_index(nx, 2, 2)]);
  const auto outs = outgoing(m, v);
  ASSERT_EQ(outs.size(), 6u);
  // Lattice neighbours of (2,2) with the (i,j)-(i+1,j+1) diagonal.
  std::set<std::pair<double, double>> expected = {{3, 2}, {3, 3}, {2, 3}, {1, 2}, {1, 1}, {2, 1}};
  std::set<std::pair<double, double>> got;
  const Vec3 c = m.position(v);
  for (std::size_t k = 0; k < outs.size(); ++k) {
    const Vec3 a = m.position(m.to(outs[k])) - c;
    const Vec3 b = m.position(m.to(outs[(k + 1) % outs.size()])) - c;
    got.insert({a.x, a.y});
    // Consecutive spokes turn left (ccw seen from +z) by less than 180 degrees.
    EXPECT_GT(cross(a, b).z, 0) << "spokes " << k << " and " << k + 1;
    // Consecutive spokes bound one face: h's face has to(h) and the next spoke's end.
    EXPECT_EQ(m.opposite(outs[k]), m.to(outs[(k + 1) % outs.size()]));
  }
  std::set<std::pair<double, double>> shifted;
  for (auto [x, y] : got) shifted.insert({x + 2, y + 2});
  EXPECT_EQ(shifted, expected);
}

TEST(Mesh, BoundaryRingStartsAndEndsOnBoundaryEdges) {
  const int nx = 4, ny = 3;
  const IndexedSoup soup = grid_soup(nx, ny);
  const Mesh m = to_mesh(soup);
  const VertexId v = find_vertex(m, soup.positions[grid_index(nx, 2, 0)]);  // bottom side
  const auto outs = outgoing(m, v);
  ASSERT_EQ(outs.size(), 3u);  // 3 faces, valence 4
  EXPECT_TRUE(m.is_boundary(outs.front()));
  EXPECT_FALSE(m.is_boundary(outs.back()));
  EXPECT_TRUE(m.is_boundary(Mesh::prev(outs.back())));  // the closing incoming edge
  // Most clockwise first: the walk goes from +x (3,0) round to -x (1,0).
  EXPECT_EQ(m.position(m.to(outs.front())), soup.positions[grid_index(nx, 3, 0)]);
  EXPECT_EQ(m.position(m.opposite(outs.back())), soup.positions[grid_index(nx, 1, 0)]);
  const auto r = ring(m, v);
  ASSERT_EQ(r.size(), 4u);
  EXPECT_EQ(static_cast<int>(r.size()), m.valence(v));
  EXPECT_FALSE(m.ccw_rotated(outs.back()).valid());
  EXPECT_FALSE(m.cw_rotated(outs.front()).valid());
}

TEST(Mesh, CubeFaceNormalsPointOutward) {
  const Mesh m = to_mesh(cube_soup(2.0));
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto [a, b, c] = m.face_vertices(FaceId(f));
    const Vec3 centroid = (m.position(a) + m.position(b) + m.position(c)) * (1.0 / 3.0);
    const Vec3 n = m.face_normal(FaceId(f));
    EXPECT_GT(dot(n, centroid - Vec3{1, 1, 1}), 0);
    // Axis-aligned: two coordinates are zero.
    const int zeros = (n.x == 0) + (n.y == 0) + (n.z == 0);
    EXPECT_EQ(zeros, 2);
  }
}

TEST(Mesh, FromPartsSingleTriangle) {
  const Mesh m =
      Mesh::from_parts({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {VertexId(0), VertexId(1), VertexId(2)},
                       {HalfedgeId(), HalfedgeId(), HalfedgeId()});
  EXPECT_EQ(m.check_invariants(), "");
  EXPECT_EQ(m.num_edges(), 3u);
  for (std::uint32_t v = 0; v < 3; ++v) {
    EXPECT_TRUE(m.is_boundary(VertexId(v)));
    EXPECT_EQ(m.valence(VertexId(v)), 2);
    EXPECT_EQ(m.halfedge(VertexId(v)), HalfedgeId(v));
  }
  EXPECT_GT(m.face_normal(FaceId(0)).z, 0);
}

TEST(Mesh, FromPartsStoresMostClockwiseHalfedge) {
  // Quad 0-1-2-3 split by diagonal 0-2: faces (0,1,2) and (0,2,3); half-edges 2 (2->0) and
  // 3 (0->2) are twins.
  const HalfedgeId none;
  const Mesh m = Mesh::from_parts(
      {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}},
      {VertexId(0), VertexId(1), VertexId(2), VertexId(0), VertexId(2), VertexId(3)},
      {none, none, HalfedgeId(3), HalfedgeId(2), none, none});
  EXPECT_EQ(m.check_invariants(), "");
  EXPECT_EQ(m.num_edges(), 5u);
  EXPECT_EQ(m.halfedge(VertexId(0)), HalfedgeId(0));  // 0->1 precedes 0->2 going ccw
  EXPECT_EQ(m.halfedge(VertexId(2)), HalfedgeId(4));  // 2->3 precedes 2->0 going ccw
  EXPECT_EQ(m.valence(VertexId(0)), 3);
  EXPECT_EQ(m.valence(VertexId(1)), 2);
  EXPECT_EQ(m.ccw_rotated(HalfedgeId(0)), HalfedgeId(3));
  EXPECT_EQ(m.edge(HalfedgeId(2)), m.edge(HalfedgeId(3)));
  EXPECT_FALSE(m.is_boundary(m.edge(HalfedgeId(2))));
}

TEST(Mesh, FromPartsKeepsIsolatedVertexWithoutHalfedge) {
  const Mesh m = Mesh::from_parts({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {5, 5, 5}},
                                  {VertexId(0), VertexId(1), VertexId(2)},
                                  {HalfedgeId(), HalfedgeId(), HalfedgeId()});
  EXPECT_TRUE(m.is_isolated(VertexId(3)));
  EXPECT_FALSE(m.is_isolated(VertexId(0)));
  int visits = 0;
  for_each_outgoing(m, VertexId(3), [&](HalfedgeId) { ++visits; });
  EXPECT_EQ(visits, 0);
}

}  // namespace
}  // namespace stlrefine::test
