// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "tests/support/cad_like.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "core/mesh/build_mesh.h"
#include "core/mesh/mesh_stats.h"
#include "tests/support/random.h"

namespace stlrefine::test {
namespace {

constexpr std::array<std::uint64_t, 4> kSeeds{1, 2, 3, 1234567};
constexpr std::array<double, 2> kCoarseness{1.0, 2.0};

double bbox_diagonal(const IndexedSoup& soup) {
  Vec3 lo = soup.positions[0], hi = soup.positions[0];
  for (const Vec3& p : soup.positions) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  return distance(lo, hi);
}

//! Longest edge squared over twice the area: the longest edge over the height onto it
//! (2 / sqrt(3) for an equilateral triangle).
double aspect_ratio(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double l = std::max({distance(a, b), distance(b, c), distance(c, a)});
  return l * l / norm(triangle_normal(a, b, c));
}

bool zipped_family(CadFamily f) {
  return f == CadFamily::CappedCylinder || f == CadFamily::Cone || f == CadFamily::Tube ||
         f == CadFamily::RoundedBox || f == CadFamily::Plate;
}
bool hull_family(CadFamily f) {
  return f == CadFamily::Sphere || f == CadFamily::Ellipsoid || f == CadFamily::Blob;
}

std::string label(CadFamily f, std::uint64_t seed, double coarseness) {
  return std::string(cad_family_name(f)) + " seed " + std::to_string(seed) + " coarseness " +
         std::to_string(coarseness);
}

TEST(CadLike, EveryMeshIsClosedManifoldAndWoundOutward) {
  for (const CadFamily f : cad_families())
    for (const std::uint64_t seed : kSeeds)
      for (const double c : kCoarseness) {
        SCOPED_TRACE(label(f, seed, c));
        const CadShape s = make_cad_shape(f, {seed, c});
        EXPECT_EQ(s.name, cad_family_name(f));
        // Soup level: every directed edge exactly once and its reverse exactly once.
        std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
        for (const auto& t : s.soup.triangles)
          for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
        for (const auto& [e, n] : directed) {
          EXPECT_EQ(n, 1) << e.first << "->" << e.second;
          EXPECT_EQ(directed.count({e.second, e.first}), 1u) << e.first << "->" << e.second;
        }
        // No two vertices at one position (STL welding would merge them).
        std::set<std::tuple<double, double, double>> positions;
        for (const Vec3& p : s.soup.positions) positions.insert({p.x, p.y, p.z});
        EXPECT_EQ(positions.size(), s.soup.positions.size());

        const IngestResult in = build_mesh(s.soup);
        EXPECT_EQ(in.report.isolated_vertices_removed, 0u);
        EXPECT_EQ(in.report.non_manifold_edges, 0u);
        EXPECT_EQ(in.report.non_manifold_vertices, 0u);
        EXPECT_EQ(in.report.faces_reoriented, 0u);
        EXPECT_EQ(in.report.inconsistent_edges, 0u);
        EXPECT_EQ(in.report.zero_area_faces, 0u);
        const MeshStats st = compute_stats(in.mesh);
        EXPECT_TRUE(st.watertight);
        EXPECT_EQ(st.components, 1u);
        // Genus 1 for the torus and the tube, 0 for the rest.
        const bool ring = f == CadFamily::Torus || f == CadFamily::Tube;
        EXPECT_EQ(st.euler_characteristic, ring ? 0 : 2);
        EXPECT_GT(st.volume, 0);  // outward
      }
}

TEST(CadLike, VerticesLieOnTheTrueSurfaceAndCreasesAreNamed) {
  for (const CadFamily f : cad_families())
    for (const std::uint64_t seed : kSeeds)
      for (const double c : kCoarseness) {
        SCOPED_TRACE(label(f, seed, c));
        const CadShape s = make_cad_shape(f, {seed, c});
        const double tol = 1e-9 * bbox_diagonal(s.soup);
        ASSERT_EQ(s.on_crease.size(), s.soup.positions.size());
        std::size_t creases = 0;
        for (std::size_t v = 0; v < s.soup.positions.size(); ++v) {
          const Vec3& p = s.soup.positions[v];
          const SurfacePoint q = s.surface->closest_point(p);
          EXPECT_LE(distance(p, q.point), tol) << "vertex " << v;
          EXPECT_EQ(q.on_crease(), s.on_crease[v] != 0) << "vertex " << v;
          creases += s.on_crease[v];
        }
        // Rims are creases: every vertex of the zipped solids and the plate lies on one.
        const bool all_crease = f == CadFamily::CappedCylinder || f == CadFamily::Cone ||
                                f == CadFamily::Tube || f == CadFamily::Plate;
        EXPECT_EQ(creases, all_crease ? s.soup.positions.size() : 0u);
        EXPECT_EQ(s.surface->closest_crease_point({0, 0, 0}).has_value(), all_crease);

        // Crease edges: mesh edges between crease vertices, chords of a crease curve (their
        // midpoint within a quarter of their length of it), the two faces at an angle.
        std::map<std::pair<std::uint32_t, std::uint32_t>, std::size_t> face_of;
        for (std::size_t t = 0; t < s.soup.triangles.size(); ++t)
          for (int k = 0; k < 3; ++k)
            face_of[{s.soup.triangles[t][k], s.soup.triangles[t][(k + 1) % 3]}] = t;
        auto unit_normal = [&](std::size_t t) {
          const auto& tri = s.soup.triangles[t];
          return normalized(triangle_normal(s.soup.positions[tri[0]], s.soup.positions[tri[1]],
                                            s.soup.positions[tri[2]]));
        };
        std::map<std::uint32_t, int> crease_valence;
        for (const auto& [a, b] : s.crease_edges) {
          ASSERT_TRUE(face_of.count({a, b}) && face_of.count({b, a})) << a << "-" << b;
          EXPECT_TRUE(s.on_crease[a] && s.on_crease[b]);
          const Vec3 &pa = s.soup.positions[a], &pb = s.soup.positions[b];
          for (const Vec3& p : {pa, pb})
            EXPECT_LE(distance(s.surface->closest_crease_point(p)->point, p), tol);
          const Vec3 mid = (pa + pb) * 0.5;
          EXPECT_LE(distance(s.surface->closest_crease_point(mid)->point, mid),
                    0.25 * distance(pa, pb));
          const double dihedral =
              std::acos(std::clamp(dot(unit_normal(face_of[{a, b}]), unit_normal(face_of[{b, a}])),
                                   -1.0, 1.0)) *
              180 / std::numbers::pi;
          EXPECT_GT(dihedral, 5);
          ++crease_valence[a], ++crease_valence[b];
        }
        // The crease curves are closed (rims, outlines) or end at corners (the plate's).
        EXPECT_EQ(crease_valence.size(), creases);
        for (const auto& [v, n] : crease_valence) EXPECT_GE(n, 2) << "vertex " << v;
      }
}

// The input itself is a fair approximation: no face more than 60 degrees from the true
// normal at its centroid's closest point (the benchmark's "ridge" criterion), none folded.
TEST(CadLike, InputFacesFollowTheTrueNormals) {
  for (const CadFamily f : cad_families())
    for (const std::uint64_t seed : kSeeds)
      for (const double c : kCoarseness) {
        SCOPED_TRACE(label(f, seed, c));
        const CadShape s = make_cad_shape(f, {seed, c});
        double worst = 0;
        for (const auto& t : s.soup.triangles) {
          const Vec3 &a = s.soup.positions[t[0]], &b = s.soup.positions[t[1]],
                     &cc = s.soup.positions[t[2]];
          const SurfacePoint q = s.surface->closest_point((a + b + cc) * (1.0 / 3));
          worst = std::max(worst, normal_angle_deg(q, normalized(triangle_normal(a, b, cc))));
        }
        EXPECT_LT(worst, 60);
      }
}

TEST(CadLike, TessellationHasTheClaimedCadTraits) {
  for (const CadFamily f : cad_families())
    for (const std::uint64_t seed : kSeeds)
      for (const double c : kCoarseness) {
        SCOPED_TRACE(label(f, seed, c));
        const CadShape s = make_cad_shape(f, {seed, c});
        // Zipped strips join curves sampled with different vertex counts.
        for (const auto& z : s.zipped_rims) EXPECT_NE(z[0], z[1]);
        const std::map<CadFamily, std::size_t> strips{
            {CadFamily::CappedCylinder, 1}, {CadFamily::Cone, 1},  {CadFamily::Tube, 4},
            {CadFamily::RoundedBox, 12},    {CadFamily::Plate, 2}, {CadFamily::Sphere, 0},
            {CadFamily::Ellipsoid, 0},      {CadFamily::Blob, 0}};
        if (f == CadFamily::Torus)
          EXPECT_GE(s.zipped_rims.size(), 6u);  // one per ring
        else
          EXPECT_EQ(s.zipped_rims.size(), strips.at(f));

        double worst_aspect = 0;
        for (const auto& t : s.soup.triangles)
          worst_aspect = std::max(
              worst_aspect,
              aspect_ratio(s.soup.positions[t[0]], s.soup.positions[t[1]], s.soup.positions[t[2]]));
        // Fans and zips make long thin triangles (the plate's 305 mm slivers most of all),
        // less thin on coarser samplings.
        if (zipped_family(f)) {
          EXPECT_GT(worst_aspect, (f == CadFamily::Plate ? 50 : 10) / c);
        }

        if (hull_family(f)) {
          // About 300 / c^2 points, each a vertex; the faces are the hull of the points (of
          // their directions for the blob): every vertex behind every face's plane.
          const double n = double(s.soup.positions.size());
          EXPECT_NEAR(n, 300 / (c * c), 3);
          EXPECT_EQ(s.soup.triangles.size(), 2 * s.soup.positions.size() - 4);
          std::vector<Vec3> p = s.soup.positions;
          if (f == CadFamily::Blob)
            for (Vec3& x : p) x = normalized(x);
          const double tol = 1e-10 * bbox_diagonal(s.soup);
          std::size_t outside = 0;
          for (const auto& t : s.soup.triangles) {
            const Vec3 nrm = normalized(triangle_normal(p[t[0]], p[t[1]], p[t[2]]));
            for (std::uint32_t v = 0; v < p.size(); ++v)
              if (v != t[0] && v != t[1] && v != t[2] && dot(nrm, p[v] - p[t[0]]) > tol) ++outside;
          }
          EXPECT_EQ(outside, 0u);
        }
      }
}

// The generated surfaces' parameters (the blob's coefficients, the plate's crease angle, ...)
// vary with the seed: each one's closest point beats a dense sample of it.
TEST(CadLike, ClosestPointOfEveryGeneratedSurfaceBeatsItsSamples) {
  for (const CadFamily f : cad_families())
    for (const std::uint64_t seed : {5u, 6u}) {
      SCOPED_TRACE(label(f, seed, 1.0));
      const CadShape s = make_cad_shape(f, {seed, 1.0});
      const double diag = bbox_diagonal(s.soup);
      Vec3 lo = s.soup.positions[0], hi = lo;
      for (const Vec3& p : s.soup.positions) {
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
      }
      const Vec3 margin = (hi - lo) * 0.2;
      const std::vector<SurfacePoint> samples = s.surface->sample(seed, 5000);
      Rng rng(seed);
      for (int i = 0; i < 100; ++i) {
        const Vec3 p{rng.uniform(lo.x - margin.x, hi.x + margin.x),
                     rng.uniform(lo.y - margin.y, hi.y + margin.y),
                     rng.uniform(lo.z - margin.z, hi.z + margin.z)};
        double nearest = std::numeric_limits<double>::infinity();
        for (const SurfacePoint& q : samples) nearest = std::min(nearest, distance(p, q.point));
        EXPECT_LE(distance(p, s.surface->closest_point(p).point), nearest + 1e-9 * diag);
      }
    }
}

TEST(CadLike, CoarsenessScalesTheSampling) {
  for (const CadFamily f : cad_families()) {
    SCOPED_TRACE(cad_family_name(f));
    const std::size_t fine = make_cad_shape(f, {7, 1.0}).soup.positions.size();
    const std::size_t coarse = make_cad_shape(f, {7, 2.0}).soup.positions.size();
    EXPECT_LT(coarse, fine);
  }
  const CadShape cyl = make_cad_shape(CadFamily::CappedCylinder, {7, 1.0});
  ASSERT_EQ(cyl.zipped_rims.size(), 1u);
  EXPECT_NEAR(double(cyl.zipped_rims[0][0]), 23, 2);
  EXPECT_NEAR(double(cyl.zipped_rims[0][1]), 37, 3);
}

TEST(CadLike, ExtremeCoarsenessStillGivesClosedMeshesOnTheSurface) {
  for (const CadFamily f : cad_families())
    for (const double c : {0.5, 4.0}) {
      SCOPED_TRACE(label(f, 9, c));
      const CadShape s = make_cad_shape(f, {9, c});
      const IngestResult in = build_mesh(s.soup);
      EXPECT_EQ(in.report.faces_reoriented + in.report.non_manifold_edges +
                    in.report.non_manifold_vertices + in.report.zero_area_faces,
                0u);
      EXPECT_TRUE(compute_stats(in.mesh).watertight);
      EXPECT_GT(compute_stats(in.mesh).volume, 0);
      for (const auto& z : s.zipped_rims) EXPECT_NE(z[0], z[1]);
      for (const Vec3& p : s.soup.positions)
        EXPECT_LE(distance(p, s.surface->closest_point(p).point), 1e-9 * bbox_diagonal(s.soup));
    }
}

TEST(CadLike, SameSeedSameMeshOtherSeedOtherMesh) {
  for (const CadFamily f : cad_families()) {
    SCOPED_TRACE(cad_family_name(f));
    const CadShape a = make_cad_shape(f, {42, 1.0}), b = make_cad_shape(f, {42, 1.0});
    const CadShape other = make_cad_shape(f, {43, 1.0});
    EXPECT_EQ(a.soup.positions, b.soup.positions);
    EXPECT_EQ(a.soup.triangles, b.soup.triangles);
    EXPECT_EQ(a.description, b.description);
    EXPECT_NE(a.soup.positions, other.soup.positions);
  }
}

TEST(CadLike, NamesAndParameters) {
  for (const CadFamily f : cad_families()) EXPECT_EQ(cad_family_from_name(cad_family_name(f)), f);
  EXPECT_FALSE(cad_family_from_name("teapot"));
  EXPECT_EQ(cad_families().size(), 9u);
  EXPECT_THROW(make_cad_shape(CadFamily::Torus, {1, 0.1}), std::invalid_argument);
  EXPECT_THROW(make_cad_shape(CadFamily::Torus, {1, 5}), std::invalid_argument);
}

}  // namespace
}  // namespace stlrefine::test
