// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Adaptive sqrt3 modes that converge (issue 17 item 5), through refine() as a user runs
// them: a tighter tolerance never gives fewer faces nor (beyond sampling) a larger error on
// the CAD-like families, and a run stopped by the level cap says how many faces are over,
// how far and where.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>

#include "core/refine.h"
#include "tests/support/cad_like.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"
#include "tests/support/true_surface.h"

namespace stlrefine::test {
namespace {

RefineParams adaptive(const char* scheme, double tol, int max_level) {
  RefineParams p;
  p.scheme = scheme;
  p.adaptive_tol = tol;
  p.max_level = max_level;
  return p;
}

// Area-weighted RMS distance of face samples (centroid, edge midpoints) from the truth.
double sampled_rms(const Mesh& m, const TrueSurface& surface) {
  double sum = 0, area = 0;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto [ia, ib, ic] = m.face_vertices(FaceId(f));
    const Vec3 a = m.position(ia), b = m.position(ib), c = m.position(ic);
    const double w = 0.5 * norm(cross(b - a, c - a));
    for (const Vec3& p : {(1.0 / 3.0) * (a + b + c), 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)}) {
      const double d = distance(p, surface.closest_point(p).point);
      sum += w * d * d / 4;
    }
    area += w;
  }
  return std::sqrt(sum / area);
}

TEST(AdaptiveSqrt3Convergence, TighterToleranceNeverGivesFewerFacesNorALargerError) {
  for (const CadFamily family :
       {CadFamily::CappedCylinder, CadFamily::Torus, CadFamily::Blob, CadFamily::Tube}) {
    for (const std::uint64_t seed : {5, 6}) {
      const CadShape shape = make_cad_shape(family, {seed, 1.5});
      const Mesh mesh = to_mesh(shape.soup);
      const double diag = bbox_diagonal(mesh);
      SCOPED_TRACE(shape.name + " seed " + std::to_string(seed));
      std::size_t faces = 0;
      double rms = 1e300;
      for (const double tol : {1e-2, 3e-3, 1e-3, 3e-4}) {
        const RefineResult r = refine(mesh, adaptive("sqrt3-interp", tol * diag, 4));
        EXPECT_GE(r.mesh.num_faces(), faces) << "tol " << tol;
        const double e = sampled_rms(r.mesh, *shape.surface);
        EXPECT_LE(e, rms * 1.02) << "tol " << tol;
        EXPECT_EQ(r.report.stop_reason == "tolerance", r.report.faces_over_criterion == 0);
        faces = r.mesh.num_faces();
        rms = e;
      }
    }
  }
}

TEST(AdaptiveSqrt3Convergence, AtTheCapItSaysHowManyFacesAreOverHowFarAndWhere) {
  const Mesh mesh = to_mesh(make_cad_shape(CadFamily::Torus, {1, 1.0}).soup);
  const double tol = 1e-4 * bbox_diagonal(mesh);
  const RefineResult r = refine(mesh, adaptive("sqrt3-interp", tol, 2));
  EXPECT_EQ(r.report.stop_reason, "max_level");
  EXPECT_GT(r.report.faces_over_criterion, 0u);
  // Over the criterion's own limit, tol / 1.22, and finite.
  EXPECT_GT(r.report.max_over_tolerance, tol / 1.23);
  EXPECT_TRUE(std::isfinite(r.report.max_over_tolerance));
  // Where: a point on the part (the centroid of a face at the cap), near the surface.
  double nearest = 1e300;
  for (const Vec3& p : r.mesh.positions())
    nearest = std::min(nearest, distance(p, r.report.worst_over_tolerance_at));
  EXPECT_LT(nearest, 0.1 * bbox_diagonal(mesh));
  // Reached: nothing over, nothing said.
  const RefineResult done = refine(mesh, adaptive("sqrt3-interp", 0.05 * bbox_diagonal(mesh), 6));
  EXPECT_EQ(done.report.stop_reason, "tolerance");
  EXPECT_EQ(done.report.max_over_tolerance, 0.0);
}

}  // namespace
}  // namespace stlrefine::test
