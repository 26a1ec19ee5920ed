// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Issue 17 item 5 (creases that mean creases) and item 2 (no face more than 60 degrees from
// the true normal), on the CAD-like meshes of tests/support/cad_like.h with their truth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/features/features.h"
#include "core/geometry/point_triangle.h"
#include "core/mesh/build_mesh.h"
#include "core/refine.h"
#include "core/schemes/split4_host.h"
#include "tests/support/cad_like.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"
#include "tests/support/true_surface.h"

namespace stlrefine::test {
namespace {

constexpr std::uint64_t kSeeds[] = {1, 2, 3, 4};

using Pair = std::pair<std::uint32_t, std::uint32_t>;

Mesh mesh_of(const CadShape& s) {
  IngestResult in = build_mesh(s.soup);
  // The generator makes clean soups: ingest keeps every vertex.
  EXPECT_EQ(in.mesh.num_vertices(), s.soup.positions.size());
  return std::move(in.mesh);
}

// The soup's vertex id of each mesh vertex (ingest may renumber; positions are distinct).
std::vector<std::uint32_t> soup_ids(const Mesh& m, const CadShape& s) {
  std::map<std::tuple<double, double, double>, std::uint32_t> id;
  for (std::uint32_t i = 0; i < s.soup.positions.size(); ++i) {
    const Vec3& p = s.soup.positions[i];
    id[{p.x, p.y, p.z}] = i;
  }
  std::vector<std::uint32_t> out(m.num_vertices());
  for (std::uint32_t v = 0; v < m.num_vertices(); ++v) {
    const Vec3& p = m.position(VertexId(v));
    out[v] = id.at({p.x, p.y, p.z});
  }
  return out;
}

Pair soup_pair(const Mesh& m, const std::vector<std::uint32_t>& ids, EdgeId e) {
  const HalfedgeId h = m.halfedge(e);
  return std::minmax(ids[m.from(h).idx], ids[m.to(h).idx]);
}

std::set<Pair> sharp_pairs(const Mesh& m, const std::vector<std::uint32_t>& ids,
                           const Features& f) {
  std::set<Pair> out;
  for (std::uint32_t e = 0; e < m.num_edges(); ++e)
    if (f.is_sharp(EdgeId(e))) out.insert(soup_pair(m, ids, EdgeId(e)));
  return out;
}

std::string label(const CadShape& s, std::uint64_t seed) {
  return s.name + " seed " + std::to_string(seed);
}

// Sharp edges the automatic detection finds that are not creases of the true surface, and
// true crease edges it misses.
std::pair<std::size_t, std::size_t> extra_and_missed(const CadShape& s) {
  const Mesh m = mesh_of(s);
  const std::vector<std::uint32_t> ids = soup_ids(m, s);
  const std::set<Pair> found = sharp_pairs(m, ids, detect_features(m, FeatureParams{}));
  std::set<Pair> truth;
  for (const auto& e : s.crease_edges) truth.insert({e[0], e[1]});
  std::size_t missed = 0, extra = 0;
  for (const Pair& e : truth) missed += found.count(e) == 0;
  for (const Pair& e : found) extra += truth.count(e) == 0;
  return {extra, missed};
}

// The automatic detection finds exactly the creases of the true surface: none on the
// smooth families (a coarse torus, hull spheres, the rounded box's tangent fillets), every
// rim of the cylinder, cone and tube, and the plate's shallow (6-12 degree) edges between
// its flat faces and its rounded sides.
TEST(AutoCreases, MatchTheTrueCreasesOnEveryFamily) {
  for (const CadFamily family : cad_families())
    for (const std::uint64_t seed : kSeeds) {
      const CadShape s = make_cad_shape(family, {seed, 1.0});
      SCOPED_TRACE(label(s, seed));
      const auto [extra, missed] = extra_and_missed(s);
      EXPECT_EQ(missed, 0u) << s.crease_edges.size() << " true crease edges";
      EXPECT_EQ(extra, 0u);
    }
}

// Issue 17 item 5 on the benchmark's seeds (6000-6011) and a fresh range (8000-8011): every
// false crease there (26 and 6 before) came from a planar-side rule: a one-facet "plane" of
// a zipped cylinder or tube wall (tube 6001, 6004, cylinder 6003, 6007), a flat face meeting
// a zipped fillet tangentially (rounded box 6001-6003, 6008, 6009, 6011, 8000, 8008, 8011),
// or a 65 degree fold of two torus slivers standing alone (torus 6009).
TEST(AutoCreases, NoFalseAndNoMissedCreaseOnTheBenchSeeds) {
  for (const std::uint64_t base : {6000u, 8000u})
    for (const CadFamily family : cad_families())
      for (std::uint64_t seed = base; seed < base + 12; ++seed) {
        const CadShape s = make_cad_shape(family, {seed, 1.0});
        SCOPED_TRACE(label(s, seed));
        const auto [extra, missed] = extra_and_missed(s);
        EXPECT_EQ(missed, 0u);
        EXPECT_EQ(extra, 0u);
      }
}

// The angle alone, as before and as a user who gives crease_angle gets it, creases the coarse
// torus at 35 degrees and smooths the plate's shallow crease: what the automatic mode fixes.
TEST(AutoCreases, AngleModeIsTheUsersOverride) {
  EXPECT_EQ(FeatureParams{}.crease_mode, CreaseMode::Auto);
  EXPECT_STREQ(to_string(CreaseMode::Auto), "auto");
  EXPECT_STREQ(to_string(CreaseMode::Angle), "angle");
  FeatureParams bad;
  bad.crease_mode = static_cast<CreaseMode>(7);
  EXPECT_THROW(bad.validate(), Error);
  const CadShape torus = make_cad_shape(CadFamily::Torus, {2, 1.0});
  const Mesh mt = mesh_of(torus);
  FeatureParams angle;
  angle.crease_mode = CreaseMode::Angle;
  angle.crease_angle_deg = 35.0;
  EXPECT_GT(detect_features(mt, angle).num_sharp_edges(), 0u);
  EXPECT_EQ(detect_features(mt, FeatureParams{}).num_sharp_edges(), 0u);
  angle.crease_angle_deg = 180.0;
  const CadShape cyl = make_cad_shape(CadFamily::CappedCylinder, {1, 1.0});
  const Mesh mc = mesh_of(cyl);
  EXPECT_EQ(detect_features(mc, angle).num_sharp_edges(), 0u);
  EXPECT_GE(detect_features(mc, FeatureParams{}).num_sharp_edges(), cyl.crease_edges.size());
  // The plate's flat faces meet its rounded sides at 6-12 degrees: the angle misses them.
  const CadShape plate = make_cad_shape(CadFamily::Plate, {1, 1.0});
  const Mesh mp = mesh_of(plate);
  angle.crease_angle_deg = 35.0;
  EXPECT_LT(detect_features(mp, angle).num_sharp_edges(), plate.crease_edges.size());
  EXPECT_EQ(detect_features(mp, FeatureParams{}).num_sharp_edges(), plate.crease_edges.size());
}

// Issue 17 item 2: the fold guard holds every child within 60 degrees of the smooth normals
// the coarse mesh gives, so two butterfly levels leave no face more than 60 degrees from the
// true normal on any family.
TEST(FoldGuard, ButterflyTwoLevelsStaysWithin60DegreesOfTheTruth) {
  for (const CadFamily family : cad_families())
    for (const std::uint64_t seed : kSeeds) {
      const CadShape s = make_cad_shape(family, {seed, 1.0});
      SCOPED_TRACE(label(s, seed));
      RefineParams p;
      p.scheme = "butterfly";
      p.levels = 2;
      const RefineResult r = refine(mesh_of(s), p);
      const std::size_t off = faces_off_truth(r.mesh, *s.surface, kFoldAngleDeg);
      // Zero on the cylinder, tube and plate seeds here; elsewhere a few level-2 faces still
      // turn past 60 degrees (the level-1 mesh's own sector normals are off there): at most
      // 1.5% of the faces (the rounded box, ~1.1%), see bench/RESULTS.md.
      const bool creased = family == CadFamily::CappedCylinder || family == CadFamily::Tube ||
                           family == CadFamily::Plate;
      if (creased) {
        EXPECT_EQ(off, 0u);
      } else {
        EXPECT_LE(off * 1000, 15 * r.mesh.num_faces()) << off << " faces past 60 degrees";
      }
    }
}

// Area-weighted RMS distance to the truth, sampled as bench/fidelity does: the centroids of
// the k^2 equal sub-triangles of every face, k chosen for about 20,000 samples in all.
double rms_to_truth(const Mesh& m, const TrueSurface& surface) {
  const int k = std::clamp(static_cast<int>(std::ceil(std::sqrt(
                               20000.0 / double(std::max<std::size_t>(m.num_faces(), 1))))),
                           1, 16);
  double sum = 0, weight = 0;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto corners = m.face_vertices(FaceId(f));
    const Vec3 &a = m.position(corners[0]), &b = m.position(corners[1]),
               &c = m.position(corners[2]);
    const double w = 0.5 * norm(m.face_normal(FaceId(f))) / (k * k);
    auto sample = [&](double u, double v) {
      const Vec3 p = a + (b - a) * u + (c - a) * v;
      const double d = norm(p - surface.closest_point(p).point);
      sum += w * d * d;
      weight += w;
    };
    for (int i = 0; i < k; ++i)
      for (int j = 0; i + j < k; ++j) {
        sample((i + 1.0 / 3) / k, (j + 1.0 / 3) / k);
        if (i + j + 1 < k) sample((i + 2.0 / 3) / k, (j + 2.0 / 3) / k);
      }
  }
  return std::sqrt(sum / weight);
}

RefineResult refine_with(const Mesh& input, const char* scheme, int levels) {
  RefineParams p;
  p.scheme = scheme;
  p.levels = levels;
  return refine(input, p);
}

// Issue 17 item 2, the guard's own cause: it holds children to the input's sector normals,
// carried from level to level (not to those of the level it refines, which follow the faces
// the stencil bent), 45 degrees from them (they are estimates). On the rounded box and the
// hull sphere, tuned on seeds 1000-1005 (bench/results-issue17-butterfly.md): no face more
// than 60 degrees from the true normal at 1 and 2 levels (main had up to 1% of the box's
// faces there).
TEST(FoldGuard, ButterflyAndG1NoFacePast60DegreesOnTheRoundedBoxAndSphere) {
  for (const char* scheme : {"butterfly", "butterfly-g1"})
    for (const CadFamily family : {CadFamily::RoundedBox, CadFamily::Sphere})
      for (const std::uint64_t seed : {1, 2, 3}) {
        const CadShape s = make_cad_shape(family, {seed, 1.0});
        const Mesh input = mesh_of(s);
        for (int levels = 1; levels <= 2; ++levels) {
          SCOPED_TRACE(label(s, seed) + " " + scheme + " L" + std::to_string(levels));
          const RefineResult r = refine_with(input, scheme, levels);
          EXPECT_EQ(faces_off_truth(r.mesh, *s.surface, kFoldAngleDeg), 0u);
        }
      }
}

// Issue 17 items 2 and 5 on the plate: with its shallow (6-12 degree) creases found, butterfly
// (2 levels) and sqrt3-interp (4 steps) come closer to the true plate than its input (main's
// baseline, which smoothed those creases into the fillets: 2.2-2.9x and 47-52x worse; this
// branch 0.60x and 0.71x on seeds 1000-1009, bench/results-issue17-creases.md).
TEST(AutoCreases, PlateRefinesCloserToTheTruthThanItsInput) {
  for (const std::uint64_t seed : {1, 2}) {
    const CadShape s = make_cad_shape(CadFamily::Plate, {seed, 1.0});
    const Mesh input = mesh_of(s);
    const double before = rms_to_truth(input, *s.surface);
    for (const auto& [scheme, steps] :
         {std::pair<const char*, int>{"butterfly", 2}, {"sqrt3-interp", 4}}) {
      SCOPED_TRACE(label(s, seed) + " " + scheme);
      RefineParams p;
      p.scheme = scheme;
      p.levels = steps;
      const double after = rms_to_truth(refine(input, p).mesh, *s.surface);
      EXPECT_LT(after, 0.9 * before) << after << " vs the input's " << before;
    }
  }
}

// Issue 17 item 2, never worse than the input, on the rounded box: its error was on the flat
// faces (exact in the input), bent by the stencil's reach into the fillets' vertices (main:
// butterfly 1.05x its input at L2, 4 of seeds 1000-1005 worse). The plane rule of the split4
// host (keep_dominant_planes) keeps a face that dominates its corners flat: most edge points
// made inside a flat face of the box stay on its plane, and the output is closer to the
// truth than the input.
TEST(PlaneRule, RoundedBoxStaysFlatAndGetsCloserToTheTruth) {
  for (const char* scheme : {"butterfly", "butterfly-g1"})
    for (const std::uint64_t seed : {1, 2, 3}) {
      const CadShape s = make_cad_shape(CadFamily::RoundedBox, {seed, 1.0});
      const Mesh input = mesh_of(s);
      const double before = rms_to_truth(input, *s.surface);
      for (int levels = 1; levels <= 2; ++levels) {
        SCOPED_TRACE(label(s, seed) + " " + scheme + " L" + std::to_string(levels));
        const RefineResult r = refine_with(input, scheme, levels);
        const double after = rms_to_truth(r.mesh, *s.surface);
        EXPECT_LT(after, 0.9 * before) << after << " vs the input's " << before;
        if (levels != 1) continue;
        // Every edge point of an input edge whose two faces lie on one flat face of the box
        // (their corners' true normal the same axis) is on that face's plane.
        auto flat_normal = [&](FaceId f, Vec3& n) {
          const auto corners = input.face_vertices(f);
          const Vec3 first = s.surface->closest_point(input.position(corners[0])).normal;
          for (const VertexId v : corners) {
            const Vec3 nv = s.surface->closest_point(input.position(v)).normal;
            if (nv != first ||
                std::abs(std::abs(nv.x) + std::abs(nv.y) + std::abs(nv.z) - 1) > 1e-12)
              return false;
          }
          n = first;
          return true;
        };
        std::size_t inside = 0, off_plane = 0;
        for (std::uint32_t e = 0; e < input.num_edges(); ++e) {
          const HalfedgeId h = input.halfedge(EdgeId(e));
          Vec3 n0, n1;
          if (!flat_normal(FaceId(h.idx / 3), n0) ||
              !flat_normal(FaceId(input.twin(h).idx / 3), n1) || n0 != n1)
            continue;
          ++inside;
          const Vec3 a = input.position(input.from(h));
          const Vec3 q = r.mesh.position(edge_vertex(input, EdgeId(e)));
          off_plane += std::abs(dot(q - a, n0)) > 1e-9 * norm(a);
        }
        // Not every one: 1-3 of the 12-18 per mesh here stay off the plane, edges with an
        // end where the plane does not dominate by the rule's measure (half the sector's
        // area, its largest face twice any other there), e.g. a fan's spokes at its apex.
        EXPECT_GT(inside, 0u);
        EXPECT_LE(4 * off_plane, inside) << "of " << inside << " edges inside the box's flat faces";
      }
    }
}

// Issue 17 item 2 for the sqrt3 host: its fold guard pulls face points back (to the centroid,
// then towards the obtuse corner) where a child turns more than 60 degrees from the sector
// normals. What it cannot prevent: children of old vertices and crease points alone, and
// flipped edges whose quad is not convex for any face point it tries. Measured on seeds 1-2
// at 4 steps (bench/results-issue17-creases.md), faces past 60 degrees per mille, without ->
// with the guard: sqrt3-interp sphere 4.9 -> 0.26, ellipsoid 4.4 -> 0.32, blob 3.6 -> 0.37,
// torus 2.1 -> 0.57, plate 80 -> 0.5, cone 1.9 -> 1.9, rounded box 293 -> 32; sqrt3-unified
// plate 38 -> 0.5, rounded box 267 -> 28.
TEST(FoldGuard, Sqrt3InterpFourStepsRarelyPast60Degrees) {
  for (const char* scheme : {"sqrt3-interp", "sqrt3-unified"})
    for (const CadFamily family : cad_families())
      for (const std::uint64_t seed : {1, 2}) {
        const CadShape s = make_cad_shape(family, {seed, 1.0});
        SCOPED_TRACE(label(s, seed) + " " + scheme);
        RefineParams p;
        p.scheme = scheme;
        p.levels = 4;
        const RefineResult r = refine(mesh_of(s), p);
        const std::size_t off = faces_off_truth(r.mesh, *s.surface, kFoldAngleDeg);
        // per mille of the faces: the rounded box's zipped fillets and fanned corners keep
        // many non-convex flips
        const std::size_t per_mille = family == CadFamily::RoundedBox ? 60 : 3;
        EXPECT_LE(off * 1000, per_mille * r.mesh.num_faces()) << off << " faces past 60 degrees";
      }
}

// An extruded convex quadrilateral (an embossed letter's stroke, as on the xyz cube): walls of
// two triangles each, capped by fans; the outline turns by 32 degrees at one corner and by 100,
// 100 and 128 at the others. Every face is planar, so a refinement that reads it right
// reproduces it exactly: new vertices on the input's faces, crease vertices on its straight
// edges.
IndexedSoup extruded_polygon(double height) {
  const double deg = std::numbers::pi / 180.0;
  const Vec3 b{10, 0, 0}, c = b + 4.0 * Vec3{std::cos(32 * deg), std::sin(32 * deg), 0};
  // d = c + s u = t w: the wall leaving c at 132 degrees meets the one reaching the origin
  // from 52 degrees.
  const Vec3 u{std::cos(132 * deg), std::sin(132 * deg), 0};
  const Vec3 w{std::cos(52 * deg), std::sin(52 * deg), 0};
  const double t = (c.x * u.y - c.y * u.x) / (w.x * u.y - w.y * u.x);
  const std::vector<Vec3> outline{{0, 0, 0}, b, c, t * w};
  const auto n = static_cast<std::uint32_t>(outline.size());
  IndexedSoup soup;
  for (const Vec3& p : outline) soup.positions.push_back(p);
  for (const Vec3& p : outline) soup.positions.push_back(p + Vec3{0, 0, height});
  for (std::uint32_t i = 1; i + 1 < n; ++i) {
    soup.triangles.push_back({0, i + 1, i});          // bottom, facing down
    soup.triangles.push_back({n, n + i, n + i + 1});  // top, facing up
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t j = (i + 1) % n;
    soup.triangles.push_back({i, j, n + j});
    soup.triangles.push_back({i, n + j, n + i});
  }
  return soup;
}

TEST(CreasesPolyhedra, WallsOfAnExtrudedPolygonMeetAtACrease) {
  const Mesh m = to_mesh(extruded_polygon(0.5));
  const Features f = detect_features(m, FeatureParams{});
  // Every edge but the walls' and caps' diagonals: 4 + 4 outline edges, 4 wall edges.
  EXPECT_EQ(f.num_sharp_edges(), 12u);
  // A coarse 12-gon prism's facets (30 degrees, each bending the same at its far edge) stay
  // smooth: the rule needs the walls to bend nowhere else.
  IndexedSoup prism;
  const int k = 12;
  for (int z = 0; z < 2; ++z)
    for (int i = 0; i < k; ++i) {
      const double a = 2 * std::numbers::pi * i / k;
      prism.positions.push_back({10 * std::cos(a), 10 * std::sin(a), 20.0 * z});
    }
  for (std::uint32_t i = 0; i < std::uint32_t(k); ++i) {
    const std::uint32_t j = (i + 1) % k;
    prism.triangles.push_back({i, j, k + j});
    prism.triangles.push_back({i, k + j, k + i});
  }
  const Mesh tube = to_mesh(prism);
  EXPECT_EQ(detect_features(tube, FeatureParams{}).num_sharp_edges(), 2u * k);  // the rims
}

TEST(CreasesPolyhedra, ExtrudedPolygonRefinesOntoItself) {
  const Mesh input = to_mesh(extruded_polygon(0.5));
  for (const char* scheme : {"lsf", "butterfly", "sqrt3-interp", "butterfly-g1"}) {
    SCOPED_TRACE(scheme);
    RefineParams params;
    params.scheme = scheme;
    params.levels = std::string(scheme) == "sqrt3-interp" ? 4 : 2;
    const Mesh out = refine(input, params).mesh;
    double worst = 0;
    for (std::uint32_t v = 0; v < out.num_vertices(); ++v) {
      const Vec3 p = out.position(VertexId(v));
      double best = INFINITY;
      for (std::uint32_t fi = 0; fi < input.num_faces(); ++fi) {
        const auto vs = input.face_vertices(FaceId(fi));
        best =
            std::min(best, point_triangle_distance(p, input.position(vs[0]), input.position(vs[1]),
                                                   input.position(vs[2])));
      }
      worst = std::max(worst, best);
    }
    EXPECT_LE(worst, 1e-9);  // mm
  }
}

}  // namespace
}  // namespace stlrefine::test
