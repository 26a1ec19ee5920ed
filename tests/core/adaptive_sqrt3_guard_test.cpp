// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The adaptive sqrt3 host's fold guard (issue 17 item 2): an edge whose flip would fold is
// not flipped and a face point whose fine faces fold moves towards its face's centroid, as
// in the uniform host (sqrt3_refine, same tests and kSqrt3FoldAngleDeg), on the CAD-like
// meshes of tests/support, checked against their true surfaces.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "core/refine.h"
#include "core/schemes/adaptive_sqrt3.h"
#include "tests/core/test_util.h"
#include "tests/support/cad_like.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"
#include "tests/support/true_surface.h"

namespace stlrefine::test {
namespace {

struct Outcome {
  Level level;
  Sqrt3AdaptiveStats stats;
};

Outcome adapt(const Level& coarse, const char* scheme, Sqrt3AdaptiveCriteria c, FoldGuard guard) {
  const auto s = make_scheme(scheme);
  c.guard = guard;
  AdaptiveSqrt3 adaptive(coarse, *adaptive_sqrt3_scheme(*s), c);
  adaptive.run(1u << 24);
  Outcome out;
  out.level = adaptive.result();
  out.stats = adaptive.stats();
  return out;
}

void expect_closed_manifold(const Mesh& m) {
  ASSERT_EQ(m.check_invariants(), "");
  for (std::uint32_t h = 0; h < m.num_halfedges(); ++h)
    ASSERT_FALSE(m.is_boundary(HalfedgeId(h))) << "half-edge " << h;
}

TEST(AdaptiveSqrt3Guard, FoldsLessAgainstTheTruthAndStaysWatertight) {
  // Faces more than 90 degrees from the true normal ("folded", issue 17), guarded against
  // unguarded, for the interpolating and the approximating stencil. Measured (tol 2e-3 of
  // the diagonal, 4 steps): sqrt3-interp 23 against 3,708 folded faces over these 12
  // meshes (354 before the guard's rounds and passes), 0 on the sphere and the blob (15-33
  // unguarded); Kobbelt's sqrt3 1 against 1.
  std::size_t folded_guarded = 0, folded_unguarded = 0, kept = 0, pulled = 0;
  for (const CadFamily family : {CadFamily::CappedCylinder, CadFamily::Torus, CadFamily::Sphere,
                                 CadFamily::Blob, CadFamily::RoundedBox, CadFamily::Tube}) {
    for (const std::uint64_t seed : {1, 2}) {
      const CadShape shape = make_cad_shape(family, {seed, 1.0});
      const Level coarse = make_level(to_mesh(shape.soup), 35);
      const double tol = 2e-3 * bbox_diagonal(coarse.mesh);
      for (const char* scheme : {"sqrt3-interp", "sqrt3"}) {
        SCOPED_TRACE(shape.name + " seed " + std::to_string(seed) + " " + scheme);
        const Outcome on = adapt(coarse, scheme, {0, tol, 4}, FoldGuard::AsStencil);
        const Outcome off = adapt(coarse, scheme, {0, tol, 4}, FoldGuard::Off);
        expect_closed_manifold(on.level.mesh);
        const std::size_t a = faces_off_truth(on.level.mesh, *shape.surface, 90);
        const std::size_t b = faces_off_truth(off.level.mesh, *shape.surface, 90);
        std::printf(
            "guard %-12s seed %d %-12s faces %zu / %zu folded %zu / %zu kept %zu pulled %zu\n",
            shape.name.c_str(), int(seed), scheme, on.level.mesh.num_faces(),
            off.level.mesh.num_faces(), a, b, on.stats.flips_kept, on.stats.face_points_pulled);
        folded_guarded += a;
        folded_unguarded += b;
        kept += on.stats.flips_kept;
        pulled += on.stats.face_points_pulled;
        if (std::string(scheme) == "sqrt3-interp") {
          EXPECT_LE(a, b);
        }
        if (std::string(scheme) == "sqrt3-interp") {  // the input vertices stay where they are
          for (std::uint32_t v = 0; v < coarse.mesh.num_vertices(); ++v)
            ASSERT_EQ(on.level.mesh.position(VertexId(v)), coarse.mesh.position(VertexId(v)));
        }
      }
    }
  }
  EXPECT_GT(kept, 0u);  // the guard acted, both halves
  EXPECT_GT(pulled, 0u);
  EXPECT_LT(10 * folded_guarded, folded_unguarded);
}

TEST(AdaptiveSqrt3Guard, PullsAgainstTheNeighboursPulledPointsOnTheRoundedBox) {
  // Issue 17 item 2: faces more than 60 degrees from the true normal. The guard once pulled
  // each face point against its neighbours' stencil points and decided each flip once
  // against the stencil's points: where both face points of a flipped edge were pulled,
  // nobody checked the pair, and 248 / 259 faces (165 / 167 over 90 degrees) were left on
  // these two meshes, uniform sqrt3-interp 0. Now (rounds against the neighbours' pulled
  // points, a second pass over the flips) 8 / 4, all beside the creases the 35 degree
  // angle marks (the trisection points are not pulled; bench/results-issue17-s6-adaptive.md).
  for (const std::uint64_t seed : {1, 2}) {
    const CadShape shape = make_cad_shape(CadFamily::RoundedBox, {seed, 1.0});
    const Level coarse = make_level(to_mesh(shape.soup), 35);
    SCOPED_TRACE("seed " + std::to_string(seed));
    const double tol = 2e-3 * bbox_diagonal(coarse.mesh);
    const Outcome on = adapt(coarse, "sqrt3-interp", {0, tol, 4}, FoldGuard::AsStencil);
    expect_closed_manifold(on.level.mesh);
    EXPECT_LE(faces_off_truth(on.level.mesh, *shape.surface, 60), 10u);
    EXPECT_LE(faces_off_truth(on.level.mesh, *shape.surface, 90), 3u);
    // Refining everything to the same depth: uniform sqrt3-interp leaves 0 there.
    const Outcome all = adapt(coarse, "sqrt3-interp", {0, 1e-12, 1}, FoldGuard::AsStencil);
    EXPECT_EQ(faces_off_truth(all.level.mesh, *shape.surface, 60), 0u);
  }
}

TEST(AdaptiveSqrt3Guard, WithoutAnEdgeToKeepItIsTheUnguardedHierarchy) {
  // A smooth regular mesh where no flip folds: the guard changes nothing, bit for bit.
  const Level coarse = make_level(to_mesh(icosphere_soup(2, 10.0)), 35);
  const Sqrt3AdaptiveCriteria c{0, 1e-3 * bbox_diagonal(coarse.mesh), 3};
  const Outcome on = adapt(coarse, "sqrt3-interp", c, FoldGuard::AsStencil);
  const Outcome off = adapt(coarse, "sqrt3-interp", c, FoldGuard::Off);
  ASSERT_EQ(on.stats.flips_kept, 0u);
  ASSERT_GT(on.level.mesh.num_faces(), coarse.mesh.num_faces());
  EXPECT_TRUE(triangle_set(on.level.mesh, false) == triangle_set(off.level.mesh, false));
}

TEST(AdaptiveSqrt3Guard, ToleranceTowardsZeroComesNearTheGuardedUniformLevel) {
  // Without the guard a tolerance that refines everything gives the uniform level exactly
  // (AdaptiveSqrt3.RefiningEverythingGivesTheUniformLevel). With it, the documented
  // difference (bench/results-issue17-s4-adaptive.md): the uniform host iterates its guard
  // over the whole level, this one decides each edge and face point once
  // (adaptive_sqrt3_guard.cpp, in a fixed depth of local rounds and passes): 0-1 faces
  // folded against the truth where the uniform level has none; and a few slivers beside
  // kept flips are never refined because the finer surface lies wholly outside their prism
  // (the criterion measures inside it, and finds 0 there): 1.1 % fewer faces on the torus,
  // the blob's count equal.
  for (const CadFamily family : {CadFamily::Blob, CadFamily::Torus}) {
    const CadShape shape = make_cad_shape(family, {1, 1.5});
    const Level coarse = make_level(to_mesh(shape.soup), 35);
    SCOPED_TRACE(shape.name);
    const int levels = 3;
    const Outcome a = adapt(coarse, "sqrt3-interp", {0, 1e-12, levels}, FoldGuard::AsStencil);
    std::size_t fallbacks = 0;
    const Level u = refine_levels("sqrt3-interp", coarse, levels, &fallbacks);
    expect_closed_manifold(a.level.mesh);
    EXPECT_LE(a.level.mesh.num_faces(), u.mesh.num_faces());
    EXPECT_GE(a.level.mesh.num_faces(), 0.98 * double(u.mesh.num_faces()));
    std::printf(
        "everything %s: faces %zu, uniform guard fallbacks %zu, adaptive kept %zu, folded "
        "adaptive %zu uniform %zu\n",
        shape.name.c_str(), a.level.mesh.num_faces(), fallbacks, a.stats.flips_kept,
        faces_off_truth(a.level.mesh, *shape.surface, 90),
        faces_off_truth(u.mesh, *shape.surface, 90));
  }
}

TEST(AdaptiveSqrt3Guard, PlateSliversSurviveTheFloatOutput) {
  // The adaptive counterpart of Sqrt3Cad.PlateSliversSurviveTheFloatOutput: the plate read
  // from its STL, refined by adaptive sqrt3-interp at a fine tolerance (1e-6 of the
  // diagonal, up to 6 steps), written as float coordinates. Without the uniform host's
  // degenerate test, seed 9006 kept 2 faces lower than 2 float ulps of their coordinates,
  // and 2 faces 90 degrees off the truth (1e-5: one below the grid); now the adaptive guard
  // shares it (sqrt3_degenerate.h): none below the grid, none turned over by the float
  // output. Faces more than 60 degrees off: 0, but for seed 9502's 2 (before: 3), which lie
  // in the end face's plane a hair outside the rounded side (the crease curve past the true
  // rim; their closest points are all on the side), not folds: counted past 90 as the
  // uniform test does.
  std::size_t off60 = 0;
  for (const std::uint64_t seed : {9002, 9006, 9008, 9501, 9502}) {
    const CadShape shape = make_cad_shape(CadFamily::Plate, {seed, 1.0});
    const Mesh input = float_rounded(to_mesh(shape.soup));  // as read from its STL
    RefineParams params;
    params.scheme = "sqrt3-interp";
    params.adaptive_tol = 1e-6 * bbox_diagonal(input);
    params.max_level = 6;
    const Mesh out = refine(Mesh(input), params).mesh;
    const Mesh stl = float_rounded(out);
    const auto [reversed, below_grid] = float_rounding(out);
    const std::size_t off = faces_off_truth(stl, *shape.surface, 60);
    std::printf("adaptive plate seed %d: faces %zu reversed %zu below grid %zu off 60 %zu\n",
                int(seed), out.num_faces(), reversed, below_grid, off);
    off60 += off;
    EXPECT_EQ(reversed, 0u) << "seed " << seed;
    EXPECT_EQ(below_grid, 0u) << "seed " << seed;
    EXPECT_EQ(faces_off_truth(stl, *shape.surface, 90), 0u) << "seed " << seed;
  }
  EXPECT_LE(off60, 2u);
}

}  // namespace
}  // namespace stlrefine::test
