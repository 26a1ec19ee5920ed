// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// LSF on CAD-like tessellations (issue 17 items 2 and 3 for lsf): on every family of
// tests/support/cad_like.h and a few small seeds, one and two levels of lsf are never
// farther from the true surface (sampled RMS) than the input, turn no face more than 60
// degrees from the true normal, keep the input vertices bit for bit, and keep planar regions
// (the cylinder's caps, the plate's flat faces) planar.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "core/geometry/point_triangle.h"
#include "core/schemes/lsf.h"
#include "tests/core/test_util.h"
#include "tests/support/cad_like.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"
#include "tests/support/true_surface.h"

namespace stlrefine {
namespace {

using namespace test;

constexpr std::array<std::uint64_t, 3> kSeeds{1, 2, 3};

// The largest angle (degrees) between a face's normal and the true normal at its centroid's
// closest point (at a crease: to the arc of normals there).
double worst_normal_deg(const Mesh& m, const TrueSurface& surface) {
  double worst = 0;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto [i, j, l] = m.face_vertices(FaceId(f));
    const Vec3 a = m.position(i), b = m.position(j), c = m.position(l);
    const Vec3 n = normalized(triangle_normal(a, b, c));
    if (norm(n) == 0) continue;
    worst = std::max(worst, normal_angle_deg(surface.closest_point((a + b + c) * (1.0 / 3)), n));
  }
  return worst;
}

// The crease angle that marks only the true creases of a family: the cylinder's, cone's and
// tube's rims (71-108 degrees) and none of the smooth families' edges (coarse tori and
// rounded boxes have dihedrals up to ~45 degrees) at 60. The plate has none: its flat faces
// meet its rounded sides at 6-12 degrees, less than its arcs' own dihedrals, so it keeps the
// default.
double true_crease_angle(CadFamily family) {
  return family == CadFamily::Plate ? 35.0 : 60.0;
}

// Issue 17's targets for lsf on every family and the seeds above, levels 1-3: the sampled RMS
// distance to the truth never above the input's; no face more than 60 degrees from the true
// normal; input vertices bit for bit; closed and manifold in, closed and manifold out. With
// `crease_angle_of(family)` as the crease angle. `two_level_ratio` gets, per family, the mean
// over the seeds of the 2-level RMS / the input's.
template <class CreaseAngleOf>
void check_targets(CreaseAngleOf&& crease_angle_of, bool check_normals_everywhere,
                   std::vector<double>& two_level_ratio) {
  for (const CadFamily family : cad_families()) {
    double sum = 0;
    for (const std::uint64_t seed : kSeeds) {
      const CadShape shape = make_cad_shape(family, {seed, 1.0});
      const Level coarse = make_level(to_mesh(shape.soup), crease_angle_of(family));
      const double input_rms = sampled_rms_distance(coarse.mesh, *shape.surface, 8);
      Level level = coarse;
      for (int l = 1; l <= 3; ++l) {
        level = refine_level("lsf", level);
        const std::string where =
            shape.name + " seed " + std::to_string(seed) + " level " + std::to_string(l);
        const double rms =
            sampled_rms_distance(level.mesh, *shape.surface, l == 1 ? 4 : (l == 2 ? 2 : 1));
        EXPECT_LE(rms, input_rms) << where;
        if (l == 2) sum += rms / input_rms;
        // Open at the default 35 degrees (see bench/results-issue17-lsf.md): the torus, which
        // the angle cuts with false creases, and the rounded box, whose fillet ends meet the
        // corner patches, have a few faces past 60 degrees.
        if (check_normals_everywhere ||
            (family != CadFamily::Torus && family != CadFamily::RoundedBox)) {
          EXPECT_LE(worst_normal_deg(level.mesh, *shape.surface), 60.0) << where;
        }
        for (std::uint32_t v = 0; v < coarse.mesh.num_vertices(); ++v)
          ASSERT_EQ(level.mesh.position(VertexId(v)), coarse.mesh.position(VertexId(v))) << where;
        EXPECT_EQ(level.mesh.check_invariants(), "") << where;
        for (std::uint32_t h = 0; h < level.mesh.num_halfedges(); ++h)
          ASSERT_FALSE(level.mesh.is_boundary(HalfedgeId(h))) << where;
      }
    }
    two_level_ratio.push_back(sum / kSeeds.size());
  }
}

TEST(LsfCad, NeverWorseThanTheInputAndNoFaceOver60Degrees) {
  std::vector<double> ratio;
  check_targets([](CadFamily) { return 35.0; }, false, ratio);
}

// Issue 17 item 3: two levels at most 0.25x the input's RMS (the mean over the seeds). Met
// with the true creases on these seeds by the cylinder (0.11), cone (0.11; 0.257 before the
// crease normals and Hermite midpoints of bench/results-issue17-s5-lsf.md), torus, tube,
// sphere, ellipsoid, blob and the rounded box (0.106; 0.397 before the converged relaxed
// normals of bench/results-issue17-s7-lsf.md, 0.515 before the relaxed guard normals, 0.83
// before those of bench/results-issue17-lsf3.md); missed by the plate, whose 6-12 degree
// creases the 35 degree angle here leaves smooth (0.358; 0.276 before round 7: the seam
// vertices' normals relaxed across that unmarked crease, where the chord symmetry does not
// hold; with the default auto creases, which mark it, 3.01x -> 3.14x the ideal on these
// seeds): for it the bound asserted is today's, so that it cannot get worse unnoticed, and
// the target stays open.
TEST(LsfCad, WithTheTrueCreasesNoFaceOver60DegreesAndTwoLevelsAQuarterOfTheInput) {
  std::vector<double> ratio;
  check_targets(true_crease_angle, true, ratio);
  ASSERT_FALSE(HasFatalFailure());
  const auto families = cad_families();
  for (std::size_t i = 0; i < families.size(); ++i) {
    // Today's figures on these seeds where the target is missed.
    const double bound = families[i] == CadFamily::Plate ? 0.37  // 0.358
                                                         : 0.25;
    EXPECT_LE(ratio[i], bound) << cad_family_name(families[i]);
  }
}

// Every vertex of the faces refined from an input face on a plane of the true surface lies
// on that plane, to 1e-9 of the bounding box diagonal. Face 4f + k of a 1-to-4 level comes
// from face f, so the descendants of input face f after two levels are 16f .. 16f + 15.
void expect_planar_regions_stay_planar(CadFamily family, double crease_angle_deg) {
  for (const std::uint64_t seed : kSeeds) {
    const CadShape shape = make_cad_shape(family, {seed, 1.0});
    const Level coarse = make_level(to_mesh(shape.soup), crease_angle_deg);
    const Level fine = refine_levels("lsf", coarse, 2);
    const Mesh& m = coarse.mesh;
    const double tolerance = 1e-9 * bbox_diagonal(m);
    std::size_t planar_faces = 0;
    for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
      const auto corners = m.face_vertices(FaceId(f));
      const Vec3 a = m.position(corners[0]);
      const Vec3 n = normalized(triangle_normal(a, m.position(corners[1]), m.position(corners[2])));
      // On a plane of the surface: the true normal is the face's at its corners and centroid
      // (off creases: the normal there, on creases: one of the two).
      bool planar = true;
      Vec3 centroid;
      for (VertexId v : corners) centroid += (1.0 / 3) * m.position(v);
      for (const Vec3& p :
           {m.position(corners[0]), m.position(corners[1]), m.position(corners[2]), centroid}) {
        const SurfacePoint s = shape.surface->closest_point(p);
        planar =
            planar && (norm(cross(s.normal, n)) < 1e-9 || norm(cross(s.other_normal, n)) < 1e-9);
      }
      if (!planar) continue;
      ++planar_faces;
      for (std::uint32_t child = 16 * f; child < 16 * f + 16; ++child)
        for (VertexId v : fine.mesh.face_vertices(FaceId(child)))
          EXPECT_NEAR(dot(fine.mesh.position(v) - a, n), 0.0, tolerance)
              << shape.name << " seed " << seed << " face " << f << " child " << child;
    }
    EXPECT_GE(planar_faces, 4u) << shape.name << " seed " << seed;
  }
}

TEST(LsfCad, CylinderCapsStayPlanar) {
  expect_planar_regions_stay_planar(CadFamily::CappedCylinder, 35.0);
}

TEST(LsfCad, ConeAndTubeCapsStayPlanar) {
  expect_planar_regions_stay_planar(CadFamily::Cone, 35.0);
  expect_planar_regions_stay_planar(CadFamily::Tube, 35.0);
}

// The plate's flat top and bottom meet its rounded sides at 6-12 degrees: at the default 35
// degrees they are not crease-bounded (issue 17 item 5); with creases found at 5 degrees they
// are, and must stay exactly flat, as must its end sections.
TEST(LsfCad, PlateFlatFacesStayPlanar) {
  expect_planar_regions_stay_planar(CadFamily::Plate, 5.0);
}

// The plate's flat top and bottom are two triangles each: with creases found at 5 degrees
// (crease-bounded, so their corner normals are the plane's), the diagonal between the two
// coplanar triangles is the chord's midpoint, not a fit's bulge (13-17 mm off the plane
// before issue 17's guard).
TEST(LsfCad, CoplanarFacesGiveTheChordMidpoint) {
  for (const std::uint64_t seed : kSeeds) {
    const CadShape shape = make_cad_shape(CadFamily::Plate, {seed, 1.0});
    const Level coarse = make_level(to_mesh(shape.soup), 5.0);
    const Level fine = refine_level("lsf", coarse);
    const Mesh& m = coarse.mesh;
    std::size_t coplanar = 0;
    for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
      const HalfedgeId h = m.halfedge(EdgeId(e));
      if (coarse.features.is_sharp(EdgeId(e)) || dihedral_angle_deg(m, EdgeId(e)) > 1e-6) continue;
      ++coplanar;
      const Vec3 mid = 0.5 * (m.position(m.from(h)) + m.position(m.to(h)));
      EXPECT_VEC_NEAR(fine.mesh.position(edge_vertex(m, EdgeId(e))), mid, 1e-12);
    }
    EXPECT_GE(coplanar, 2u) << "seed " << seed;
  }
}

// The plane rule must not take a finely tessellated smooth surface for planes: a 120 x 60
// torus's split quads are exactly planar trapezoids, with dihedrals of 3-6 degrees to their
// neighbours. Their diagonals' points come from the fits, onto the torus, not the chords:
// each at most a tenth of its chord midpoint's distance from the torus.
TEST(LsfCad, FineTorusQuadDiagonalsAreNotChords) {
  constexpr double kMajor = 3.0, kMinor = 1.0;
  const Level coarse = make_level(to_mesh(torus_soup(120, 60, kMajor, kMinor)));
  const Level fine = refine_level("lsf", coarse);
  const Mesh& m = coarse.mesh;
  auto off_torus = [&](const Vec3& p) {
    return std::abs(std::hypot(std::hypot(p.x, p.y) - kMajor, p.z) - kMinor);
  };
  std::size_t diagonals = 0;
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
    if (dihedral_angle_deg(m, EdgeId(e)) > 1e-6) continue;
    ++diagonals;
    const HalfedgeId h = m.halfedge(EdgeId(e));
    const Vec3 mid = 0.5 * (m.position(m.from(h)) + m.position(m.to(h)));
    EXPECT_LE(off_torus(fine.mesh.position(edge_vertex(m, EdgeId(e)))), 0.1 * off_torus(mid))
        << "edge " << e;
  }
  EXPECT_EQ(diagonals, 120u * 60u);
}

// The xyz cube's embossed letters (tests/data/core): walls a few times longer than tall between
// the letters' top and bottom outlines, meeting at corners. Round 9's ruled strips ending at a
// sharp line between two corners (made for the plate's 305 mm slivers) took them as ruled
// strips too: the largest distance of two lsf levels from the input went 0.20 -> 0.41 mm (the
// request's report; 2x). Such an end face must be a sliver. Largest distance of the output's
// vertices from the input's faces, auto creases: 0.409 mm before, 0.204 here (main's).
TEST(LsfCad, XyzCubeLettersStayNearTheInput) {
  const Mesh input = to_mesh(
      read_binary_stl_soup(std::string(STLREFINE_CORE_TEST_DATA_DIR) + "/xyz_cube_20mm.stl"));
  ASSERT_GT(input.num_faces(), 100u);
  const Level fine =
      refine_levels("lsf", Level{Mesh(input), detect_features(input, FeatureParams{})}, 2);
  double worst = 0;
  for (const Vec3& p : fine.mesh.positions()) {
    double nearest = std::numeric_limits<double>::infinity();
    for (std::uint32_t i = 0; i < input.num_faces(); ++i) {
      const HalfedgeId h = Mesh::halfedge(FaceId(i), 0);
      nearest = std::min(nearest, point_triangle_distance(p, input.position(input.from(h)),
                                                          input.position(input.to(h)),
                                                          input.position(input.opposite(h))));
    }
    worst = std::max(worst, nearest);
  }
  EXPECT_LE(worst, 0.25);  // mm
}

}  // namespace
}  // namespace stlrefine
