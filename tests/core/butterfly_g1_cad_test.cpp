// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Issue 17 item 2 for butterfly-g1: no face more than 60 degrees from the true normal,
// enforced by the scheme against the surface's normals. Its edge points (the 8-point base's
// and the G1 masks') are checked against the Hermite midpoints of the normals at edges with an
// uneven-spoke end (check_edge_points_against_normals, split4_host.h), as butterfly's are;
// rings of even spokes keep the paper's rules bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "core/analysis/local_matrix.h"
#include "core/io/stl.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "core/schemes/butterfly.h"
#include "core/schemes/butterfly_g1.h"
#include "core/schemes/split4_host.h"
#include "tests/core/test_util.h"
#include "tests/support/cad_like.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/true_surface.h"

namespace stlrefine::test {
namespace {

// Before the check (main at a87aa9d) seeds 9001 and 9500 (9500: the fresh seeds of round 9)
// turned one face each 60 and 62 degrees from the truth at L3.
TEST(ButterflyG1Cad, ZippedTorusThreeLevelsNoFacePast60) {
  for (const std::uint64_t seed : {9001u, 9500u}) {
    SCOPED_TRACE("torus seed " + std::to_string(seed));
    const CadShape s = make_cad_shape(CadFamily::Torus, {seed, 1.0});
    const Mesh input = float_mesh(s);
    const double crease_snap = 1e-6 * bbox_diagonal(input);
    RefineParams p;
    p.scheme = "butterfly-g1";
    p.levels = 3;
    const RefineResult r = refine(input, p);
    ASSERT_EQ(r.mesh.check_invariants(), "");
    for (std::uint32_t v = 0; v < input.num_vertices(); ++v)
      ASSERT_EQ(r.mesh.position(VertexId(v)), input.position(VertexId(v)));
    const std::size_t off = faces_off_truth(r.mesh, *s.surface, kFoldAngleDeg, crease_snap);
    EXPECT_EQ(off, 0u) << "of " << r.mesh.num_faces() << " faces";
  }
}

// Where every ring has even spokes (a curved polar net around a valence-9 vertex, whose masks
// apply from the second step on) the check never fires: butterfly-g1 is, bit for bit, the
// paper's 8-point butterfly with the G1 masks.
TEST(ButterflyG1Cad, EvenRingsKeepThePapersRules) {
  analysis::NetLevel net = analysis::make_net_level(9, 4, 2);
  for (Vec3& p : net.level.mesh.mutable_positions()) p.z = 0.08 * (p.x * p.x - 0.5 * p.y * p.y);
  net.level.step = 0;
  const HostScheme<Split4Stencil> paper(
      "paper", std::make_unique<SpectralStencil>(
                   std::make_unique<ButterflyStencil>(ButterflyStencil::Extraordinary::EightPoint),
                   butterfly_g1_masks(), SpectralSchedule{kButterflyG1Fraction, 1, 0}));
  const HostScheme<Split4Stencil> original(
      "original", std::make_unique<ButterflyStencil>(ButterflyStencil::Extraordinary::EightPoint));
  const auto g1 = make_scheme("butterfly-g1");
  Level a = net.level, b = net.level, c = net.level;
  StepStats stats;
  for (int step = 0; step < 3; ++step) {
    a = paper.refine_once(a, stats);
    b = g1->refine_once(b, stats);
    c = original.refine_once(c, stats);
    EXPECT_TRUE(std::equal(a.mesh.positions().begin(), a.mesh.positions().end(),
                           b.mesh.positions().begin(), b.mesh.positions().end()))
        << "step " << step;
  }
  // Not vacuous: the masks moved points, and the net is curved.
  EXPECT_FALSE(std::equal(a.mesh.positions().begin(), a.mesh.positions().end(),
                          c.mesh.positions().begin(), c.mesh.positions().end()));
}

// tray_bottom (tests/data, the shared CAD mesh): a 355 x 355 x 3.2 mm tray whose side walls
// are 38 mm slivers 3.2 mm tall, its outline turning 4.5 degrees at a vertex without a crease.
// The wall's vertex normal there averages both wall planes, and the normal check put the
// Hermite midpoint of such a normal pair over a 38 mm edge: 0.19-0.32 mm outside the flat wall
// (110 points outside the part's bounding box, butterfly and butterfly-g1 alike). Now the
// normals are trusted only as far as the strip's width allows: 0.024 mm out (the 4-point
// smoothing of the shallow turn itself).
TEST(NormalCheck, TraySliverWallsStayFlat) {
  const std::filesystem::path path =
      std::filesystem::path(STLREFINE_CORE_TEST_DATA_DIR).parent_path() / "tray_bottom.stl";
  const Mesh input = build_mesh(weld(read_stl_file(path))).mesh;
  Vec3 lo = input.position(VertexId(0)), hi = lo;
  for (const Vec3& p : input.positions()) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  for (const char* scheme : {"butterfly", "butterfly-g1"}) {
    RefineParams p;
    p.scheme = scheme;
    p.levels = 2;
    const RefineResult r = refine(input, p);
    ASSERT_EQ(r.mesh.check_invariants(), "");
    double outside = 0;  // mm beyond the input's bounding box
    for (const Vec3& q : r.mesh.positions())
      outside = std::max(
          {outside, lo.x - q.x, q.x - hi.x, lo.y - q.y, q.y - hi.y, lo.z - q.z, q.z - hi.z});
    EXPECT_LE(outside, 0.05) << scheme;  // measured: 0.024 (before: 0.32)
  }
}

}  // namespace
}  // namespace stlrefine::test
