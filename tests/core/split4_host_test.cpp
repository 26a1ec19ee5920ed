// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/schemes/split4_host.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <functional>
#include <set>
#include <utility>

#include "core/mesh/build_mesh.h"
#include "core/mesh/mesh_stats.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/reference_split4.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

// Edge midpoints, optionally with one edge point moved by `push`.
class MidpointStencil final : public Split4Stencil {
 public:
  explicit MidpointStencil(std::function<Vec3(const Mesh&, EdgeId)> push = {})
      : push_(std::move(push)) {}
  void edge_points(const Level& coarse, std::span<Vec3> out) const override {
    const Mesh& m = coarse.mesh;
    for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
      const HalfedgeId h = m.halfedge(EdgeId(e));
      out[e] = (m.position(m.from(h)) + m.position(m.to(h))) * 0.5;
      if (push_) out[e] += push_(m, EdgeId(e));
    }
  }
  bool interpolating() const override { return true; }

 private:
  std::function<Vec3(const Mesh&, EdgeId)> push_;
};

// Same cyclic vertex order (rotation allowed).
bool same_cycle(std::array<VertexId, 3> a, std::array<std::uint32_t, 3> b) {
  for (int r = 0; r < 3; ++r)
    if (a[0].idx == b[r] && a[1].idx == b[(r + 1) % 3] && a[2].idx == b[(r + 2) % 3]) return true;
  return false;
}

void expect_split4_topology(const Level& coarse, const Level& fine) {
  const Mesh& c = coarse.mesh;
  const Mesh& m = fine.mesh;
  EXPECT_EQ(m.check_invariants(), "");
  ASSERT_EQ(m.num_faces(), 4 * c.num_faces());
  ASSERT_EQ(m.num_vertices(), c.num_vertices() + c.num_edges());
  std::size_t boundary = 0;
  for (std::uint32_t e = 0; e < c.num_edges(); ++e) boundary += c.is_boundary(EdgeId(e));
  EXPECT_EQ(m.num_edges(), 2 * c.num_edges() + 3 * c.num_faces());
  const auto faces = reference_split4_faces(c);
  for (std::uint32_t f = 0; f < m.num_faces(); ++f)
    EXPECT_TRUE(same_cycle(m.face_vertices(FaceId(f)), faces[f])) << "fine face " << f;
  for (std::uint32_t v = 0; v < c.num_vertices(); ++v)
    EXPECT_EQ(m.valence(VertexId(v)), c.valence(VertexId(v))) << "old vertex " << v;
  for (std::uint32_t e = 0; e < c.num_edges(); ++e) {
    const VertexId nv = edge_vertex(c, EdgeId(e));
    EXPECT_EQ(m.valence(nv), c.is_boundary(EdgeId(e)) ? 4 : 6) << "edge vertex " << e;
    EXPECT_EQ(m.is_boundary(nv), c.is_boundary(EdgeId(e)));
  }
  std::size_t fine_boundary = 0;
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) fine_boundary += m.is_boundary(EdgeId(e));
  EXPECT_EQ(fine_boundary, 2 * boundary);
}

std::vector<Level> sample_levels() {
  std::vector<Level> out;
  out.push_back(make_level(to_mesh(icosahedron_soup())));
  out.push_back(make_level(to_mesh(cube_soup(1.0))));
  out.push_back(make_level(to_mesh(grid_soup(4, 3))));
  out.push_back(make_level(to_mesh(fan_soup(5))));
  out.push_back(make_level(to_mesh(cylinder_soup(8, 1, 3))));
  out.push_back(make_level(to_mesh(torus_soup(8, 6, 3, 1))));
  return out;
}

TEST(Split4Host, NewVertexIdsAndFaceLayout) {
  const MidpointStencil stencil;
  for (const Level& coarse : sample_levels()) {
    StepStats stats;
    const Level fine = split4(coarse, stencil, stats);
    expect_split4_topology(coarse, fine);
    const Mesh& c = coarse.mesh;
    for (std::uint32_t v = 0; v < c.num_vertices(); ++v)
      EXPECT_EQ(fine.mesh.position(VertexId(v)), c.position(VertexId(v)));
    for (std::uint32_t e = 0; e < c.num_edges(); ++e) {
      const HalfedgeId h = c.halfedge(EdgeId(e));
      EXPECT_EQ(fine.mesh.position(edge_vertex(c, EdgeId(e))),
                (c.position(c.from(h)) + c.position(c.to(h))) * 0.5);
    }
    EXPECT_EQ(stats.fold_fallbacks, 0u);
  }
}

TEST(Split4Host, SchemesUseTheSameTopology) {
  for (const char* name : {"loop", "butterfly"}) {
    for (const Level& coarse : sample_levels()) {
      const Level fine = refine_level(name, coarse);
      expect_split4_topology(coarse, fine);
    }
  }
}

TEST(Split4Host, HalvesOfSharpEdgesStaySharp) {
  const MidpointStencil stencil;
  for (const Level& coarse : sample_levels()) {
    StepStats stats;
    const Level fine = split4(coarse, stencil, stats);
    const Mesh& c = coarse.mesh;
    const Mesh& m = fine.mesh;
    std::set<std::pair<std::uint32_t, std::uint32_t>> expected;
    for (std::uint32_t e = 0; e < c.num_edges(); ++e) {
      if (!coarse.features.is_sharp(EdgeId(e))) continue;
      const HalfedgeId h = c.halfedge(EdgeId(e));
      const auto mid = edge_vertex(c, EdgeId(e)).idx;
      expected.insert(std::minmax(c.from(h).idx, mid));
      expected.insert(std::minmax(c.to(h).idx, mid));
    }
    std::size_t sharp = 0;
    for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
      const HalfedgeId h = m.halfedge(EdgeId(e));
      const std::pair<std::uint32_t, std::uint32_t> key = std::minmax(m.from(h).idx, m.to(h).idx);
      EXPECT_EQ(fine.features.is_sharp(EdgeId(e)), expected.count(key) == 1)
          << key.first << "-" << key.second;
      sharp += fine.features.is_sharp(EdgeId(e));
    }
    EXPECT_EQ(sharp, 2 * coarse.features.num_sharp_edges());
    // Old vertices keep their kind; new ones are crease vertices on sharp edges.
    for (std::uint32_t v = 0; v < c.num_vertices(); ++v)
      EXPECT_EQ(fine.features.kind(VertexId(v)), coarse.features.kind(VertexId(v)));
    for (std::uint32_t e = 0; e < c.num_edges(); ++e)
      EXPECT_EQ(fine.features.kind(edge_vertex(c, EdgeId(e))),
                coarse.features.is_sharp(EdgeId(e)) ? VertexKind::Crease : VertexKind::Smooth);
  }
}

TEST(Split4Host, SharpFlagsAreCarriedNotRedetected) {
  // A flat grid with one tagged edge: the fine level must keep the tag although the
  // dihedral angle there is 0.
  const int nx = 4;
  const IndexedSoup soup = grid_soup(nx, 4);
  const Mesh m = to_mesh(soup);
  const VertexId a = find_vertex(m, soup.positions[grid_index(nx, 1, 2)]);
  const VertexId b = find_vertex(m, soup.positions[grid_index(nx, 2, 2)]);
  const VertexId c = find_vertex(m, soup.positions[grid_index(nx, 3, 2)]);
  const Level coarse = make_level_with_sharp(m, {{a, b}, {b, c}});
  StepStats stats;
  const Level fine = split4(coarse, MidpointStencil(), stats);
  EXPECT_EQ(fine.features.num_sharp_edges(), 2 * coarse.features.num_sharp_edges());
  EXPECT_EQ(fine.features.kind(b), VertexKind::Crease);
  EXPECT_EQ(fine.features.kind(a), VertexKind::Dart);
}

TEST(Split4Host, FoldGuardPullsBackAFoldingEdgePoint) {
  // Push one interior edge point of a flat grid far sideways, so that a child triangle
  // turns over (180 degrees from its parent).
  const int nx = 4;
  const IndexedSoup soup = grid_soup(nx, 4);
  const Mesh m = to_mesh(soup);
  const EdgeId target = find_edge(m, find_vertex(m, soup.positions[grid_index(nx, 2, 2)]),
                                  find_vertex(m, soup.positions[grid_index(nx, 3, 2)]));
  ASSERT_TRUE(target.valid());
  const Vec3 push{0, 3, 0};
  const MidpointStencil folding([&](const Mesh&, EdgeId e) { return e == target ? push : Vec3{}; });
  const Level coarse = make_level(m);
  // The raw points fold:
  std::vector<Vec3> raw(m.positions().begin(), m.positions().end());
  raw.resize(m.num_vertices() + m.num_edges());
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    const HalfedgeId h = m.halfedge(EdgeId(e));
    raw[m.num_vertices() + e] =
        (m.position(m.from(h)) + m.position(m.to(h))) * 0.5 + (EdgeId(e) == target ? push : Vec3{});
  }
  ASSERT_LT(min_child_parent_cos(m, raw), 0.0);

  StepStats stats;
  const Level fine = split4(coarse, folding, stats);
  EXPECT_GE(stats.fold_fallbacks, 1u);
  EXPECT_GE(min_child_parent_cos(m, fine.mesh.positions()), 0.0);
  // The guarded point lies between the midpoint and the raw point.
  const HalfedgeId h = m.halfedge(target);
  const Vec3 mid = (m.position(m.from(h)) + m.position(m.to(h))) * 0.5;
  const Vec3 got = fine.mesh.position(edge_vertex(m, target));
  EXPECT_NEAR(got.x, mid.x, 1e-12);
  EXPECT_NEAR(got.z, mid.z, 1e-12);
  EXPECT_GE(got.y, mid.y);
  EXPECT_LT(got.y, mid.y + push.y);
  // Other edge points are untouched.
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    if (EdgeId(e) == target) continue;
    EXPECT_EQ(fine.mesh.position(edge_vertex(m, EdgeId(e))), raw[m.num_vertices() + e]);
  }
}

// The host derives the fine level's vertex kinds and curve neighbours arithmetically;
// they must equal a full re-classification of the fine mesh from its sharp flags.
TEST(Split4Host, DerivedFeaturesEqualAFullReclassification) {
  IndexedSoup fin = cube_soup(10.0);  // a fin on a cube edge: a non-manifold cut
  const std::uint32_t tip = static_cast<std::uint32_t>(fin.positions.size());
  fin.positions.push_back({5.0, -5.0, 10.0});
  fin.triangles.push_back({0, 1, tip});
  ASSERT_EQ(build_mesh(fin).report.non_manifold_edges, 1u);
  for (const IndexedSoup& soup : {cube_soup(2.0), cylinder_soup(12, 5.0, 8.0), grid_soup(5, 4),
                                  fan_soup(7, 0.5), torus_soup(10, 6, 10.0, 3.0), fin}) {
    Level level = make_level(to_mesh(soup));
    for (const char* scheme : {"loop", "butterfly"}) {
      Level fine = level;
      for (int i = 0; i < 2; ++i) {
        fine = refine_level(scheme, fine);
        const auto flags = fine.features.sharp_edges();
        const Features full(fine.mesh, BigVector<std::uint8_t>(flags.begin(), flags.end()));
        ASSERT_EQ(full.num_sharp_edges(), fine.features.num_sharp_edges());
        for (std::uint32_t v = 0; v < fine.mesh.num_vertices(); ++v) {
          const VertexId id(v);
          ASSERT_EQ(full.kind(id), fine.features.kind(id)) << scheme << " vertex " << v;
          if (full.kind(id) != VertexKind::Crease) continue;
          auto x = full.curve_neighbours(id), y = fine.features.curve_neighbours(id);
          if (x[0] != y[0]) std::swap(y[0], y[1]);
          EXPECT_EQ(x[0], y[0]);
          EXPECT_EQ(x[1], y[1]);
        }
      }
    }
  }
}

}  // namespace
}  // namespace stlrefine::test
