// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Curvature-adaptive 1-to-4 refinement with red-green closure (spec 5 gap 4), and the
// curvatures of the LSF fit.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/refine.h"
#include "core/schemes/adaptive_split4.h"
#include "core/schemes/lsf.h"
#include "core/schemes/lsf_curvature.h"
#include "tests/support/cad_like.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"
#include "tests/support/true_surface.h"

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

// Vertices of `mesh` farther than eps from every vertex of `reference`.
std::size_t vertices_not_in(const Mesh& mesh, const Mesh& reference, double eps) {
  std::vector<Vec3> ref(reference.positions().begin(), reference.positions().end());
  std::sort(ref.begin(), ref.end(), [](const Vec3& a, const Vec3& b) { return a.x < b.x; });
  std::size_t missing = 0;
  for (const Vec3& p : mesh.positions()) {
    auto it = std::lower_bound(ref.begin(), ref.end(), p.x - eps,
                               [](const Vec3& a, double x) { return a.x < x; });
    bool found = false;
    for (; it != ref.end() && it->x <= p.x + eps && !found; ++it) found = distance(*it, p) <= eps;
    missing += !found;
  }
  return missing;
}

TEST(Adaptive, ButterflyReachesItsToleranceWithTheUniformLevelsPoints) {
  // Issue 17: the edge points used to come from the stencil on the conforming mesh, whose
  // green triangles and mixed levels the butterfly is not made for; they left the chord by
  // more at every level and the refinement ran to the cap. Now every leaf is a face of a
  // uniform level and split with that level's points: the tolerance is reached, and every
  // output vertex is a vertex of uniform butterfly at the level reached.
  const Mesh coarse = to_mesh(icosphere_soup(1, 10.0));
  const RefineResult r = refine(coarse, adaptive("butterfly", 0.02, 6));
  expect_watertight_manifold(r.mesh);
  EXPECT_EQ(r.report.stop_reason, "tolerance");
  EXPECT_EQ(r.report.edges_over_tolerance, 0u);
  EXPECT_LT(r.report.levels, 6);
  RefineParams uniform;
  uniform.scheme = "butterfly";
  uniform.levels = r.report.levels;
  const RefineResult u = refine(coarse, uniform);
  EXPECT_LT(r.mesh.num_faces(), u.mesh.num_faces());
  EXPECT_EQ(vertices_not_in(r.mesh, u.mesh, 1e-9), 0u);
}

TEST(Adaptive, EveryOutputVertexIsAVertexOfTheUniformLevelReached) {
  // Per face as accurate as uniform refinement: a leaf of level k is a face of uniform
  // level k. Also on a zipped CAD-like cylinder (slivers, fans, creases), where the
  // stencils' neighbourhoods are most irregular: should a stencil read farther than the
  // uniform regions' margin allows, points would differ here.
  const CadShape cylinder = make_cad_shape(CadFamily::CappedCylinder, {2, 1.0});
  for (const Mesh& coarse : {to_mesh(icosphere_soup(1, 10.0)), to_mesh(cylinder.soup)}) {
    for (const char* scheme : {"lsf", "butterfly"}) {
      SCOPED_TRACE(std::string(scheme) + ", " + std::to_string(coarse.num_faces()) + " faces");
      const RefineResult r = refine(coarse, adaptive(scheme, 0.01, 3));
      RefineParams uniform;
      uniform.scheme = scheme;
      uniform.levels = r.report.levels;
      const RefineResult u = refine(coarse, uniform);
      EXPECT_LE(r.mesh.num_faces(), u.mesh.num_faces());
      // A uniform region walks a vertex's ring from another spoke than the whole level,
      // so sums run in another order; lsf's fits on the zipped slivers amplify that
      // rounding (cylinder, seed 2: 92 vertices differ by more than 1e-7 mm, 9 by more than
      // 1e-6, none by 1e-5; a region margin twice as wide gives the same figures, so it is
      // not the margin). Butterfly's fixed weights stay within 1e-9.
      const double eps = std::string(scheme) == "lsf" ? 2e-5 : 1e-9;
      EXPECT_EQ(vertices_not_in(r.mesh, u.mesh, eps), 0u);
    }
  }
}

TEST(Adaptive, EveryCadLikeFamilyRefinesWatertightAndSaysWhyItStopped) {
  // The uniform regions are cut from the level below by rings of faces; a cut that pinched
  // a vertex (two fans meeting only there) crashed the 1-to-4 step on the region.
  // (Before the fix: butterfly on the tube of seed 1 at 1e-2 of the diagonal, lsf on the
  // torus of seed 2 at 1e-2, among others.)
  for (const CadFamily family : cad_families()) {
    for (const std::uint64_t seed : {1, 2}) {
      const CadShape shape = make_cad_shape(family, {seed, 1.0});
      const Mesh mesh = to_mesh(shape.soup);
      const double tol = 0.01 * bbox_diagonal(mesh);
      for (const char* scheme : {"lsf", "butterfly"}) {
        SCOPED_TRACE(shape.name + " " + std::to_string(seed) + " " + scheme);
        const RefineResult r = refine(mesh, adaptive(scheme, tol, 3));
        expect_watertight_manifold(r.mesh);
        EXPECT_GE(r.mesh.num_faces(), mesh.num_faces());
        EXPECT_TRUE(r.report.stop_reason == "tolerance" || r.report.stop_reason == "max_level");
        EXPECT_EQ(r.report.stop_reason == "max_level", r.report.edges_over_tolerance > 0);
        EXPECT_EQ(r.report.edges_over_tolerance > 0, r.report.max_over_tolerance > tol);
      }
    }
  }
}

TEST(Adaptive, AtTheLevelCapItSaysHowManyEdgesAreOverTheToleranceHowFarAndWhere) {
  const Mesh coarse = to_mesh(icosphere_soup(1, 10.0));
  for (const char* scheme : {"lsf", "butterfly"}) {
    SCOPED_TRACE(scheme);
    const double tol = 1e-4;
    const RefineResult r = refine(coarse, adaptive(scheme, tol, 2));
    EXPECT_EQ(r.report.levels, 2);
    EXPECT_EQ(r.report.stop_reason, "max_level");
    EXPECT_GT(r.report.edges_over_tolerance, 0u);
    EXPECT_GT(r.report.max_over_tolerance, tol);
    // Where the scheme converges no edge is reported as not converging.
    EXPECT_EQ(r.report.edges_not_converging, 0u);
    // It converges: one level less leaves edges farther off their chords.
    const RefineResult one = refine(coarse, adaptive(scheme, tol, 1));
    EXPECT_EQ(one.report.stop_reason, "max_level");
    EXPECT_LT(r.report.max_over_tolerance, 0.5 * one.report.max_over_tolerance);
    EXPECT_NEAR(norm(r.report.worst_over_tolerance_at), 10.0, 0.1);
    // A tolerance met everywhere says so.
    const RefineResult loose = refine(coarse, adaptive(scheme, 1.0, 2));
    EXPECT_EQ(loose.report.stop_reason, "tolerance");
    EXPECT_EQ(loose.report.edges_over_tolerance, 0u);
    EXPECT_EQ(loose.report.max_over_tolerance, 0.0);
  }
}

TEST(Adaptive, TheIssuesIcosphereTighterToleranceNoLongerGivesFewerFaces) {
  // Issue 17's case: butterfly on an icosphere of 1,280 faces (radius 10), max_level 4, at
  // 3e-4 and 1e-4 of the bbox diagonal. Before the fix: 156,080 faces with 66,660 edges
  // over tolerance, then 114,680 faces (bench/results-issue17-adaptive.md). Now the looser
  // one reaches its tolerance at level 3 and the tighter one makes more faces.
  const Mesh coarse = to_mesh(icosphere_soup(3, 10.0));
  const double diag = bbox_diagonal(coarse);
  const RefineResult loose = refine(coarse, adaptive("butterfly", 3e-4 * diag, 4));
  const RefineResult tight = refine(coarse, adaptive("butterfly", 1e-4 * diag, 4));
  EXPECT_EQ(loose.report.stop_reason, "tolerance");
  EXPECT_EQ(loose.report.levels, 3);
  EXPECT_LT(loose.mesh.num_faces(), 20'000u);
  EXPECT_GT(tight.mesh.num_faces(), loose.mesh.num_faces());
  expect_watertight_manifold(tight.mesh);
}

TEST(Adaptive, SaysWhereTheSchemesOwnLevelsDoNotConverge) {
  // butterfly on the zipped rounded box: next to the fillets' fans its own levels do not
  // approach a limit at the rate a smooth scheme does (uniform butterfly there is no better
  // than the input at L2-L3, bench/results-issue17-creases.md). Refining more cannot reach
  // the tolerance there, and the report says so. (lsf on a coarse zipped cylinder was the
  // example until lsf's edge points were fixed for such meshes.)
  // Seed 3 was in this list until round 6: its 2 false creases (core/features) were part of
  // why it did not converge; with them gone its 7 edges over tolerance still converge (the
  // report says 0 not converging), so seed 4 (10 of 16 not converging) replaces it.
  for (const std::uint64_t seed : {1, 2, 4}) {
    SCOPED_TRACE(seed);
    const CadShape shape = make_cad_shape(CadFamily::RoundedBox, {seed, 1.0});
    const Mesh mesh = to_mesh(shape.soup);
    const RefineResult r = refine(mesh, adaptive("butterfly", 0.01 * bbox_diagonal(mesh), 3));
    EXPECT_EQ(r.report.stop_reason, "max_level");
    EXPECT_GT(r.report.edges_not_converging, 0u);
    EXPECT_LE(r.report.edges_not_converging, r.report.edges_over_tolerance);
  }
}

// Area-weighted RMS distance of face sample points (centroid and the three edge midpoints)
// from the true surface.
double sampled_rms(const Mesh& m, const TrueSurface& surface) {
  double sum = 0, area = 0;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const Vec3 a = m.position(m.from(HalfedgeId(3 * f))),
               b = m.position(m.from(HalfedgeId(3 * f + 1))),
               c = m.position(m.from(HalfedgeId(3 * f + 2)));
    const double w = 0.5 * norm(cross(b - a, c - a));
    for (const Vec3& p : {(1.0 / 3.0) * (a + b + c), 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)}) {
      const double d = distance(p, surface.closest_point(p).point);
      sum += w * d * d / 4;
    }
    area += w;
  }
  return std::sqrt(sum / area);
}

TEST(Adaptive, TighterToleranceNeverGivesFewerFacesNorALargerErrorOnCadLikeMeshes) {
  // Issue 17: a tighter tolerance gave fewer faces (butterfly) and a larger error (lsf on
  // the zipped cylinder). Leaves split with the uniform levels' points make a tighter
  // tolerance split a superset of the leaves.
  for (const CadFamily family : {CadFamily::CappedCylinder, CadFamily::Torus}) {
    const CadShape shape = make_cad_shape(family, {3, 1.0});
    const Mesh mesh = to_mesh(shape.soup);
    for (const char* scheme : {"lsf", "butterfly"}) {
      SCOPED_TRACE(shape.name + " " + scheme);
      std::size_t faces = 0;
      double rms = 1e300;
      for (const double tol : {0.2, 0.05, 0.02, 0.005}) {
        const RefineResult r = refine(mesh, adaptive(scheme, tol, 2));
        expect_watertight_manifold(r.mesh);
        EXPECT_GE(r.mesh.num_faces(), faces) << "tol " << tol;
        const double e = sampled_rms(r.mesh, *shape.surface);
        EXPECT_LE(e, rms * 1.02) << "tol " << tol;
        EXPECT_FALSE(r.report.stop_reason.empty());
        EXPECT_EQ(r.report.stop_reason == "tolerance", r.report.edges_over_tolerance == 0);
        faces = r.mesh.num_faces();
        rms = e;
      }
    }
  }
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

TEST(Adaptive, GreenClosureNeverBendsASliverOver) {
  // A sliver leaf beside a red one, whose split side's butterfly point bulges past its
  // opposite corner (a rim chord next to a cap sliver, a zipped strip), was bisected green
  // and its half turned over: 1-3 faces folded against the truth on these runs (180 deg on
  // the cylinder's caps). Such a leaf is split red now, as uniform refinement splits it.
  struct Run {
    CadFamily family;
    std::uint64_t seed;
  };
  for (const Run run : {Run{CadFamily::CappedCylinder, 9000}, Run{CadFamily::CappedCylinder, 9001},
                        Run{CadFamily::Cone, 9005}, Run{CadFamily::Plate, 9002}}) {
    const CadShape shape = make_cad_shape(run.family, {run.seed, 1.0});
    SCOPED_TRACE(shape.name + " " + std::to_string(run.seed));
    const Mesh mesh = to_mesh(shape.soup);
    const RefineResult r = refine(mesh, adaptive("butterfly", 1e-3 * bbox_diagonal(mesh), 4));
    expect_watertight_manifold(r.mesh);
    EXPECT_EQ(faces_off_truth(r.mesh, *shape.surface, 90), 0u);
  }
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

// fuzz_pipeline's findings: both adaptive hosts knew their output's edges by vertex pair,
// so on a mesh that is not simple faces overlapped and they failed with an Internal error
// (a 500); both shapes were then refused before any work.
//  - crash-fb7b3439...: a tetrahedron's corner with one facet repeated in reverse; ingest
//    cuts the non-manifold edge apart and leaves two edges between vertices 0 and 2.
//  - crash-02345917...: a facet and its reverse (a closed two-face pillow) among other
//    parts: the inner edges of the two faces' 1-to-4 children join the same vertices.
// AdaptiveSplit4 now knows edges by identity and refines both; the adaptive sqrt3 host
// still refuses them before any work.
IndexedSoup doubled_edge_soup() {
  IndexedSoup s;
  s.positions = {{0, 0, 0}, {0, 2, 0}, {2, 0, 0}, {0, 0, 2}};
  s.triangles = {{{0, 1, 2}}, {{0, 2, 3}}, {{0, 3, 1}}, {{2, 0, 3}}};
  return s;
}

IndexedSoup pillow_soup() {
  IndexedSoup s;
  s.positions = {{0, 0, 0}, {4, 0, 0}, {0, 3, 1}, {9, 9, 9}, {13, 9, 9}, {9, 12, 9}};
  s.triangles = {{{0, 1, 2}}, {{0, 2, 1}}, {{3, 4, 5}}};
  return s;
}

// A closed, curved mesh that is not simple: an icosphere with one facet repeated in
// reverse. Each of the facet's edges then has three facets; ingest cuts them apart and
// leaves two edges between each pair of the facet's corners.
IndexedSoup sphere_with_reversed_facet_soup() {
  IndexedSoup s = icosphere_soup(2, 10.0);
  const auto t = s.triangles[0];
  s.triangles.push_back({{t[0], t[2], t[1]}});
  return s;
}

bool is_simple(const Mesh& mesh) {
  try {
    require_simple_mesh(mesh);
  } catch (const Error&) {
    return false;
  }
  return true;
}

// The boundary loops of a mesh as cyclic sequences of the vertices below `keep` (input
// vertices keep their ids), each rotated to start at its smallest vertex, sorted.
std::vector<std::vector<std::uint32_t>> boundary_loops(const Mesh& m, std::uint32_t keep) {
  std::vector<HalfedgeId> out_of(m.num_vertices());
  for (std::uint32_t h = 0; h < m.num_halfedges(); ++h)
    if (m.is_boundary(HalfedgeId(h))) out_of[m.from(HalfedgeId(h)).idx] = HalfedgeId(h);
  std::vector<std::uint8_t> seen(m.num_halfedges(), 0);
  std::vector<std::vector<std::uint32_t>> loops;
  for (std::uint32_t h0 = 0; h0 < m.num_halfedges(); ++h0) {
    if (!m.is_boundary(HalfedgeId(h0)) || seen[h0]) continue;
    std::vector<std::uint32_t> loop;
    for (HalfedgeId h(h0); h.valid() && !seen[h.idx]; h = out_of[m.to(h).idx]) {
      seen[h.idx] = 1;
      if (m.from(h).idx < keep) loop.push_back(m.from(h).idx);
    }
    if (!loop.empty())
      std::rotate(loop.begin(), std::min_element(loop.begin(), loop.end()), loop.end());
    loops.push_back(loop);
  }
  std::sort(loops.begin(), loops.end());
  return loops;
}

// Watertight and conforming: a valid half-edge mesh whose boundary loops are the input's,
// only subdivided (a crack or a T-junction inside would add a loop or break one), input
// vertices untouched, and every edge within tolerance when the refinement stopped early.
void expect_adaptive_output_is_sound(const Mesh& in, const char* scheme, double tol) {
  SCOPED_TRACE(scheme);
  const RefineResult r = refine(in, adaptive(scheme, tol, 6));
  EXPECT_EQ(r.mesh.check_invariants(), "");
  const auto nv = static_cast<std::uint32_t>(in.num_vertices());
  EXPECT_EQ(boundary_loops(r.mesh, nv), boundary_loops(in, nv));
  for (std::uint32_t v = 0; v < nv; ++v)
    EXPECT_EQ(r.mesh.position(VertexId(v)), in.position(VertexId(v)));
  EXPECT_GT(r.report.levels, 0);
  if (r.report.levels < 6) {
    EXPECT_EQ(r.report.edges_over_tolerance, 0u);
    const Level final_level{r.mesh, detect_features(r.mesh, {})};
    EXPECT_EQ(count_edges_over_tolerance(final_level, *adaptive_scheme(*make_scheme(scheme)), tol),
              0u);
  }
}

TEST(Adaptive, RefinesMeshesThatAreNotSimpleLikeSimpleOnes) {
  for (const IndexedSoup& soup :
       {doubled_edge_soup(), pillow_soup(), sphere_with_reversed_facet_soup()}) {
    const Mesh mesh = to_mesh(soup);
    ASSERT_FALSE(is_simple(mesh));
    for (const char* scheme : {"lsf", "butterfly"})
      expect_adaptive_output_is_sound(mesh, scheme, soup.positions.size() > 6 ? 0.05 : 0.01);
  }
}

// A closed manifold that is not simple: a torus with only two vertex rings around the
// tube. Going up from ring 0 to ring 1 and on from ring 1 back to ring 0 gives two distinct
// edges between each pair (0, j), (1, j). Ingest, seeing each directed pair twice, would
// cut them apart, so the mesh is assembled here with its twins given explicitly. Each
// band's quads are split along a different diagonal, so no two faces share three vertices.
Mesh two_ring_torus(int n) {
  BigVector<Vec3> positions;
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < n; ++j) {
      const double a = 2 * M_PI * (j + 0.5 * i) / n, rho = i == 0 ? 10.0 : 6.0;
      positions.push_back({rho * std::cos(a), rho * std::sin(a), i == 0 ? 2.0 : -2.0});
    }
  }
  auto at = [n](int i, int j) { return VertexId(static_cast<std::uint32_t>(i * n + (j % n))); };
  // Edge keys: rings (i, j) -> (i, j+1), the two bands' verticals at j, the diagonals.
  auto ring = [n](int i, int j) { return i * n + j % n; };
  auto vertical = [n](int band, int j) { return 2 * n + band * n + j % n; };
  auto diagonal = [n](int band, int j) { return 4 * n + band * n + j; };
  BigVector<VertexId> corners;
  std::vector<int> keys;
  auto add = [&](std::array<VertexId, 3> v, std::array<int, 3> k) {
    corners.insert(corners.end(), v.begin(), v.end());
    keys.insert(keys.end(), k.begin(), k.end());
  };
  for (int j = 0; j < n; ++j) {
    // Band 0: (0,j) (0,j+1) (1,j+1) (1,j), diagonal (0,j)-(1,j+1).
    add({at(0, j), at(0, j + 1), at(1, j + 1)}, {ring(0, j), vertical(0, j + 1), diagonal(0, j)});
    add({at(0, j), at(1, j + 1), at(1, j)}, {diagonal(0, j), ring(1, j), vertical(0, j)});
    // Band 1: (1,j) (1,j+1) (0,j+1) (0,j), diagonal (1,j)-(0,j+1).
    add({at(1, j), at(1, j + 1), at(0, j + 1)}, {ring(1, j), vertical(1, j + 1), diagonal(1, j)});
    add({at(1, j), at(0, j + 1), at(0, j)}, {diagonal(1, j), ring(0, j), vertical(1, j)});
  }
  BigVector<HalfedgeId> twin(corners.size());
  std::vector<int> first(6 * n, -1);
  for (std::size_t h = 0; h < keys.size(); ++h) {
    int& other = first[keys[h]];
    if (other < 0) {
      other = static_cast<int>(h);
    } else {
      twin[h] = HalfedgeId(static_cast<std::uint32_t>(other));
      twin[other] = HalfedgeId(static_cast<std::uint32_t>(h));
    }
  }
  return Mesh::from_parts(std::move(positions), std::move(corners), std::move(twin));
}

TEST(Adaptive, AClosedMeshThatIsNotSimpleStaysClosed) {
  const Mesh mesh = two_ring_torus(12);
  ASSERT_FALSE(is_simple(mesh));
  ASSERT_EQ(mesh.check_invariants(), "");
  ASSERT_TRUE(boundary_loops(mesh, static_cast<std::uint32_t>(mesh.num_vertices())).empty());
  for (const char* scheme : {"lsf", "butterfly"}) {
    SCOPED_TRACE(scheme);
    const RefineResult r = refine(mesh, adaptive(scheme, 0.05, 3));
    expect_watertight_manifold(r.mesh);
    EXPECT_GT(r.mesh.num_faces(), mesh.num_faces());
    expect_adaptive_output_is_sound(mesh, scheme, 0.05);
  }
}

TEST(Adaptive, Sqrt3SchemesStillRefuseMeshesThatAreNotSimpleBeforeAnyWork) {
  for (const IndexedSoup& soup : {doubled_edge_soup(), pillow_soup()}) {
    const Mesh mesh = to_mesh(soup);
    for (const char* scheme : {"sqrt3-interp", "sqrt3"}) {
      SCOPED_TRACE(scheme);
      try {
        refine(mesh, adaptive(scheme, 1e-6, 2));
        ADD_FAILURE() << "the adaptive sqrt3 mode accepted a mesh that is not simple";
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
