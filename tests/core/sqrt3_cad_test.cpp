// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Issue 17 item 3 for the interpolatory sqrt3 schemes: after 4 steps on CAD-like meshes
// (tests/support/cad_like.h) at most half the input's RMS distance from the true surface.
// Their stencils alone stayed at 0.55-0.85x (bench/results-issue17-s9-s3acc.md); the host's
// normal check (sqrt3_host.h) takes the PN centroid of lsf's relaxed guard normals where an
// uneven ring puts a face point off the surface.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/features/features.h"
#include "core/geometry/pn_centroid.h"
#include "core/refine.h"
#include "core/schemes/sqrt3_host.h"
#include "core/schemes/sqrt3_interp.h"
#include "tests/core/test_util.h"
#include "tests/support/cad_like.h"
#include "tests/support/shapes.h"
#include "tests/support/true_surface.h"

namespace stlrefine::test {
namespace {

constexpr std::uint64_t kSeeds[] = {1, 2};

// Mean over kSeeds of the 4-step scheme's sampled RMS distance from the truth over the input's.
double four_step_ratio(const char* scheme, CadFamily family) {
  double sum = 0;
  for (const std::uint64_t seed : kSeeds) {
    const CadShape shape = make_cad_shape(family, {seed, 1.0});
    const Mesh input = to_mesh(shape.soup);
    Level level{Mesh(input), detect_features(input, FeatureParams{})};
    level = refine_levels(scheme, std::move(level), 4);
    sum += sampled_rms_distance(level.mesh, *shape.surface, 2) /
           sampled_rms_distance(input, *shape.surface, 8);
  }
  return sum / std::size(kSeeds);
}

// Measured on seeds 1, 2 (sqrt3-interp / sqrt3-unified): cylinder 0.27 / 0.26, tube 0.28 /
// 0.27, sphere 0.10 / 0.10, blob 0.11 / 0.11, rounded box 0.30 / 0.20, plate 0.32 / 0.32;
// before the normal check and lsf's normals 0.54-0.87.
TEST(Sqrt3Cad, FourStepsWithinHalfTheInputRms) {
  for (const char* scheme : {"sqrt3-interp", "sqrt3-unified"}) {
    for (const CadFamily family : {CadFamily::CappedCylinder, CadFamily::Tube, CadFamily::Sphere,
                                   CadFamily::Blob, CadFamily::RoundedBox, CadFamily::Plate}) {
      EXPECT_LE(four_step_ratio(scheme, family), 0.5) << scheme << " " << cad_family_name(family);
    }
  }
}

// The first step's face points on a zipped capped cylinder (side slivers between rims of ~23
// and ~37 jittered vertices, caps fanned from one rim vertex): the stencil's lattice weights
// put them about as far off the cylinder as the flat centroids; the checked ones are the PN
// centroids of the normals, far closer.
TEST(Sqrt3NormalCheck, SliverFacePointsOfACylinderGoNearTheSurface) {
  const CadShape shape = make_cad_shape(CadFamily::CappedCylinder, {1, 1.0});
  const Mesh input = to_mesh(shape.soup);
  const Level coarse{Mesh(input), detect_features(input, FeatureParams{})};
  const LabsikGreinerStencil stencil;
  const UnguardedSqrt3 paper(stencil);
  StepStats stats;
  const Level raw = sqrt3_refine(coarse, paper, stats);
  const Level checked = sqrt3_refine(coarse, stencil, stats);
  const std::uint32_t nv = static_cast<std::uint32_t>(input.num_vertices());
  double raw_sq = 0, checked_sq = 0;
  std::size_t moved = 0;
  for (std::uint32_t f = 0; f < input.num_faces(); ++f) {
    const Vec3 r = raw.mesh.position(VertexId(nv + f)), c = checked.mesh.position(VertexId(nv + f));
    const double dr = distance(r, shape.surface->closest_point(r).point);
    const double dc = distance(c, shape.surface->closest_point(c).point);
    raw_sq += dr * dr;
    checked_sq += dc * dc;
    moved += r != c;
  }
  // Input vertices bit-identical.
  for (std::uint32_t v = 0; v < nv; ++v)
    ASSERT_EQ(checked.mesh.position(VertexId(v)), input.position(VertexId(v)));
  // The side strip's faces (the caps are planes: their points stay).
  EXPECT_GE(moved, 40u);
  // Measured: 46 points moved, 0.032 mm RMS off the cylinder (all faces) -> 0.065 of that.
  EXPECT_LE(std::sqrt(checked_sq), 0.2 * std::sqrt(raw_sq));
}

// Issue 17 item 2 in the file a bureau gets: the plate refined 6 sqrt3 steps (level 3),
// written as float coordinates. On main, sqrt3-interp made slivers 1e-6 mm high on the flat
// end faces (near-flat flips beside trisected creases, face points the fold guard left almost
// on a kept edge) that faced the right way in double precision and turned over in the float
// output: seeds 9002, 9006 (2), 9008, 9501, 9502, 180 degrees off the truth; 1-13 faces per
// seed lower than 2 float ulps of their coordinates (rounding moves a corner's distance from
// the opposite edge by up to sqrt 3 ulps). The host's fold guard counts such degenerate faces
// as folds (sqrt3_degenerate.h, kSqrt3ThinFloatUlps, kSqrt3ThinParentFraction).
TEST(Sqrt3Cad, PlateSliversSurviveTheFloatOutput) {
  for (const std::uint64_t seed : {9002, 9006, 9008, 9501, 9502}) {
    const CadShape shape = make_cad_shape(CadFamily::Plate, {seed, 1.0});
    const Mesh input = float_rounded(to_mesh(shape.soup));  // as read from its STL
    RefineParams params;
    params.scheme = "sqrt3-interp";
    params.levels = 6;
    const Mesh out = refine(Mesh(input), params).mesh;
    const Mesh stl = float_rounded(out);
    const auto [reversed, below_grid] = float_rounding(out);
    EXPECT_EQ(reversed, 0u) << "seed " << seed;
    EXPECT_EQ(below_grid, 0u) << "seed " << seed;
    EXPECT_EQ(faces_off_truth(stl, *shape.surface, 90), 0u) << "seed " << seed;
  }
}

// The PN centroid of a sphere's small triangle with its true normals is on the sphere to
// third order in the edge length, where the flat centroid is off by the sagitta; zero offset
// on a plane.
TEST(PnCentroid, SphereAndPlane) {
  const double r = 10;
  const std::array<Vec3, 3> dirs = {normalized(Vec3{1, 0.1, 0.05}), normalized(Vec3{1, -0.12, 0.1}),
                                    normalized(Vec3{1, 0.02, -0.15})};
  const std::array<Vec3, 3> p = {r * dirs[0], r * dirs[1], r * dirs[2]};
  const Vec3 flat = (p[0] + p[1] + p[2]) * (1.0 / 3.0);
  const Vec3 pn = flat + pn_centroid_offset(p, dirs);
  const double sagitta = r - norm(flat);
  EXPECT_GT(sagitta, 0.02);
  EXPECT_LE(std::abs(norm(pn) - r), 0.02 * sagitta);
  const Vec3 n = normalized(Vec3{0.3, -1, 2});
  const std::array<Vec3, 3> plane = {Vec3{0, 2, 1}, Vec3{2, 0, -1}, Vec3{-1, 0.5, 0}};
  const std::array<Vec3, 3> on_plane = {plane[0] - dot(plane[0], n) * n,
                                        plane[1] - dot(plane[1], n) * n,
                                        plane[2] - dot(plane[2], n) * n};
  EXPECT_LE(norm(pn_centroid_offset(on_plane, {n, n, n})), 1e-15);
}

}  // namespace
}  // namespace stlrefine::test
