// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Loop subdivision with Hoppe's sharp rules, checked against spec section 1 and the
// test vectors of section 7.7.
#include "core/schemes/loop.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include "core/mesh/mesh_stats.h"
#include "tests/core/reference_cases.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/reference_split4.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

constexpr double kExact = 1e-14;

// --- point-by-point comparison with the spec reference (one and two levels)

class LoopReference : public ::testing::TestWithParam<RefCase> {};

TEST_P(LoopReference, FirstLevelMatchesSpec) {
  const Level coarse = GetParam().make();
  const Level fine = refine_level("loop", coarse);
  expect_matches_reference(coarse, fine, reference_loop_step(coarse));
}

TEST_P(LoopReference, SecondLevelMatchesSpec) {
  const Level coarse = refine_level("loop", GetParam().make());
  const Level fine = refine_level("loop", coarse);
  expect_matches_reference(coarse, fine, reference_loop_step(coarse));
}

INSTANTIATE_TEST_SUITE_P(Meshes, LoopReference, ::testing::ValuesIn(reference_cases()),
                         [](const auto& info) { return info.param.name; });

// --- weights

TEST(LoopScheme, BetaValues) {
  EXPECT_DOUBLE_EQ(loop_beta(6), 1.0 / 16.0);
  EXPECT_DOUBLE_EQ(loop_beta(3), 3.0 / 16.0);
}

TEST(LoopScheme, TetrahedronVerticesUseBetaThree) {
  // Valence 3, beta = 3/16: v' = 7/16 v + 3/16 (sum of the others) = v/4 (centroid 0).
  const IndexedSoup soup = tetrahedron_soup();
  const Level coarse = make_level(to_mesh(soup), 180);
  const Level fine = refine_level("loop", coarse);
  for (std::uint32_t v = 0; v < 4; ++v)
    EXPECT_VEC_NEAR(fine.mesh.position(VertexId(v)), coarse.mesh.position(VertexId(v)) * 0.25,
                    kExact);
  // Edge points: 3/8 (a + b) + 1/8 (c + d) = 1/4 (a + b).
  for (std::uint32_t e = 0; e < coarse.mesh.num_edges(); ++e) {
    const HalfedgeId h = coarse.mesh.halfedge(EdgeId(e));
    const Vec3 want =
        (coarse.mesh.position(coarse.mesh.from(h)) + coarse.mesh.position(coarse.mesh.to(h))) *
        0.25;
    EXPECT_VEC_NEAR(fine.mesh.position(edge_vertex(coarse.mesh, EdgeId(e))), want, kExact);
  }
}

// Flat 8x8 grid with vertex (4,4) lifted to z = 1: one Loop step spreads exactly the
// masks' weights, so every fine height is a weight (the impulse response).
TEST(LoopScheme, RegularImpulseResponseIsTheMask) {
  const int n = 8;
  const IndexedSoup soup = grid_soup(n, n);
  Level coarse = make_level(to_mesh(soup), 180);
  const Mesh& m = coarse.mesh;
  auto V = [&](int i, int j) { return find_vertex(m, soup.positions[grid_index(n, i, j)]); };
  const VertexId c = V(4, 4);
  coarse.mesh.mutable_positions()[c.idx].z = 1.0;
  const Level fine = refine_level("loop", coarse);

  std::map<std::uint32_t, double> want;  // fine vertex -> z; others 0
  want[c.idx] = 10.0 / 16.0;             // 1 - 6 beta(6)
  const auto r = ring(m, c);
  ASSERT_EQ(r.size(), 6u);
  for (std::size_t k = 0; k < r.size(); ++k) {
    want[r[k].vertex.idx] = 1.0 / 16.0;               // beta(6)
    want[edge_vertex(m, r[k].edge).idx] = 3.0 / 8.0;  // spoke edge
    const EdgeId opposite = find_edge(m, r[k].vertex, r[(k + 1) % r.size()].vertex);
    ASSERT_TRUE(opposite.valid());
    want[edge_vertex(m, opposite).idx] = 1.0 / 8.0;  // c is the tip
  }
  for (std::uint32_t v = 0; v < fine.mesh.num_vertices(); ++v) {
    const double expected = want.count(v) ? want[v] : 0.0;
    EXPECT_NEAR(fine.mesh.position(VertexId(v)).z, expected, kExact) << "fine vertex " << v;
  }
}

TEST(LoopScheme, FanCentreUsesBetaOfItsValence) {
  for (int n = 3; n <= 9; ++n) {
    const Level coarse = make_level(to_mesh(fan_soup(n, 1.0)), 180);
    const VertexId c = find_vertex(coarse.mesh, {0, 0, 1});
    ASSERT_TRUE(c.valid());
    const Level fine = refine_level("loop", coarse);
    const double beta =
        (5.0 / 8.0 - std::pow(3.0 / 8.0 + std::cos(2 * std::numbers::pi / n) / 4, 2)) / n;
    // The ring is a regular polygon centred on the axis: only the centre's weight shows.
    EXPECT_VEC_NEAR(fine.mesh.position(c), (Vec3{0, 0, 1.0 - n * beta}), kExact) << "n = " << n;
    if (n == 3) {
      EXPECT_NEAR(fine.mesh.position(c).z, 7.0 / 16.0, kExact);
    }
    if (n == 6) {
      EXPECT_NEAR(fine.mesh.position(c).z, 10.0 / 16.0, kExact);
    }
    // Spokes are smooth edges: 3/8 centre + 3/8 ring + 1/8 each tip (both on the ring).
    for (const RingEntry& r : ring(coarse.mesh, c))
      EXPECT_NEAR(fine.mesh.position(edge_vertex(coarse.mesh, r.edge)).z, 3.0 / 8.0, kExact);
  }
}

// --- Hoppe's sharp rules on a tagged polyline (see reference_cases.h for the layout)

class LoopCreaseImpulse : public ::testing::Test {
 protected:
  static constexpr int n = 8;
  void SetUp() override {
    soup_ = grid_soup(n, n);
    const Mesh m = to_mesh(soup_);
    std::vector<std::pair<VertexId, VertexId>> sharp;
    for (int i = 0; i < 3; ++i) sharp.push_back({V(m, i, 3), V(m, i + 1, 3)});
    for (int j = 3; j < n; ++j) sharp.push_back({V(m, 3, j), V(m, 3, j + 1)});
    sharp.push_back({V(m, 5, 5), V(m, 6, 5)});  // an isolated sharp edge: two darts
    base_ = make_level_with_sharp(m, sharp);
  }
  VertexId V(const Mesh& m, int i, int j) const {
    return find_vertex(m, soup_.positions[grid_index(n, i, j)]);
  }
  VertexId V(int i, int j) const { return V(base_.mesh, i, j); }
  // Lifts (i,j) to z = 1 and refines once.
  Level lift(int i, int j) {
    coarse_ = base_;
    coarse_.mesh.mutable_positions()[V(i, j).idx].z = 1.0;
    return refine_level("loop", coarse_);
  }
  double vz(const Level& fine, int i, int j) const { return fine.mesh.position(V(i, j)).z; }
  double ez(const Level& fine, int i0, int j0, int i1, int j1) const {
    const EdgeId e = find_edge(base_.mesh, V(i0, j0), V(i1, j1));
    EXPECT_TRUE(e.valid());
    return fine.mesh.position(edge_vertex(base_.mesh, e)).z;
  }
  IndexedSoup soup_;
  Level base_, coarse_;
};

TEST_F(LoopCreaseImpulse, KindsAreAsDesigned) {
  const Features& f = base_.features;
  EXPECT_EQ(f.kind(V(0, 3)), VertexKind::Corner);
  EXPECT_EQ(f.kind(V(3, 8)), VertexKind::Corner);
  EXPECT_EQ(f.kind(V(3, 3)), VertexKind::Crease);
  EXPECT_EQ(f.kind(V(5, 5)), VertexKind::Dart);
  EXPECT_TRUE(loop_regular_crease(base_, V(1, 3)));
  EXPECT_TRUE(loop_regular_crease(base_, V(2, 3)));
  EXPECT_TRUE(loop_regular_crease(base_, V(3, 4)));
  EXPECT_FALSE(loop_regular_crease(base_, V(3, 3)));  // 0 and 4 edges on its two sides
  EXPECT_TRUE(loop_regular_crease(base_, V(4, 0)));   // boundary, valence 4
  EXPECT_FALSE(loop_regular_crease(base_, V(8, 0)));  // grid corner, valence 2
  EXPECT_FALSE(loop_regular_crease(base_, V(0, 0)));  // grid corner, valence 3
}

TEST_F(LoopCreaseImpulse, RegularCreaseVertex) {
  const Level fine = lift(1, 3);
  EXPECT_NEAR(vz(fine, 1, 3), 3.0 / 4.0, kExact);  // 1/8, 3/4, 1/8
  EXPECT_NEAR(vz(fine, 2, 3), 1.0 / 8.0, kExact);
  EXPECT_NEAR(vz(fine, 0, 3), 0.0, kExact);              // corner fixed
  EXPECT_NEAR(ez(fine, 0, 3, 1, 3), 5.0 / 8.0, kExact);  // corner (special) - regular
  EXPECT_NEAR(ez(fine, 1, 3, 2, 3), 1.0 / 2.0, kExact);  // regular - regular
  EXPECT_NEAR(ez(fine, 1, 3, 1, 4), 3.0 / 8.0, kExact);  // smooth edges: E-mask
  EXPECT_NEAR(ez(fine, 1, 2, 1, 3), 3.0 / 8.0, kExact);
  EXPECT_NEAR(ez(fine, 0, 2, 1, 3), 3.0 / 8.0, kExact);
  EXPECT_NEAR(ez(fine, 1, 4, 2, 4), 1.0 / 8.0, kExact);  // lifted vertex is a tip
  EXPECT_NEAR(vz(fine, 1, 4), 1.0 / 16.0, kExact);       // smooth neighbour: beta(6)
  EXPECT_NEAR(vz(fine, 2, 4), 1.0 / 16.0, kExact);
  EXPECT_NEAR(vz(fine, 1, 2), 1.0 / 16.0, kExact);
}

TEST_F(LoopCreaseImpulse, IrregularCreaseVertexIsSpecial) {
  Level fine = lift(3, 3);
  EXPECT_NEAR(vz(fine, 3, 3), 3.0 / 4.0, kExact);  // crease rule, regular or not
  EXPECT_NEAR(vz(fine, 2, 3), 1.0 / 8.0, kExact);
  EXPECT_NEAR(vz(fine, 3, 4), 1.0 / 8.0, kExact);
  EXPECT_NEAR(ez(fine, 2, 3, 3, 3), 3.0 / 8.0, kExact);  // 3/8 special + 5/8 regular
  EXPECT_NEAR(ez(fine, 3, 3, 3, 4), 3.0 / 8.0, kExact);
  fine = lift(2, 3);
  EXPECT_NEAR(ez(fine, 2, 3, 3, 3), 5.0 / 8.0, kExact);
  EXPECT_NEAR(ez(fine, 1, 3, 2, 3), 1.0 / 2.0, kExact);
  fine = lift(3, 4);
  EXPECT_NEAR(ez(fine, 3, 3, 3, 4), 5.0 / 8.0, kExact);
  EXPECT_NEAR(ez(fine, 3, 4, 3, 5), 1.0 / 2.0, kExact);
}

TEST_F(LoopCreaseImpulse, CornerStaysFixed) {
  const Level fine = lift(0, 3);
  EXPECT_EQ(fine.mesh.position(V(0, 3)), coarse_.mesh.position(V(0, 3)));
  EXPECT_NEAR(ez(fine, 0, 3, 1, 3), 3.0 / 8.0, kExact);
  // Boundary edges at the corner: (0,3) is special, (0,2) and (0,4) are regular.
  EXPECT_NEAR(ez(fine, 0, 2, 0, 3), 3.0 / 8.0, kExact);
  EXPECT_NEAR(ez(fine, 0, 3, 0, 4), 3.0 / 8.0, kExact);
  EXPECT_NEAR(vz(fine, 1, 3), 1.0 / 8.0, kExact);
}

TEST_F(LoopCreaseImpulse, DartEdgeUsesSmoothMask) {
  Level fine = lift(5, 5);
  EXPECT_NEAR(vz(fine, 5, 5), 10.0 / 16.0, kExact);      // darts use the V-mask
  EXPECT_NEAR(ez(fine, 5, 5, 6, 5), 3.0 / 8.0, kExact);  // not 1/2: the crease fades out
  fine = lift(6, 6);                                     // tip of the dart edge
  EXPECT_NEAR(ez(fine, 5, 5, 6, 5), 1.0 / 8.0, kExact);
}

TEST_F(LoopCreaseImpulse, BoundaryRules) {
  Level fine = lift(4, 0);
  EXPECT_NEAR(vz(fine, 4, 0), 3.0 / 4.0, kExact);
  EXPECT_NEAR(vz(fine, 3, 0), 1.0 / 8.0, kExact);
  EXPECT_NEAR(vz(fine, 4, 1), 1.0 / 16.0, kExact);  // interior smooth vertex
  EXPECT_NEAR(ez(fine, 3, 0, 4, 0), 1.0 / 2.0, kExact);
  EXPECT_NEAR(ez(fine, 4, 0, 5, 0), 1.0 / 2.0, kExact);
  EXPECT_NEAR(ez(fine, 4, 0, 4, 1), 3.0 / 8.0, kExact);  // interior edge at the boundary
  fine = lift(7, 0);
  EXPECT_NEAR(ez(fine, 7, 0, 8, 0), 5.0 / 8.0, kExact);  // grid corner (valence 2) special
  fine = lift(8, 0);
  EXPECT_NEAR(vz(fine, 8, 0), 3.0 / 4.0, kExact);  // a crease vertex, not fixed
  EXPECT_NEAR(ez(fine, 7, 0, 8, 0), 3.0 / 8.0, kExact);
  EXPECT_NEAR(ez(fine, 8, 0, 8, 1), 3.0 / 8.0, kExact);
}

// --- test vectors (spec 7.7)

TEST(LoopScheme, IcosahedronTestVectors) {
  const Level coarse = make_level(to_mesh(icosahedron_soup()), 180);
  const Level fine = refine_level("loop", coarse);
  for (std::uint32_t v = 0; v < 12; ++v) {
    EXPECT_NEAR(norm(fine.mesh.position(VertexId(v))), 0.7675720593359079, 1e-12);
    EXPECT_NEAR(norm(fine.mesh.position(VertexId(v))), 0.767572, 5e-7);
    // Moves along its own direction.
    EXPECT_NEAR(dot(normalized(fine.mesh.position(VertexId(v))), coarse.mesh.position(VertexId(v))),
                1.0, 1e-12);
  }
  for (std::uint32_t e = 0; e < 30; ++e) {
    EXPECT_NEAR(norm(fine.mesh.position(edge_vertex(coarse.mesh, EdgeId(e)))), 0.7694208842938134,
                1e-12);
    EXPECT_NEAR(norm(fine.mesh.position(edge_vertex(coarse.mesh, EdgeId(e)))), 0.769421, 5e-7);
  }
}

// --- invariants

TEST(LoopScheme, CountsAndEulerCharacteristic) {
  for (const auto& soup :
       {torus_soup(8, 6, 3, 1), icosphere_soup(1), grid_soup(4, 3), cylinder_soup(8, 1, 2)}) {
    Level level = make_level(to_mesh(soup));
    const MeshStats s0 = compute_stats(level.mesh);
    for (int l = 1; l <= 3; ++l) {
      const std::size_t V = level.mesh.num_vertices(), E = level.mesh.num_edges(),
                        F = level.mesh.num_faces();
      level = refine_level("loop", level);
      EXPECT_EQ(level.mesh.num_faces(), 4 * F);
      EXPECT_EQ(level.mesh.num_vertices(), V + E);
      EXPECT_EQ(level.mesh.num_edges(), 2 * E + 3 * F);
      EXPECT_EQ(level.mesh.check_invariants(), "");
      const MeshStats s = compute_stats(level.mesh);
      EXPECT_EQ(s.euler_characteristic, s0.euler_characteristic);
      EXPECT_EQ(s.watertight, s0.watertight);
      EXPECT_EQ(s.boundary_loops, s0.boundary_loops);
    }
  }
}

TEST(LoopScheme, PlanarInputStaysPlanar) {
  const IndexedSoup soup = jittered_plane_soup(6);
  const Vec3 n = jittered_plane_normal();
  const double d = dot(n, soup.positions[0]);
  ASSERT_GT(std::abs(d), 1.0);  // the plane misses the origin, so scaled masks would show
  const Level fine = refine_levels("loop", make_level(to_mesh(soup)), 3);
  for (const Vec3& p : fine.mesh.positions()) EXPECT_NEAR(dot(n, p), d, 1e-12);
}

TEST(LoopScheme, CubeStaysACube) {
  // Every face is flat and every edge a crease between corners: Hoppe's rules keep the
  // cube exactly (crease points stay on the edges, face points in the faces).
  const Level coarse = make_level(to_mesh(cube_soup(1.0)));
  const Level fine = refine_levels("loop", coarse, 3);
  for (std::uint32_t v = 0; v < 8; ++v)
    EXPECT_EQ(fine.mesh.position(VertexId(v)), coarse.mesh.position(VertexId(v)));
  auto on = [](double x) { return std::abs(x) < 1e-12 || std::abs(x - 1) < 1e-12; };
  for (std::uint32_t v = 0; v < fine.mesh.num_vertices(); ++v) {
    const Vec3 p = fine.mesh.position(VertexId(v));
    const int faces = on(p.x) + on(p.y) + on(p.z);
    EXPECT_GE(faces, 1) << str(p);
    if (fine.features.kind(VertexId(v)) != VertexKind::Smooth) {
      EXPECT_GE(faces, 2) << str(p);
    }
    for (double c : {p.x, p.y, p.z}) {
      EXPECT_GE(c, -1e-12);
      EXPECT_LE(c, 1 + 1e-12);
    }
  }
  EXPECT_NEAR(signed_volume(fine.mesh), 1.0, 1e-12);
}

TEST(LoopScheme, AffineInvariance) {
  // refine(A p + t) == A refine(p) + t: the masks are affine combinations. Crease
  // detection is off (angles are not affine invariant); boundaries still use their rules.
  auto A = [](const Vec3& p) {
    return Vec3{2 * p.x + 0.5 * p.y - 0.3 * p.z + 1000.25,
                -0.4 * p.x + 1.5 * p.y + 0.2 * p.z - 2000.5,
                0.1 * p.x - 0.7 * p.y + 3 * p.z + 512.125};
  };
  for (const auto& soup : {icosphere_soup(1), torus_soup(8, 6, 3, 1), bumpy_grid_soup(6, 0.2),
                           fan_soup(7, 0.4), bipyramid_soup(5)}) {
    IndexedSoup moved = soup;
    for (Vec3& p : moved.positions) p = A(p);
    const Level a = refine_levels("loop", make_level(to_mesh(soup), 180), 2);
    const Level b = refine_levels("loop", make_level(to_mesh(moved), 180), 2);
    ASSERT_EQ(a.mesh.num_vertices(), b.mesh.num_vertices());
    const double tol = 1e-12 * max_abs_coord(b.mesh.positions());
    for (std::uint32_t v = 0; v < a.mesh.num_vertices(); ++v)
      EXPECT_VEC_NEAR(b.mesh.position(VertexId(v)), A(a.mesh.position(VertexId(v))), tol);
  }
}

TEST(LoopScheme, TranslationInvarianceWithCreases) {
  const Vec3 t{1234.5, -987.25, 4096.125};
  for (const auto& soup :
       {cube_soup(2.0), cylinder_soup(24, 10, 20), grid_soup(5, 4), icosphere_soup(1)}) {
    const Level a = refine_levels("loop", make_level(to_mesh(soup)), 2);
    const Level b = refine_levels("loop", make_level(to_mesh(translated(soup, t))), 2);
    ASSERT_EQ(a.mesh.num_vertices(), b.mesh.num_vertices());
    const double tol = 1e-12 * max_abs_coord(b.mesh.positions());
    for (std::uint32_t v = 0; v < a.mesh.num_vertices(); ++v)
      EXPECT_VEC_NEAR(b.mesh.position(VertexId(v)), a.mesh.position(VertexId(v)) + t, tol);
  }
}

TEST(LoopScheme, ApproximatesAndShrinksConvexShapes) {
  const Level coarse = make_level(to_mesh(icosphere_soup(1)), 180);
  const Level fine = refine_level("loop", coarse);
  std::size_t moved = 0;
  for (std::uint32_t v = 0; v < coarse.mesh.num_vertices(); ++v) {
    moved += fine.mesh.position(VertexId(v)) != coarse.mesh.position(VertexId(v));
    EXPECT_LT(norm(fine.mesh.position(VertexId(v))), 1.0);
  }
  EXPECT_EQ(moved, coarse.mesh.num_vertices());
}

}  // namespace
}  // namespace stlrefine::test
