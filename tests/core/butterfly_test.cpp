// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Zorin's modified butterfly with the crease handling of spec section 2, checked against
// the spec's rules, its test vectors (7.7) and the invariants of section 7.
#include "core/schemes/butterfly.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>

#include "core/mesh/mesh_stats.h"
#include "core/schemes/split4_host.h"
#include "tests/core/reference_cases.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/reference_split4.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

constexpr double kExact = 1e-14;

// --- point-by-point comparison with the spec reference

class ButterflyReference : public ::testing::TestWithParam<RefCase> {};

// Compares one step; where the raw rule folds a child face the fold guard may move the
// edge points of that face, so those are skipped, and the guard must have fired.
void check_step_against_reference(const Level& coarse) {
  const ReferenceStep ref = reference_butterfly_step(coarse);
  StepStats stats;
  const Level fine = refine_level("butterfly", coarse, &stats);
  const auto folded = edges_of_folded_faces(coarse.mesh, ref);
  const bool any_fold = std::find(folded.begin(), folded.end(), true) != folded.end();
  if (any_fold) {
    EXPECT_GT(stats.fold_fallbacks, 0u) << "the raw butterfly folds here";
  } else {
    EXPECT_EQ(stats.fold_fallbacks, 0u) << "nothing folds, the guard must not act";
  }
  expect_matches_reference(coarse, fine, ref, folded);
}

TEST_P(ButterflyReference, FirstLevelMatchesSpec) {
  check_step_against_reference(GetParam().make());
}

TEST_P(ButterflyReference, SecondLevelMatchesSpec) {
  check_step_against_reference(refine_level("butterfly", GetParam().make()));
}

INSTANTIATE_TEST_SUITE_P(Meshes, ButterflyReference, ::testing::ValuesIn(reference_cases()),
                         [](const auto& info) { return info.param.name; });

// --- interpolation

TEST(ButterflyScheme, InputVerticesAreBitIdentical) {
  for (const auto& [soup, angle] : std::vector<std::pair<IndexedSoup, double>>{
           {icosahedron_soup(), 180},
           {icosahedron_soup(), 35},
           {cube_soup(3.0), 35},
           {cylinder_soup(24, 10, 20), 35},
           {cylinder_soup(8, 10, 100), 180},
           {grid_soup(5, 4), 35},
           {bumpy_grid_soup(6, 0.3), 180},
           {torus_soup(8, 6, 3, 1), 180},
           {fan_soup(7, 0.5), 180},
           {translated(icosphere_soup(1, 7.3), {0.1, 1e5, -3.3}), 35}}) {
    Level level = make_level(to_mesh(soup), angle);
    const Mesh input = level.mesh;
    for (int l = 1; l <= 3; ++l) {
      level = refine_level("butterfly", level);
      for (std::uint32_t v = 0; v < input.num_vertices(); ++v) {
        const Vec3 a = level.mesh.position(VertexId(v)), b = input.position(VertexId(v));
        EXPECT_TRUE(a.x == b.x && a.y == b.y && a.z == b.z)
            << "level " << l << " vertex " << v << " moved from " << str(b) << " to " << str(a);
      }
    }
  }
}

// --- polynomial reproduction (spec 7.5)

// Lattice (x0 + i h, y0 + j h) with z = f: the xy of every edge point is the lattice
// midpoint (linear precision), i.e. exactly the parameter point of the polynomial.
class HeightField : public ::testing::Test {
 protected:
  static constexpr int n = 10;
  static constexpr double x0 = -1.0, y0 = -1.0, h = 0.2;
  Level refine(const std::function<double(double, double)>& f, int levels) {
    coarse_ = make_level(to_mesh(height_field_soup(n, n, x0, y0, h, f)), 180);
    std::size_t folds = 0;
    Level fine = refine_levels("butterfly", coarse_, levels, &folds);
    EXPECT_EQ(folds, 0u);
    return fine;
  }
  // Largest |z - f(x, y)| over level-1 edge points whose endpoints are both interior.
  double max_interior_error(const Level& fine, const std::function<double(double, double)>& f) {
    const Mesh& c = coarse_.mesh;
    double worst = 0;
    int checked = 0;
    for (std::uint32_t e = 0; e < c.num_edges(); ++e) {
      const HalfedgeId he = c.halfedge(EdgeId(e));
      if (c.is_boundary(c.from(he)) || c.is_boundary(c.to(he))) continue;
      const Vec3 p = fine.mesh.position(edge_vertex(c, EdgeId(e)));
      const Vec3 mid = (c.position(c.from(he)) + c.position(c.to(he))) * 0.5;
      EXPECT_NEAR(p.x, mid.x, 1e-14);
      EXPECT_NEAR(p.y, mid.y, 1e-14);
      worst = std::max(worst, std::abs(p.z - f(p.x, p.y)));
      ++checked;
    }
    // Horizontal and vertical edges between interior vertices, plus interior diagonals.
    EXPECT_EQ(checked, 2 * (n - 1) * (n - 2) + (n - 2) * (n - 2));
    return worst;
  }
  Level coarse_;
};

TEST_F(HeightField, EightPointRuleReproducesCubics) {
  const Level fine = refine(cubic_field, 1);
  EXPECT_LE(max_interior_error(fine, cubic_field), 1e-12);
}

TEST_F(HeightField, EveryCubicMonomialIsReproduced) {
  using F = std::function<double(double, double)>;
  for (const F& f : std::vector<F>{
           [](double x, double) { return x * x * x; }, [](double x, double y) { return x * x * y; },
           [](double x, double y) { return x * y * y; }, [](double, double y) { return y * y * y; },
           [](double x, double y) { return 1 + x - y + x * y; }}) {
    const Level fine = refine(f, 1);
    EXPECT_LE(max_interior_error(fine, f), 1e-12);
  }
}

TEST_F(HeightField, SecondLevelReproducesCubicsAwayFromTheBoundary) {
  const Level fine = refine(cubic_field, 2);
  // Level-2 points depend on level-1 points within one coarse spacing; those are exact when
  // they are at least one spacing away from the boundary.
  double worst = 0;
  int checked = 0;
  for (const Vec3& p : fine.mesh.positions()) {
    const double margin = 2.5 * h;
    if (p.x < x0 + margin || p.x > x0 + n * h - margin || p.y < y0 + margin ||
        p.y > y0 + n * h - margin)
      continue;
    worst = std::max(worst, std::abs(p.z - cubic_field(p.x, p.y)));
    ++checked;
  }
  EXPECT_GT(checked, 100);
  EXPECT_LE(worst, 1e-12);
}

TEST_F(HeightField, QuarticsAreNotReproduced) {
  // Guards the two tests above against passing vacuously: degree 4 must show an error.
  auto f = [](double x, double y) { return x * x * x * x + x * x * y * y; };
  const Level fine = refine(f, 1);
  EXPECT_GT(max_interior_error(fine, f), 1e-6);
}

// --- extraordinary rules (spec 2 and test vectors 7.7)

TEST(ButterflyScheme, OctahedronEdgePointsValenceFour) {
  const Level coarse = make_level(to_mesh(octahedron_soup()), 180);
  const Level fine = refine_level("butterfly", coarse);
  for (std::uint32_t e = 0; e < coarse.mesh.num_edges(); ++e) {
    const HalfedgeId h = coarse.mesh.halfedge(EdgeId(e));
    const Vec3 a = coarse.mesh.position(coarse.mesh.from(h));
    const Vec3 b = coarse.mesh.position(coarse.mesh.to(h));
    const Vec3 p = fine.mesh.position(edge_vertex(coarse.mesh, EdgeId(e)));
    EXPECT_VEC_NEAR(p, (a + b) * (5.0 / 8.0), kExact);  // e.g. (5/8, 0, 5/8)
    EXPECT_NEAR(norm(p), 0.883883, 5e-7);
  }
}

TEST(ButterflyScheme, IcosahedronEdgePointsValenceFive) {
  const Level coarse = make_level(to_mesh(icosahedron_soup()), 180);
  const Level fine = refine_level("butterfly", coarse);
  for (std::uint32_t e = 0; e < coarse.mesh.num_edges(); ++e) {
    const HalfedgeId h = coarse.mesh.halfedge(EdgeId(e));
    const Vec3 a = coarse.mesh.position(coarse.mesh.from(h));
    const Vec3 b = coarse.mesh.position(coarse.mesh.to(h));
    const Vec3 p = fine.mesh.position(edge_vertex(coarse.mesh, EdgeId(e)));
    EXPECT_NEAR(norm(p), 0.9682078588105345, 1e-12);
    EXPECT_NEAR(norm(p), 0.968208, 5e-7);
    EXPECT_NEAR(dot(normalized(p), normalized(a + b)), 1.0, 1e-12);  // by symmetry
  }
}

TEST(ButterflyScheme, TetrahedronEdgePointsValenceThree) {
  const Level coarse = make_level(to_mesh(tetrahedron_soup()), 180);
  const Level fine = refine_level("butterfly", coarse);
  for (std::uint32_t e = 0; e < coarse.mesh.num_edges(); ++e) {
    const HalfedgeId h = coarse.mesh.halfedge(EdgeId(e));
    const Vec3 a = coarse.mesh.position(coarse.mesh.from(h));
    const Vec3 b = coarse.mesh.position(coarse.mesh.to(h));
    const Vec3 p = fine.mesh.position(edge_vertex(coarse.mesh, EdgeId(e)));
    EXPECT_VEC_NEAR(p, (a + b) * (2.0 / 3.0), kExact);
    EXPECT_NEAR(norm(p), 0.769800, 5e-7);
  }
}

TEST(ButterflyScheme, WeightTableMatchesSpec) {
  for (int k : {3, 4, 5, 7, 8, 12}) {
    const auto s = butterfly_ring_weights(k);
    double sum = 0;
    for (int j = 0; j < k; ++j) {
      EXPECT_NEAR(ButterflyStencil::extraordinary_weight(k, j), s[j], 1e-15) << k << "," << j;
      sum += ButterflyStencil::extraordinary_weight(k, j);
    }
    EXPECT_NEAR(sum, 0.25, 1e-15) << "k = " << k;
  }
  EXPECT_DOUBLE_EQ(ButterflyStencil::extraordinary_weight(3, 0), 5.0 / 12.0);
  EXPECT_DOUBLE_EQ(ButterflyStencil::extraordinary_weight(3, 1), -1.0 / 12.0);
  EXPECT_DOUBLE_EQ(ButterflyStencil::extraordinary_weight(4, 0), 3.0 / 8.0);
  EXPECT_DOUBLE_EQ(ButterflyStencil::extraordinary_weight(4, 1), 0.0);
  EXPECT_DOUBLE_EQ(ButterflyStencil::extraordinary_weight(4, 2), -1.0 / 8.0);
}

// Fan of valence k (ring = boundary): a spoke's point uses the centre's rule alone
// (sharp ring vertices are treated as regular). Lifting one vertex to z = 1 reads the
// weights off the spoke points.
TEST(ButterflyScheme, FanSpokesUseTheCentreRuleForEveryValence) {
  for (int k : {3, 4, 5, 7, 8}) {
    const IndexedSoup soup = fan_soup(k);
    const Level flat = make_level(to_mesh(soup), 180);
    const Mesh& m = flat.mesh;
    const VertexId c = find_vertex(m, soup.positions[0]);
    const auto weights = butterfly_ring_weights(k);
    for (int lifted = 0; lifted <= k; ++lifted) {  // 0: the centre, else ring vertex
      Level coarse = flat;
      const VertexId lv = find_vertex(m, soup.positions[lifted]);
      coarse.mesh.mutable_positions()[lv.idx].z = 1.0;
      const Level fine = refine_level("butterfly", coarse);
      for (int spoke = 1; spoke <= k; ++spoke) {
        const EdgeId e = find_edge(m, c, find_vertex(m, soup.positions[spoke]));
        const double z = fine.mesh.position(edge_vertex(m, e)).z;
        const int offset = ((lifted - spoke) % k + k) % k;  // s_j is symmetric in j
        const double want = lifted == 0 ? 0.75 : weights[offset];
        EXPECT_NEAR(z, want, kExact) << "k " << k << " lifted " << lifted << " spoke " << spoke;
      }
    }
  }
}

TEST(ButterflyScheme, RegularFanUsesVirtualPoints) {
  // Valence 6: both ends regular, so the 8-point stencil with the two c points across the
  // boundary reflected: spoke = 5/8 c + 3/8 e0 + 1/16 (e1 + e-1) - 1/16 (e2 + e-2).
  const IndexedSoup soup = fan_soup(6);
  const Level flat = make_level(to_mesh(soup), 180);
  const Mesh& m = flat.mesh;
  const VertexId c = find_vertex(m, soup.positions[0]);
  const double w[6] = {3.0 / 8.0, 1.0 / 16.0, -1.0 / 16.0, 0.0, -1.0 / 16.0, 1.0 / 16.0};
  for (int lifted = 0; lifted <= 6; ++lifted) {
    Level coarse = flat;
    coarse.mesh.mutable_positions()[find_vertex(m, soup.positions[lifted]).idx].z = 1.0;
    const Level fine = refine_level("butterfly", coarse);
    for (int spoke = 1; spoke <= 6; ++spoke) {
      const EdgeId e = find_edge(m, c, find_vertex(m, soup.positions[spoke]));
      const double want = lifted == 0 ? 5.0 / 8.0 : w[((lifted - spoke) % 6 + 6) % 6];
      EXPECT_NEAR(fine.mesh.position(edge_vertex(m, e)).z, want, kExact)
          << "lifted " << lifted << " spoke " << spoke;
    }
  }
}

TEST(ButterflyScheme, BothEndsExtraordinaryAreAveraged) {
  // Bipyramid over a pentagon: apex valence 5, equator valence 4.
  const IndexedSoup soup = bipyramid_soup(5, 1.3);
  const Level coarse = make_level(to_mesh(soup), 180);
  const Level fine = refine_level("butterfly", coarse);
  const Mesh& m = coarse.mesh;
  const Vec3 top = soup.positions[5], bottom = soup.positions[6];
  const auto s5 = butterfly_ring_weights(5);
  for (int i = 0; i < 5; ++i) {
    const Vec3 e0 = soup.positions[i];
    // Apex side: 3/4 apex + sum_j s_j e_j, ring offsets j from e0 (symmetric weights).
    Vec3 apex_side = top * 0.75;
    for (int j = 0; j < 5; ++j) apex_side += soup.positions[(i + j) % 5] * s5[j];
    // Equator side (k = 4, ring: apex, neighbour, bottom, neighbour): 3/8 apex - 1/8 bottom.
    const Vec3 eq_side = e0 * 0.75 + top * (3.0 / 8.0) - bottom * (1.0 / 8.0);
    const EdgeId e = find_edge(m, find_vertex(m, top), find_vertex(m, e0));
    EXPECT_VEC_NEAR(fine.mesh.position(edge_vertex(m, e)), (apex_side + eq_side) * 0.5, kExact);
  }
}

// --- curves (boundary and crease edges)

class ButterflyCurve : public ::testing::Test {
 protected:
  static constexpr int n = 8;
  void SetUp() override { soup_ = grid_soup(n, n); }
  VertexId V(int i, int j) const {
    return find_vertex(base_.mesh, soup_.positions[grid_index(n, i, j)]);
  }
  Level lift(int i, int j) {
    Level coarse = base_;
    coarse.mesh.mutable_positions()[V(i, j).idx].z = 1.0;
    return refine_level("butterfly", coarse);
  }
  double ez(const Level& fine, int i0, int j0, int i1, int j1) const {
    const EdgeId e = find_edge(base_.mesh, V(i0, j0), V(i1, j1));
    EXPECT_TRUE(e.valid());
    return fine.mesh.position(edge_vertex(base_.mesh, e)).z;
  }
  IndexedSoup soup_;
  Level base_;
};

TEST_F(ButterflyCurve, FourPointRuleOnBoundary) {
  base_ = make_level(to_mesh(soup_), 180);
  const Level fine = lift(4, 0);
  EXPECT_NEAR(ez(fine, 3, 0, 4, 0), 9.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 4, 0, 5, 0), 9.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 2, 0, 3, 0), -1.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 5, 0, 6, 0), -1.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 1, 0, 2, 0), 0.0, kExact);
  EXPECT_NEAR(ez(fine, 6, 0, 7, 0), 0.0, kExact);
  // The curve points use curve vertices only: x and y stay on the boundary line.
  for (int i = 0; i < n; ++i) {
    const EdgeId e = find_edge(base_.mesh, V(i, 0), V(i + 1, 0));
    const Vec3 p = fine.mesh.position(edge_vertex(base_.mesh, e));
    if (i >= 1 && i + 1 <= n - 1) {
      EXPECT_NEAR(p.y, 0.0, kExact);
      EXPECT_NEAR(p.x, i + 0.5, kExact);
    }
  }
}

TEST_F(ButterflyCurve, BoundaryRoundsTheGridCorner) {
  // A grid corner has two sharp edges: it is a crease vertex, so the 4-point rule runs
  // around it (its neighbour beyond is on the other side).
  base_ = make_level(to_mesh(soup_), 180);
  const Level fine = lift(0, 1);
  EXPECT_NEAR(ez(fine, 0, 0, 1, 0), -1.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 0, 0, 0, 1), 9.0 / 16.0, kExact);
}

TEST_F(ButterflyCurve, EndConditionAtACorner) {
  // Tagging (4,0)-(4,1) gives (4,0) three sharp edges: a corner that ends both boundary
  // polylines. The missing neighbour is 2 p0 - p1, giving 7/16, 10/16, -1/16.
  base_ = make_level_with_sharp(to_mesh(soup_), {});
  const Mesh m = base_.mesh;
  base_ = make_level_with_sharp(m, {{V(4, 0), V(4, 1)}});
  ASSERT_EQ(base_.features.kind(V(4, 0)), VertexKind::Corner);
  Level fine = lift(5, 0);
  EXPECT_NEAR(ez(fine, 4, 0, 5, 0), 10.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 5, 0, 6, 0), 9.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 6, 0, 7, 0), -1.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 3, 0, 4, 0), 0.0, kExact);  // the corner cuts the polyline
  fine = lift(4, 0);
  EXPECT_NEAR(ez(fine, 4, 0, 5, 0), 7.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 3, 0, 4, 0), 7.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 5, 0, 6, 0), -1.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 2, 0, 3, 0), -1.0 / 16.0, kExact);
  fine = lift(6, 0);
  EXPECT_NEAR(ez(fine, 4, 0, 5, 0), -1.0 / 16.0, kExact);
  // (4,0)-(4,1) has a corner at one end and a dart at the other: both are ends, so the
  // midpoint.
  fine = lift(4, 1);
  EXPECT_NEAR(ez(fine, 4, 0, 4, 1), 0.5, kExact);
  fine = lift(4, 2);
  EXPECT_NEAR(ez(fine, 4, 0, 4, 1), 0.0, kExact);
}

TEST_F(ButterflyCurve, InteriorCreaseUsesOnlyCurveVertices) {
  // Interior crease (0,4)..(8,4) (boundary to boundary). Lifting a vertex next to the
  // crease must not change any crease point: both sides are refined as separate patches.
  base_ = make_level_with_sharp(to_mesh(soup_), {});
  const Mesh m = base_.mesh;
  std::vector<std::pair<VertexId, VertexId>> sharp;
  for (int i = 0; i < n; ++i) sharp.push_back({V(i, 4), V(i + 1, 4)});
  base_ = make_level_with_sharp(m, sharp);
  for (auto [i, j] : std::vector<std::pair<int, int>>{{4, 5}, {4, 3}, {3, 3}, {5, 5}}) {
    const Level fine = lift(i, j);
    for (int k = 0; k < n; ++k)
      EXPECT_NEAR(ez(fine, k, 4, k + 1, 4), 0.0, kExact) << "lifted " << i << "," << j;
  }
  const Level fine = lift(4, 4);
  EXPECT_NEAR(ez(fine, 3, 4, 4, 4), 9.0 / 16.0, kExact);
  EXPECT_NEAR(ez(fine, 5, 4, 6, 4), -1.0 / 16.0, kExact);
}

// fuzz_pipeline's finding (crash-41e5db01...): a facet and its reverse give their corners
// valence 2 with a whole ring; with no sharp edge there (crease detection off, or
// zero-area facets) the extraordinary rule read weights for k = 2 from an empty table, and
// the CLI and the daemon died of SIGSEGV. Such a vertex now takes the regular rule.
TEST(ButterflyScheme, FacetsFoldedOntoEachOtherRefineWithoutTheExtraordinaryRule) {
  IndexedSoup soup;
  soup.positions = {{0, 0, 0}, {4, 0, 0}, {0, 3, 0}};
  soup.triangles = {{{0, 1, 2}}, {{0, 2, 1}}};
  const Level level = make_level(to_mesh(soup), 180);
  ASSERT_EQ(level.mesh.valence(VertexId(0)), 2);
  ASSERT_FALSE(level.features.cuts_ring(VertexId(0)));
  const Level fine = refine_level("butterfly", level);
  ASSERT_EQ(fine.mesh.num_faces(), 8u);
  for (std::uint32_t v = 0; v < fine.mesh.num_vertices(); ++v) {
    const Vec3 p = fine.mesh.position(VertexId(v));
    EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) << v;
    EXPECT_EQ(p.z, 0.0) << "vertex " << v << " left the plane of the part";
  }
}

TEST(ButterflyScheme, CubeEdgesStayOnTheirLines) {
  const Level coarse = make_level(to_mesh(cube_soup(1.0)));
  const Level fine = refine_levels("butterfly", coarse, 3);
  auto on = [](double x) { return std::abs(x) < 1e-12 || std::abs(x - 1) < 1e-12; };
  std::size_t crease_vertices = 0;
  for (std::uint32_t v = 0; v < fine.mesh.num_vertices(); ++v) {
    const Vec3 p = fine.mesh.position(VertexId(v));
    const int planes = on(p.x) + on(p.y) + on(p.z);
    EXPECT_GE(planes, 1) << str(p);  // faces stay flat
    if (fine.features.kind(VertexId(v)) != VertexKind::Smooth) {
      ++crease_vertices;
      EXPECT_GE(planes, 2) << "crease vertex off its cube edge: " << str(p);
    }
    for (double c : {p.x, p.y, p.z}) {
      EXPECT_GE(c, -1e-12);
      EXPECT_LE(c, 1 + 1e-12);
    }
  }
  EXPECT_EQ(crease_vertices, 8u + 12u * 7u);  // corners + 7 new points per cube edge
  EXPECT_NEAR(signed_volume(fine.mesh), 1.0, 1e-12);
}

TEST(ButterflyScheme, CylinderRimsAndCapsStayInTheirPlanes) {
  const int segments = 24;
  const double r = 10, height = 20;
  const Level coarse = make_level(to_mesh(cylinder_soup(segments, r, height)));
  const int levels = 3;
  const Level fine = refine_levels("butterfly", coarse, levels);
  // Faces descend from face f / 4^levels; cap faces have axis-parallel normals.
  const std::uint32_t stride = 1u << (2 * levels);
  std::size_t cap_vertices = 0;
  for (std::uint32_t f = 0; f < fine.mesh.num_faces(); ++f) {
    const Vec3 pn = coarse.mesh.face_normal(FaceId(f / stride));
    if (pn.x != 0 || pn.y != 0) continue;  // a side face
    const double plane = pn.z > 0 ? height : 0.0;
    for (VertexId v : fine.mesh.face_vertices(FaceId(f))) {
      EXPECT_NEAR(fine.mesh.position(v).z, plane, 1e-12 * height) << str(fine.mesh.position(v));
      ++cap_vertices;
    }
  }
  EXPECT_GT(cap_vertices, 0u);
  std::size_t rim = 0;
  for (std::uint32_t v = 0; v < fine.mesh.num_vertices(); ++v) {
    if (fine.features.kind(VertexId(v)) == VertexKind::Smooth) continue;
    ++rim;
    const Vec3 p = fine.mesh.position(VertexId(v));
    EXPECT_TRUE(std::abs(p.z) <= 1e-12 * height || std::abs(p.z - height) <= 1e-12 * height)
        << str(p);
    EXPECT_NEAR(std::hypot(p.x, p.y), r, 0.01 * r);  // the 4-point curve hugs the circle
  }
  EXPECT_EQ(rim, static_cast<std::size_t>(2 * segments * 8));
}

TEST(ButterflyScheme, WatertightInWatertightOut) {
  for (const auto& soup : {icosphere_soup(1), torus_soup(8, 6, 3, 1), cube_soup(1.0),
                           cylinder_soup(24, 10, 20), bipyramid_soup(7)}) {
    const Level coarse = make_level(to_mesh(soup));
    const MeshStats s0 = compute_stats(coarse.mesh);
    ASSERT_TRUE(s0.watertight);
    const Level fine = refine_levels("butterfly", coarse, 2);
    EXPECT_EQ(fine.mesh.check_invariants(), "");
    const MeshStats s = compute_stats(fine.mesh);
    EXPECT_TRUE(s.watertight);
    EXPECT_EQ(s.boundary_edges, 0u);
    EXPECT_EQ(s.genus, s0.genus);
    EXPECT_EQ(s.components, s0.components);
  }
  const Level open = make_level(to_mesh(grid_soup(4, 3)));
  const Level fine = refine_levels("butterfly", open, 2);
  EXPECT_EQ(compute_stats(fine.mesh).boundary_edges, 4u * 14u);
  EXPECT_EQ(compute_stats(fine.mesh).boundary_loops, 1u);
}

TEST(ButterflyScheme, CountsAndEulerCharacteristic) {
  for (const auto& soup :
       {torus_soup(8, 6, 3, 1), icosphere_soup(1), grid_soup(4, 3), cylinder_soup(8, 1, 2)}) {
    Level level = make_level(to_mesh(soup));
    const long long chi0 = compute_stats(level.mesh).euler_characteristic;
    for (int l = 1; l <= 3; ++l) {
      const std::size_t V = level.mesh.num_vertices(), E = level.mesh.num_edges(),
                        F = level.mesh.num_faces();
      level = refine_level("butterfly", level);
      EXPECT_EQ(level.mesh.num_faces(), 4 * F);
      EXPECT_EQ(level.mesh.num_vertices(), V + E);
      EXPECT_EQ(level.mesh.num_edges(), 2 * E + 3 * F);
      EXPECT_EQ(compute_stats(level.mesh).euler_characteristic, chi0);
    }
  }
}

TEST(ButterflyScheme, TranslationInvariance) {
  const Vec3 t{1234.5, -987.25, 4096.125};
  for (const auto& [soup, angle] :
       std::vector<std::pair<IndexedSoup, double>>{{icosphere_soup(1), 180},
                                                   {cube_soup(2.0), 35},
                                                   {cylinder_soup(24, 10, 20), 35},
                                                   {grid_soup(5, 4), 35},
                                                   {bumpy_grid_soup(6, 0.2), 180},
                                                   {bipyramid_soup(7), 180},
                                                   {fan_soup(5, 0.3), 180}}) {
    const Level a = refine_levels("butterfly", make_level(to_mesh(soup), angle), 2);
    const Level b = refine_levels("butterfly", make_level(to_mesh(translated(soup, t)), angle), 2);
    ASSERT_EQ(a.mesh.num_vertices(), b.mesh.num_vertices());
    const double tol = 1e-12 * max_abs_coord(b.mesh.positions());
    for (std::uint32_t v = 0; v < a.mesh.num_vertices(); ++v)
      EXPECT_VEC_NEAR(b.mesh.position(VertexId(v)), a.mesh.position(VertexId(v)) + t, tol);
  }
}

TEST(ButterflyScheme, AffineInvariance) {
  auto A = [](const Vec3& p) {
    return Vec3{2 * p.x + 0.5 * p.y - 0.3 * p.z + 100.25,
                -0.4 * p.x + 1.5 * p.y + 0.2 * p.z - 200.5,
                0.1 * p.x - 0.7 * p.y + 3 * p.z + 51.125};
  };
  // The rules are affine invariant; the fold guard, which measures angles (60 degrees from
  // the smooth normals), is not: the shapes are ones it leaves alone before and after the map
  // (bumpy_grid_soup(6, 0.2), made three times steeper by it, is not). Nor is the normal
  // check, which measures spokes and normals: this torus's longest spoke is at most 1.8 times
  // its shortest, 2.7 after the map (split once: the same), under the check's 3
  // (torus_soup(8, 6, 3, 1): 3.06 and 3.96, a zipper by that measure, is checked).
  for (const auto& soup : {icosphere_soup(1), torus_soup(12, 5, 4, 1.5), fan_soup(7, 0.4),
                           bipyramid_soup(5), octahedron_soup()}) {
    IndexedSoup moved = soup;
    for (Vec3& p : moved.positions) p = A(p);
    std::size_t folds_a = 0, folds_b = 0;
    const Level a = refine_levels("butterfly", make_level(to_mesh(soup), 180), 2, &folds_a);
    const Level b = refine_levels("butterfly", make_level(to_mesh(moved), 180), 2, &folds_b);
    ASSERT_EQ(folds_a + folds_b, 0u);
    const double tol = 1e-12 * max_abs_coord(b.mesh.positions());
    for (std::uint32_t v = 0; v < a.mesh.num_vertices(); ++v)
      EXPECT_VEC_NEAR(b.mesh.position(VertexId(v)), A(a.mesh.position(VertexId(v))), tol);
  }
}

TEST(ButterflyScheme, PlanarInputStaysPlanar) {
  const IndexedSoup soup = jittered_plane_soup(6);
  const Vec3 nrm = jittered_plane_normal();
  const double d = dot(nrm, soup.positions[0]);
  ASSERT_GT(std::abs(d), 1.0);
  const Level fine = refine_levels("butterfly", make_level(to_mesh(soup)), 3);
  for (const Vec3& p : fine.mesh.positions()) EXPECT_NEAR(dot(nrm, p), d, 1e-12);
}

// --- fold guard

TEST(ButterflyScheme, FoldGuardOnLongThinCylinder) {
  // r = 10 with h = 50 to 300: side triangles 5-40 times longer than wide. With crease
  // detection off the raw butterfly folds cap children at levels 2-3 (checked with the
  // reference below), so the guard must act; with the default angle it never has to.
  // (Since the guard holds 45 degrees from the carried smooth normals its levels are
  // flatter and the raw rule folds on fewer of them: 8 segments at h = 100 only among the
  // four shapes this test had, hence 10 and 16 segments and h = 50.)
  // (The normal check moves the sides' points first and the raw rule folds on fewer of the
  // later levels: 12 segments and h = 200 added to keep four folding configurations.)
  std::size_t raw_folds = 0;
  for (double angle : {180.0, 35.0}) {
    for (int segments : {8, 10, 12, 16, 24}) {
      for (double height : {50.0, 100.0, 200.0, 300.0}) {
        Level level = make_level(to_mesh(cylinder_soup(segments, 10, height)), angle);
        for (int l = 1; l <= 3; ++l) {
          const ReferenceStep raw = reference_butterfly_step(level);
          const double raw_cos = min_child_parent_cos(level.mesh, raw.positions);
          StepStats stats;
          const Level fine = refine_level("butterfly", level, &stats);
          const double cos = min_child_parent_cos(level.mesh, fine.mesh.positions());
          const std::string where = "angle " + std::to_string(angle) + " segments " +
                                    std::to_string(segments) + " height " + std::to_string(height) +
                                    " level " + std::to_string(l);
          EXPECT_GE(cos, 0.0) << where << ": a child turned more than 90 degrees";
          if (raw_cos < 0) {
            ++raw_folds;
            // The normal check (at the side's slivers, uneven rings) may have moved the
            // folding points before the guard saw them.
            std::vector<Vec3> checked(raw.positions.begin() + level.mesh.num_vertices(),
                                      raw.positions.end());
            const std::size_t moved =
                check_edge_points_against_normals(level.mesh, level.features, checked);
            EXPECT_GT(stats.fold_fallbacks + moved, 0u) << where << ": the raw rule folds";
          } else if (angle < 180) {
            // With creases off the rims are smoothed, and rim children turn more than 60
            // degrees from the smooth normals there: the guard acts without a raw fold.
            EXPECT_EQ(stats.fold_fallbacks, 0u) << where << ": nothing to fix";
          }
          level = fine;
        }
      }
    }
  }
  EXPECT_GE(raw_folds, 4u) << "the configurations no longer exercise the guard";
}

}  // namespace
}  // namespace stlrefine::test
