// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Curvature-adaptive 1-to-4 refinement with red-green closure (spec 5 gap 4), and the
// curvatures of the LSF fit.

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "core/refine.h"
#include "core/schemes/adaptive_split4.h"
#include "core/schemes/lsf.h"
#include "core/schemes/lsf_curvature.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"

namespace stlrefine {
namespace {

using namespace test;

RefineParams adaptive(const char* scheme, double tol, int max_level) {
  RefineParams p;
  p.scheme = scheme;
  p.adaptive_tol = tol;
  p.max_level = max_level;
  return p;
}

void expect_watertight_manifold(const Mesh& mesh) {
  EXPECT_EQ(mesh.check_invariants(), "");
  for (std::uint32_t h = 0; h < mesh.num_halfedges(); ++h)
    ASSERT_FALSE(mesh.is_boundary(HalfedgeId(h))) << "half-edge " << h;
}

class AdaptiveScheme : public ::testing::TestWithParam<const char*> {};

TEST(Adaptive, LsfRefinesASphereUntilEveryEdgeIsWithinTolerance) {
  const Mesh coarse = to_mesh(icosphere_soup(1, 10.0));
  const RefineResult r = refine(coarse, adaptive("lsf", 0.02, 8));
  expect_watertight_manifold(r.mesh);
  EXPECT_GT(r.report.levels, 1);
  EXPECT_LT(r.report.levels, 8);  // stopped because nothing was left over tolerance
  EXPECT_EQ(r.report.edges_over_tolerance, 0u);
  // The stopping rule itself: one more look finds no edge over tolerance.
  Level final_level{r.mesh, detect_features(r.mesh, {})};
  EXPECT_EQ(count_edges_over_tolerance(final_level, *adaptive_scheme(*make_scheme("lsf")), 0.02),
            0u);
  for (std::uint32_t v = 0; v < coarse.num_vertices(); ++v)
    EXPECT_EQ(r.mesh.position(VertexId(v)), coarse.position(VertexId(v)));
}

TEST(Adaptive, ButterflyAtTheLevelCapReportsTheEdgesStillOverTolerance) {
  // The butterfly's stencil assumes regular connectivity; the valence changes where levels
  // meet make its edge points leave the chord, so at a tight tolerance it keeps refining
  // there until the cap. The report must say so rather than pretend the tolerance holds.
  const Mesh coarse = to_mesh(icosphere_soup(1, 10.0));
  const RefineResult r = refine(coarse, adaptive("butterfly", 0.02, 5));
  expect_watertight_manifold(r.mesh);
  EXPECT_EQ(r.report.levels, 5);
  Level final_level{r.mesh, detect_features(r.mesh, {})};
  EXPECT_EQ(
      r.report.edges_over_tolerance,
      count_edges_over_tolerance(final_level, *adaptive_scheme(*make_scheme("butterfly")), 0.02));
  EXPECT_GT(r.report.edges_over_tolerance, 0u);
}

TEST_P(AdaptiveScheme, LooserToleranceGivesFewerFacesThanUniform) {
  const Mesh coarse = to_mesh(torus_soup(16, 8, 20.0, 5.0));
  const RefineResult tight = refine(coarse, adaptive(GetParam(), 0.01, 3));
  const RefineResult loose = refine(coarse, adaptive(GetParam(), 0.2, 3));
  expect_watertight_manifold(tight.mesh);
  expect_watertight_manifold(loose.mesh);
  EXPECT_LT(loose.mesh.num_faces(), tight.mesh.num_faces());
  EXPECT_LE(tight.mesh.num_faces(), 64 * coarse.num_faces());
  EXPECT_GT(loose.mesh.num_faces(), coarse.num_faces());
}

TEST_P(AdaptiveScheme, CylinderSplitsOnlyItsSideAndKeepsCapsPlanarAndRimsSharp) {
  const double radius = 10.0, height = 20.0;
  const Mesh coarse = to_mesh(cylinder_soup(12, radius, height));
  const RefineResult r = refine(coarse, adaptive(GetParam(), 0.01, 4));
  expect_watertight_manifold(r.mesh);
  EXPECT_GT(r.mesh.num_faces(), coarse.num_faces());
  std::size_t on_rims = 0;
  for (const Vec3& p : r.mesh.positions()) {
    const bool on_cap = std::abs(p.z) < 1e-12 || std::abs(p.z - height) < 1e-12;
    if (!on_cap) {
      EXPECT_GT(p.z, 1e-9);
      EXPECT_LT(p.z, height - 1e-9);
      continue;
    }
    const double r_xy = std::hypot(p.x, p.y);
    EXPECT_LE(r_xy, radius + 1e-9);
    on_rims += r_xy > radius - 0.05;  // rim points, refined along the circle
  }
  EXPECT_GT(on_rims, 2u * 12u);  // the rims were refined, not only the side
  // The rim stays a crease: detection at the default angle still finds it sharp.
  const Features f = detect_features(r.mesh, {});
  EXPECT_GE(f.num_sharp_edges(), on_rims);
}

INSTANTIATE_TEST_SUITE_P(Schemes, AdaptiveScheme, ::testing::Values("lsf", "butterfly"));

TEST(Adaptive, FlatFacedInputNeedsNoRefinement) {
  // Every cube vertex is a corner and every edge a crease: the fit reproduces the flat
  // faces and the straight creases, so no edge point leaves its chord.
  const Mesh cube = to_mesh(cube_soup(2.0));
  const RefineResult r = refine(cube, adaptive("lsf", 1e-9, 4));
  EXPECT_EQ(r.report.levels, 0);
  EXPECT_EQ(r.mesh.num_faces(), cube.num_faces());
}

TEST(Adaptive, GreenTrianglesCloseASingleSplitEdge) {
  // A bent strip: only the edges near the fold are over tolerance, so the marking has
  // faces with exactly one marked edge (green) and the result still conforms.
  const Mesh bent = to_mesh(height_field_soup(
      8, 8, -4, -4, 1.0, [](double x, double) { return x > 0 ? 0.0 : 0.05 * x * x * x * x; }));
  AdaptiveSplit4 adaptive(Level{bent, detect_features(bent, {})});
  StepStats stats;
  AdaptiveStepStats step;
  ASSERT_TRUE(adaptive.step(*adaptive_scheme(*make_scheme("lsf")), 0.05, 1u << 20, stats, step));
  const Level* fine = &adaptive.level();
  EXPECT_GT(step.green_faces, 0u);
  EXPECT_GT(step.red_faces, 0u);
  EXPECT_LT(step.red_faces, bent.num_faces());
  EXPECT_EQ(fine->mesh.check_invariants(), "");
  EXPECT_EQ(fine->mesh.num_faces(), bent.num_faces() + 3 * step.red_faces + step.green_faces);
  // Conforming: no T-junction leaves an inner crack. The only boundary half-edges are the
  // coarse boundary's, each split boundary edge adding one; the Euler characteristic holds.
  auto boundary_halfedges = [](const Mesh& m) {
    std::size_t n = 0;
    for (std::uint32_t h = 0; h < m.num_halfedges(); ++h) n += m.is_boundary(HalfedgeId(h));
    return n;
  };
  std::size_t new_boundary_vertices = 0;
  for (std::uint32_t h = 0; h < fine->mesh.num_halfedges(); ++h)
    new_boundary_vertices += fine->mesh.is_boundary(HalfedgeId(h)) &&
                             fine->mesh.from(HalfedgeId(h)).idx >= bent.num_vertices();
  EXPECT_GT(new_boundary_vertices, 0u);
  EXPECT_EQ(boundary_halfedges(fine->mesh), boundary_halfedges(bent) + new_boundary_vertices);
  auto euler = [](const Mesh& m) {
    return static_cast<long>(m.num_vertices()) - static_cast<long>(m.num_edges()) +
           static_cast<long>(m.num_faces());
  };
  EXPECT_EQ(euler(fine->mesh), euler(bent));
}

double min_angle_deg(const Mesh& m) {
  double smallest = 180;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    for (std::uint32_t k = 0; k < 3; ++k) {
      const Vec3 p = m.position(m.from(HalfedgeId(3 * f + k)));
      const Vec3 a = m.position(m.from(HalfedgeId(3 * f + (k + 1) % 3))) - p;
      const Vec3 b = m.position(m.from(HalfedgeId(3 * f + (k + 2) % 3))) - p;
      smallest = std::min(smallest, std::acos(dot(a, b) / (norm(a) * norm(b))) * 180 / M_PI);
    }
  }
  return smallest;
}

TEST(Adaptive, RepeatedStepsNeverBisectAGreenAgain) {
  // Greens are replaced by their red parent before they are refined, so triangle shape stays
  // close to the uniform refinement's however many steps run (bisecting greens again would
  // halve the smallest angle each time).
  const Mesh torus = to_mesh(torus_soup(12, 8, 20.0, 6.0));
  RefineParams uniform;
  uniform.scheme = "lsf";
  uniform.levels = 5;
  const RefineResult full = refine(torus, uniform);
  const RefineResult r = refine(torus, adaptive("lsf", 0.004, 5));
  EXPECT_EQ(r.report.levels, 5);
  expect_watertight_manifold(r.mesh);
  EXPECT_GT(r.mesh.num_faces(), 4 * torus.num_faces());
  EXPECT_LT(r.mesh.num_faces(), full.mesh.num_faces());
  EXPECT_GT(min_angle_deg(r.mesh), 0.5 * min_angle_deg(full.mesh));
  for (std::uint32_t v = 0; v < torus.num_vertices(); ++v)
    EXPECT_EQ(r.mesh.position(VertexId(v)), torus.position(VertexId(v)));
}

TEST(Adaptive, RejectsApproximatingSchemesAndBadRanges) {
  auto field_of = [](const RefineParams& p) {
    try {
      p.validate();
    } catch (const Error& e) {
      return std::string(e.field());
    }
    return std::string("none");
  };
  EXPECT_EQ(field_of(adaptive("loop", 0.1, 3)), "adaptive_tol");
  EXPECT_EQ(field_of(adaptive("lsf", -1, 3)), "adaptive_tol");
  EXPECT_EQ(field_of(adaptive("lsf", std::nan(""), 3)), "adaptive_tol");
  EXPECT_EQ(field_of(adaptive("lsf", 0.1, 0)), "max_level");
  EXPECT_EQ(field_of(adaptive("lsf", 0.1, 9)), "max_level");
  EXPECT_EQ(field_of(adaptive("butterfly", 0.1, 8)), "none");
}

// fuzz_pipeline's findings: both adaptive hosts know their output's edges by vertex pair,
// so on a mesh that is not simple faces overlapped and they failed with an Internal error
// (a 500). Both shapes are refused before any work; uniform levels refine them.
//  - crash-fb7b3439...: a tetrahedron's corner with one facet repeated in reverse; ingest
//    cuts the non-manifold edge apart and leaves two edges between vertices 0 and 2.
//  - crash-02345917...: a facet and its reverse (a closed two-face pillow) among other
//    parts: the inner edges of the two faces' 1-to-4 children join the same vertices.
TEST(Adaptive, RefusesMeshesThatAreNotSimpleBeforeAnyWork) {
  IndexedSoup doubled_edge;
  doubled_edge.positions = {{0, 0, 0}, {0, 2, 0}, {2, 0, 0}, {0, 0, 2}};
  doubled_edge.triangles = {{{0, 1, 2}}, {{0, 2, 3}}, {{0, 3, 1}}, {{2, 0, 3}}};
  IndexedSoup pillow;
  pillow.positions = {{0, 0, 0}, {4, 0, 0}, {0, 3, 1}, {9, 9, 9}, {13, 9, 9}, {9, 12, 9}};
  pillow.triangles = {{{0, 1, 2}}, {{0, 2, 1}}, {{3, 4, 5}}};
  for (const IndexedSoup& soup : {doubled_edge, pillow}) {
    const Mesh mesh = to_mesh(soup);
    for (const char* scheme : {"butterfly", "lsf", "sqrt3-interp", "sqrt3"}) {
      SCOPED_TRACE(scheme);
      try {
        refine(mesh, adaptive(scheme, 1e-6, 2));
        ADD_FAILURE() << "the adaptive mode accepted a mesh that is not simple";
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::NotTriangleMesh) << e.what();
        EXPECT_EQ(e.reason(), "adaptive_non_simple");
      }
    }
    RefineParams uniform;
    uniform.levels = 1;
    EXPECT_EQ(refine(mesh, uniform).mesh.num_faces(), 4 * mesh.num_faces());
  }
}

TEST(Adaptive, FaceBudgetIsCheckedBeforeEachStepIsBuilt) {
  RefineParams p = adaptive("lsf", 1e-6, 6);
  p.max_faces = 2000;
  try {
    refine(to_mesh(icosphere_soup(1, 10.0)), p);
    FAIL() << "expected the face budget to stop the refinement";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::BudgetExceeded);
    EXPECT_EQ(e.field(), "max_faces");
  }
}

TEST(LsfCurvature, SphereCurvaturesAreOneOverRadius) {
  const double radius = 2.5;
  const Mesh sphere = to_mesh(icosphere_soup(3, radius));
  const auto k = vertex_curvatures(sphere, detect_features(sphere, {}));
  const CurvatureSummary s = summarize(k);
  EXPECT_EQ(s.invalid, 0u);
  // Outward winding: the normal c1 x c2 points outwards, so a convex sphere has H < 0.
  for (const VertexCurvature& c : k) {
    ASSERT_TRUE(c.valid);
    EXPECT_NEAR(std::abs(c.mean), 1.0 / radius, 0.03 / radius);
    EXPECT_NEAR(c.gaussian, 1.0 / (radius * radius), 0.06 / (radius * radius));
    EXPECT_NEAR(std::abs(c.k1), 1.0 / radius, 0.05 / radius);
    EXPECT_NEAR(std::abs(c.k2), 1.0 / radius, 0.05 / radius);
  }
  EXPECT_NEAR(s.abs_max.p50, 1.0 / radius, 0.03 / radius);
}

TEST(LsfCurvature, CylinderSideHasOnePrincipalCurvatureZeroAndCornersAreInvalid) {
  const Mesh cube = to_mesh(cube_soup(2.0));
  const auto kc = vertex_curvatures(cube, detect_features(cube, {}));
  for (const VertexCurvature& c : kc) EXPECT_FALSE(c.valid);  // every cube vertex is a corner

  const Mesh plane = to_mesh(grid_soup(4, 4));
  const auto kp = vertex_curvatures(plane, detect_features(plane, {}));
  for (const VertexCurvature& c : kp) {
    if (!c.valid) continue;
    EXPECT_NEAR(c.gaussian, 0.0, 1e-9);
    EXPECT_NEAR(c.mean, 0.0, 1e-9);
  }
  const Mesh torus = to_mesh(torus_soup(48, 24, 20.0, 5.0));
  const auto kt = vertex_curvatures(torus, detect_features(torus, {}));
  // Outer equator: k = 1/r across the tube and 1/(R + r) around the axis.
  for (std::uint32_t v = 0; v < torus.num_vertices(); ++v) {
    const Vec3 p = torus.position(VertexId(v));
    if (std::hypot(p.x, p.y) < 24.99 || std::abs(p.z) > 1e-9) continue;
    const VertexCurvature& c = kt[v];
    ASSERT_TRUE(c.valid);
    EXPECT_NEAR(std::max(std::abs(c.k1), std::abs(c.k2)), 1.0 / 5.0, 0.01);
    EXPECT_NEAR(std::min(std::abs(c.k1), std::abs(c.k2)), 1.0 / 25.0, 0.005);
  }
}

}  // namespace
}  // namespace stlrefine
