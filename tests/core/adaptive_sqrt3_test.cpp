// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// Forward adaptive sqrt3 refinement (spec 3.6, Labsik-Greiner 3.2): conforming and
// watertight output, edge neighbours at most one level apart, every point the uniform
// hierarchy's, creases and corners kept, the criteria and the face budget.
#include "core/schemes/adaptive_sqrt3.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "core/refine.h"
#include "core/schemes/adaptive_split4.h"
#include "core/schemes/scheme.h"
#include "tests/core/reference_cases.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

constexpr std::array<const char*, 3> kSchemes = {"sqrt3-interp", "sqrt3-unified", "sqrt3"};

struct Case {
  std::string name;
  Level level;
};

std::vector<Case> cases() {
  std::vector<Case> out;
  out.push_back({"Icosphere", make_level(to_mesh(icosphere_soup(1, 10.0)), 35)});
  out.push_back(
      {"JitteredIcosphere", make_level(to_mesh(jittered(icosphere_soup(1, 10.0), 0.5)), 180)});
  out.push_back({"Torus", make_level(to_mesh(torus_soup(12, 8, 20.0, 6.0)), 180)});
  out.push_back({"Cylinder", make_level(to_mesh(cylinder_soup(12, 10.0, 20.0)), 35)});
  out.push_back({"Cube", make_level(to_mesh(cube_soup(2.0)), 35)});
  out.push_back({"BumpyOpenGrid", make_level(to_mesh(bumpy_grid_soup(8, 0.1)), 180)});
  out.push_back({"Fan7", make_level(to_mesh(fan_soup(7, 0.5)), 180)});
  out.push_back({"TaggedPolyline", tagged_polyline_level(true)});
  out.push_back({"Bipyramid5", make_level(to_mesh(bipyramid_soup(5, 1.3)), 35)});
  return out;
}

struct Outcome {
  Level level;
  std::vector<std::uint8_t> face_level;
  Sqrt3AdaptiveStats stats;
};

// The hierarchy's rules alone (FoldGuard::Off), compared here with the uniform host's
// rules alone, which it matches; the fold guard is tested in adaptive_sqrt3_guard_test.cpp.
Outcome adapt(const Level& coarse, const char* scheme, Sqrt3AdaptiveCriteria c,
              std::uint64_t max_faces = 1u << 26) {
  const auto s = make_scheme(scheme);
  c.guard = FoldGuard::Off;
  AdaptiveSqrt3 adaptive(coarse, *adaptive_sqrt3_scheme(*s), c);
  adaptive.run(max_faces);
  Outcome out;
  out.level = adaptive.result(&out.face_level);
  out.stats = adaptive.stats();
  return out;
}

Level uniform(const Level& coarse, const char* scheme, int levels) {
  return refine_levels_unguarded(scheme, coarse, levels);
}

std::size_t boundary_halfedges(const Mesh& m) {
  std::size_t n = 0;
  for (std::uint32_t h = 0; h < m.num_halfedges(); ++h) n += m.is_boundary(HalfedgeId(h));
  return n;
}

long euler(const Mesh& m) {
  return static_cast<long>(m.num_vertices()) - static_cast<long>(m.num_edges()) +
         static_cast<long>(m.num_faces());
}

// Conforming: a valid manifold mesh whose only boundary lies along the input's boundary
// (a crack or a T-junction would add boundary half-edges inside), same Euler
// characteristic, and edge neighbours at most one level apart.
void expect_conforming(const Level& coarse, const Outcome& r) {
  const Mesh& m = r.level.mesh;
  ASSERT_EQ(m.check_invariants(), "");
  ASSERT_EQ(r.face_level.size(), m.num_faces());
  EXPECT_EQ(euler(m), euler(coarse.mesh));
  if (boundary_halfedges(coarse.mesh) == 0) {
    EXPECT_EQ(boundary_halfedges(m), 0u);
  } else {
    // Every boundary half-edge of the output lies on a boundary edge of the input.
    for (std::uint32_t h = 0; h < m.num_halfedges(); ++h) {
      if (!m.is_boundary(HalfedgeId(h))) continue;
      EXPECT_TRUE(r.level.features.is_sharp(m.edge(HalfedgeId(h))));
    }
  }
  int jump = 0;
  for (std::uint32_t h = 0; h < m.num_halfedges(); ++h) {
    const HalfedgeId t = m.twin(HalfedgeId(h));
    if (!t.valid()) continue;
    jump = std::max(jump, std::abs(int(r.face_level[h / 3]) - int(r.face_level[t.idx / 3])));
  }
  EXPECT_LE(jump, 1);
  EXPECT_EQ(m.num_faces(), coarse.mesh.num_faces() +
                               2 * (r.stats.refined_by_criterion + r.stats.refined_by_closure));
}

std::vector<Vec3> sorted_positions(const Mesh& m) {
  std::vector<Vec3> p(m.positions().begin(), m.positions().end());
  std::sort(p.begin(), p.end(), vec_less);
  return p;
}

// The criterion a curved mesh meets nowhere: every triangle is refined up to the cap.
TEST(AdaptiveSqrt3, RefiningEverythingGivesTheUniformLevel) {
  for (const char* scheme : kSchemes) {
    for (const Case& c : cases()) {
      if (c.name == "Cube" || c.name == "Cylinder" || c.name == "Fan7" || c.name == "Bipyramid5")
        continue;  // flat faces are never refined
      SCOPED_TRACE(std::string(scheme) + " " + c.name);
      const int levels = 3;
      const Outcome r = adapt(c.level, scheme, {1e-9, 0, levels});
      const Level u = uniform(c.level, scheme, levels);
      expect_conforming(c.level, r);
      ASSERT_EQ(r.level.mesh.num_faces(), u.mesh.num_faces());
      EXPECT_EQ(r.stats.levels, levels);
      // The same triangles: bit for bit for the interpolating rule (the stencils see the
      // same neighbourhoods in the same order), to rounding for the others (a ring sum may
      // start elsewhere).
      const auto a = sorted_positions(r.level.mesh), b = sorted_positions(u.mesh);
      ASSERT_EQ(a.size(), b.size());
      const bool exact = std::string(scheme) == "sqrt3-interp";
      if (exact) {
        EXPECT_TRUE(a == b);
        EXPECT_TRUE(triangle_set(r.level.mesh, false) == triangle_set(u.mesh, false));
      } else {
        // Rounding may reorder nearly equal points: match each with a neighbour in x.
        for (const Vec3& p : a) {
          auto it = std::lower_bound(b.begin(), b.end(), p - Vec3{1e-11, 0, 0}, vec_less);
          bool found = false;
          for (; it != b.end() && it->x <= p.x + 1e-11 && !found; ++it)
            found = distance(*it, p) <= 1e-11;
          ASSERT_TRUE(found) << str(p);
        }
      }
      EXPECT_EQ(r.level.features.num_sharp_edges(), u.features.num_sharp_edges());
    }
  }
}

TEST(AdaptiveSqrt3, ConformingWithLevelJumpAtMostOneOnEveryCase) {
  for (const char* scheme : kSchemes) {
    for (const Case& c : cases()) {
      for (const Sqrt3AdaptiveCriteria& crit :
           {Sqrt3AdaptiveCriteria{20, 0, 4}, Sqrt3AdaptiveCriteria{10, 0, 5},
            Sqrt3AdaptiveCriteria{0, 0.05, 5},
            Sqrt3AdaptiveCriteria{10, 0, 5, Sqrt3Closure::EdgeNeighbours},
            Sqrt3AdaptiveCriteria{0, 0.05, 5, Sqrt3Closure::EdgeNeighbours}}) {
        SCOPED_TRACE(std::string(scheme) + " " + c.name + " angle " +
                     std::to_string(crit.angle_deg) + " tol " + std::to_string(crit.tol) +
                     " closure " + std::to_string(int(crit.closure)));
        const Outcome r = adapt(c.level, scheme, crit);
        expect_conforming(c.level, r);
        EXPECT_LE(r.stats.levels, crit.max_level);
      }
    }
  }
}

TEST(AdaptiveSqrt3, InterpolatingOutputVerticesAreUniformVerticesAndInputIsKept) {
  // Interpolating: a vertex never moves once made, so every adaptive vertex is a vertex of
  // the uniform level at the cap, bit for bit, and input vertex v is output vertex v.
  for (const char* scheme : {"sqrt3-interp", "sqrt3-unified"}) {
    for (const Case& c : cases()) {
      SCOPED_TRACE(std::string(scheme) + " " + c.name);
      const int cap = 4;
      const Outcome r = adapt(c.level, scheme, {15, 0.02, cap});
      const Level u = uniform(c.level, scheme, cap);
      const std::vector<Vec3> all = sorted_positions(u.mesh);
      // sqrt3-unified's ring sums may start elsewhere than the uniform host's: to rounding.
      const double tol = std::string(scheme) == "sqrt3-interp" ? 0.0 : 1e-11;
      for (const Vec3& p : r.level.mesh.positions()) {
        const auto it = std::lower_bound(all.begin(), all.end(), p - Vec3{tol, 0, 0}, vec_less);
        bool found = false;
        for (auto i = it; i != all.end() && i->x <= p.x + tol && !found; ++i)
          found = tol == 0 ? *i == p : distance(*i, p) <= tol;
        ASSERT_TRUE(found) << str(p);
      }
      for (std::uint32_t v = 0; v < c.level.mesh.num_vertices(); ++v)
        ASSERT_EQ(r.level.mesh.position(VertexId(v)), c.level.mesh.position(VertexId(v)));
    }
  }
}

TEST(AdaptiveSqrt3, ApproximatingOutputVerticesAreVerticesOfSomeUniformLevel) {
  // Kobbelt's rule moves old vertices: an output vertex sits at its position on the finest
  // level among its faces, which is a vertex of that uniform level (without the uniform
  // host's fold guard, which the adaptive host does not have, see uniform()).
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.name);
    const int cap = 3;
    const Outcome r = adapt(c.level, "sqrt3", {15, 0, cap});
    std::vector<Vec3> all;
    Level u = c.level;
    for (int l = 0; l <= cap; ++l) {
      if (l > 0) u = uniform(u, "sqrt3", 1);
      all.insert(all.end(), u.mesh.positions().begin(), u.mesh.positions().end());
    }
    std::sort(all.begin(), all.end(), vec_less);
    for (const Vec3& p : r.level.mesh.positions()) {
      const auto it = std::lower_bound(all.begin(), all.end(), p - Vec3{1e-9, 0, 0}, vec_less);
      bool found = false;
      for (auto i = it; i != all.end() && i->x <= p.x + 1e-9 && !found; ++i)
        found = distance(*i, p) < 1e-9;
      ASSERT_TRUE(found) << str(p);
    }
  }
}

// Closest distance from p to triangle (a, b, c).
double point_triangle(const Vec3& p, const Vec3& A, const Vec3& B, const Vec3& C) {
  const Vec3 n = cross(B - A, C - A);
  const double n2 = dot(n, n);
  if (n2 > 0) {
    const double u = dot(cross(C - B, p - B), n), v = dot(cross(A - C, p - C), n),
                 w = dot(cross(B - A, p - A), n);
    if (u >= 0 && v >= 0 && w >= 0) return std::abs(dot(p - A, n)) / std::sqrt(n2);
  }
  double best = std::numeric_limits<double>::max();
  for (const auto& [s, e] : {std::pair{A, B}, std::pair{B, C}, std::pair{C, A}}) {
    const Vec3 d = e - s;
    const double t = std::clamp(dot(p - s, d) / std::max(dot(d, d), 1e-300), 0.0, 1.0);
    best = std::min(best, distance(p, s + t * d));
  }
  return best;
}

// The largest distance from a point to the mesh, looking only as far as `reach` (a point
// with nothing within reach counts as infinitely far). Faces are binned on a grid by their
// bounding boxes grown by reach, so a point only looks at the faces of its own cell.
double worst_distance(std::span<const Vec3> points, const Mesh& m, double reach) {
  // Cells about a face across: few cells per face and few faces per cell.
  double extent = 0;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto [a, b, c] = m.face_vertices(FaceId(f));
    extent += distance(m.position(a), m.position(b)) + distance(m.position(b), m.position(c));
  }
  const double cell = std::max(4 * reach, extent / (2.0 * std::max<std::size_t>(m.num_faces(), 1)));
  auto index = [&](double x) { return static_cast<std::int64_t>(std::floor(x / cell)); };
  auto key = [](std::int64_t i, std::int64_t j, std::int64_t k) {
    return (i & 0x1fffff) | ((j & 0x1fffff) << 21) | ((k & 0x1fffff) << 42);
  };
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> grid;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (const VertexId v : m.face_vertices(FaceId(f))) {
      const Vec3& p = m.position(v);
      lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
      hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
    }
    for (std::int64_t i = index(lo.x - reach); i <= index(hi.x + reach); ++i)
      for (std::int64_t j = index(lo.y - reach); j <= index(hi.y + reach); ++j)
        for (std::int64_t k = index(lo.z - reach); k <= index(hi.z + reach); ++k)
          grid[key(i, j, k)].push_back(f);
  }
  double worst = 0;
  for (const Vec3& p : points) {
    double best = std::numeric_limits<double>::infinity();
    const auto it = grid.find(key(index(p.x), index(p.y), index(p.z)));
    if (it != grid.end()) {
      for (std::uint32_t f : it->second) {
        const auto [a, b, c] = m.face_vertices(FaceId(f));
        best = std::min(best, point_triangle(p, m.position(a), m.position(b), m.position(c)));
      }
    }
    worst = std::max(worst, best);
  }
  return worst;
}

TEST(AdaptiveSqrt3, ToleranceGivesFewerFacesThanUniformAndStaysNearTheUniformLimit) {
  // The sphere and the torus need refinement everywhere, but less where flatter: the
  // adaptive mesh has fewer faces than the uniform one at the cap, and every vertex of the
  // uniform mesh at the cap (the finest surface we have) lies within the tolerance of it.
  for (const char* scheme : {"sqrt3-interp", "sqrt3-unified"}) {
    for (const Case& c : cases()) {
      if (c.name != "Torus" && c.name != "JitteredIcosphere" && c.name != "Cylinder") continue;
      SCOPED_TRACE(std::string(scheme) + " " + c.name);
      const double tol = 0.02;
      const int cap = 5;
      const Outcome r = adapt(c.level, scheme, {0, tol, cap});
      const Level u = uniform(c.level, scheme, cap);
      EXPECT_LT(r.level.mesh.num_faces(), u.mesh.num_faces() / 2);
      EXPECT_GT(r.level.mesh.num_faces(), c.level.mesh.num_faces());
      EXPECT_EQ(r.stats.over_criterion_at_cap, 0u);  // the cap was not what stopped it
      const double worst = worst_distance(u.mesh.positions(), r.level.mesh, 2 * tol);
      // Measured 0.92-0.9998 tol here: the two steps the criterion looks at carry nearly
      // all of the deviation. No slack: within the tolerance is what a user is promised.
      EXPECT_LE(worst, tol) << "worst distance " << worst;
    }
  }
}

// A binary STL of the shared corpus, bit-identical corners welded.
Level read_corpus_level(const std::string& name) {
  const IndexedSoup soup =
      read_binary_stl_soup(std::string(STLREFINE_CORE_TEST_DATA_DIR) + "/" + name);
  EXPECT_FALSE(soup.triangles.empty()) << name;
  return make_level(to_mesh(soup), 35);
}

// Points on every face: its centroid, edge midpoints and the points (4, 1, 1) / 6.
std::vector<Vec3> face_samples(const Mesh& m) {
  std::vector<Vec3> out;
  for (std::uint32_t f = 0; f < m.num_faces(); ++f) {
    const auto [ia, ib, ic] = m.face_vertices(FaceId(f));
    const Vec3 a = m.position(ia), b = m.position(ib), c = m.position(ic);
    out.insert(out.end(), {(a + b + c) * (1.0 / 3.0), 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a),
                           (4.0 * a + b + c) * (1.0 / 6.0), (a + 4.0 * b + c) * (1.0 / 6.0),
                           (a + b + 4.0 * c) * (1.0 / 6.0)});
  }
  return out;
}

// Irregular real meshes: bunny_low (valences 3 to 11, uneven triangles, a few creases) and
// OpenSCAD's sphere_fn16 (thin triangles in fans round the poles). The criterion used to
// look only at the new points of the next two steps; here the uniform level at the cap was
// 1.65 tol from the bunny at tol 0.01 and 1.11 tol from the sphere at 0.05 (the limit is
// farthest at the middle of coarse edges, where those points are not). Both directions are
// checked, with no slack: every vertex of the uniform level at the cap is within tol of the
// adaptive mesh, and every point sampled on an adaptive face within tol of the uniform level.
// Where the cap stops the refinement (over_criterion_at_cap > 0) the promise is the same:
// within tol of the uniform level at that cap.
void expect_within_tolerance_of_uniform(const std::string& file, double tol) {
  const Level coarse = read_corpus_level(file);
  const int cap = 4;
  for (const char* scheme : {"sqrt3-interp", "sqrt3-unified"}) {
    SCOPED_TRACE(file + " " + scheme + " tol " + std::to_string(tol));
    const Outcome r = adapt(coarse, scheme, {0, tol, cap});
    const Level u = uniform(coarse, scheme, cap);
    expect_conforming(coarse, r);
    // Fewer faces than the uniform level: 0.05-0.34 times on the bunny; on the sphere at
    // 0.01 the cap stops most of it (0.87 times).
    EXPECT_LT(r.level.mesh.num_faces(), u.mesh.num_faces());
    const double to_adaptive = worst_distance(u.mesh.positions(), r.level.mesh, 2 * tol);
    const double to_uniform = worst_distance(face_samples(r.level.mesh), u.mesh, 2 * tol);
    EXPECT_LE(to_adaptive, tol) << "uniform vertex to the adaptive mesh";
    EXPECT_LE(to_uniform, tol) << "adaptive face to the uniform level";
  }
}

TEST(AdaptiveSqrt3, ToleranceHoldsOnTheIrregularBunny) {
  for (double tol : {0.01, 0.005}) expect_within_tolerance_of_uniform("bunny_low.stl", tol);
}

TEST(AdaptiveSqrt3, ToleranceHoldsOnTheSphereWithPolarFans) {
  for (double tol : {0.05, 0.02, 0.01}) expect_within_tolerance_of_uniform("sphere_fn16.stl", tol);
}

TEST(AdaptiveSqrt3, EdgeNeighbourClosureMakesFewerFacesFromTheSamePoints) {
  // The stencil closure refines triangles only so that stencils are in the mesh; the edge
  // closure leaves those out. The points are the hierarchy's either way.
  std::size_t fewer = 0;
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.name);
    const Outcome stencil = adapt(c.level, "sqrt3-interp", {15, 0, 5});
    const Outcome edges = adapt(c.level, "sqrt3-interp", {15, 0, 5, Sqrt3Closure::EdgeNeighbours});
    expect_conforming(c.level, edges);
    EXPECT_LE(edges.level.mesh.num_faces(), stencil.level.mesh.num_faces());
    EXPECT_LE(edges.stats.refined_by_closure, stencil.stats.refined_by_closure);
    fewer += edges.level.mesh.num_faces() < stencil.level.mesh.num_faces();
    const std::vector<Vec3> all = sorted_positions(stencil.level.mesh);
    for (const Vec3& p : edges.level.mesh.positions())
      EXPECT_TRUE(std::binary_search(all.begin(), all.end(), p, vec_less)) << str(p);
  }
  EXPECT_GE(fewer, 4u);  // bumpy grid, polyline, cylinder, jittered sphere
}

TEST(AdaptiveSqrt3, CylinderRefinesItsSideKeepsCapsFlatAndRimsInTheirPlanes) {
  const double radius = 10, height = 20;
  const Level coarse = make_level(to_mesh(cylinder_soup(12, radius, height)), 35);
  for (const char* scheme : kSchemes) {
    SCOPED_TRACE(scheme);
    const Outcome r = adapt(coarse, scheme, {10, 0, 5});
    expect_conforming(coarse, r);
    const Mesh& m = r.level.mesh;
    EXPECT_GT(m.num_faces(), 9 * coarse.mesh.num_faces());
    std::size_t rim = 0;
    for (std::uint32_t v = 0; v < m.num_vertices(); ++v) {
      const Vec3 p = m.position(VertexId(v));
      const bool in_cap = p.z == 0 || p.z == height;
      // The curve rule's weights sum to 1 up to rounding.
      const bool near_cap = std::abs(p.z) < 1e-12 || std::abs(p.z - height) < 1e-12;
      if (r.level.features.kind(VertexId(v)) != VertexKind::Smooth) {
        ++rim;
        EXPECT_TRUE(near_cap) << str(p);  // crease vertices stay on their rim, in its plane
        EXPECT_NEAR(std::hypot(p.x, p.y), radius, 0.05 * radius) << str(p);
      } else if (!in_cap) {
        EXPECT_GT(p.z, 0) << str(p);
        EXPECT_LT(p.z, height) << str(p);
      }
    }
    EXPECT_GE(rim, 2u * 12u * 3u);  // the rims were trisected
    // Sharp edges are never flipped: every sharp edge of the output joins two rim vertices
    // of one cap.
    for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
      if (!r.level.features.is_sharp(EdgeId(e))) continue;
      const HalfedgeId h = m.halfedge(EdgeId(e));
      EXPECT_NEAR(m.position(m.from(h)).z, m.position(m.to(h)).z, 1e-12);
    }
  }
}

TEST(AdaptiveSqrt3, CornersAndInputVerticesOfInterpolatingSchemesNeverMove) {
  for (const char* scheme : kSchemes) {
    for (const Case& c : cases()) {
      SCOPED_TRACE(std::string(scheme) + " " + c.name);
      const Outcome r = adapt(c.level, scheme, {10, 0, 4});
      const bool interpolating = make_scheme(scheme)->interpolating();
      for (std::uint32_t v = 0; v < c.level.mesh.num_vertices(); ++v) {
        if (!interpolating && c.level.features.kind(VertexId(v)) != VertexKind::Corner) continue;
        EXPECT_EQ(r.level.mesh.position(VertexId(v)), c.level.mesh.position(VertexId(v)));
      }
    }
  }
}

TEST(AdaptiveSqrt3, SharpEdgesOfTheOutputAreSharpEdgesOfTheUniformLevel) {
  // Creases are trisected with the curve rule on both sides at once and never flipped: in
  // the interpolating scheme each output sharp edge joins two sharp vertices of the
  // uniform level at the cap.
  const Level coarse = tagged_polyline_level(true);
  const int cap = 4;
  const Outcome r = adapt(coarse, "sqrt3-interp", {5, 0, cap});
  const Level u = uniform(coarse, "sqrt3-interp", cap);
  std::vector<Vec3> sharp_vertices;
  for (std::uint32_t v = 0; v < u.mesh.num_vertices(); ++v)
    if (u.features.kind(VertexId(v)) != VertexKind::Smooth)
      sharp_vertices.push_back(u.mesh.position(VertexId(v)));
  std::sort(sharp_vertices.begin(), sharp_vertices.end(), vec_less);
  std::size_t interior_sharp = 0;
  for (std::uint32_t e = 0; e < r.level.mesh.num_edges(); ++e) {
    if (!r.level.features.is_sharp(EdgeId(e))) continue;
    const HalfedgeId h = r.level.mesh.halfedge(EdgeId(e));
    interior_sharp += !r.level.mesh.is_boundary(h);
    for (const VertexId v : {r.level.mesh.from(h), r.level.mesh.to(h)})
      EXPECT_TRUE(std::binary_search(sharp_vertices.begin(), sharp_vertices.end(),
                                     r.level.mesh.position(v), vec_less));
  }
  EXPECT_GT(interior_sharp, 11u);  // the tagged polyline has 11 edges and was trisected
}

TEST(AdaptiveSqrt3, FlatInputIsLeftAlone) {
  for (const char* scheme : kSchemes) {
    const Level cube = make_level(to_mesh(cube_soup(2.0)), 35);
    const Outcome r = adapt(cube, scheme, {1, 1e-9, 6});
    EXPECT_EQ(r.level.mesh.num_faces(), cube.mesh.num_faces()) << scheme;
    EXPECT_EQ(r.stats.levels, 0) << scheme;
  }
}

TEST(AdaptiveSqrt3, StopsAtTheFaceBudgetWithAClearError) {
  const Level sphere = make_level(to_mesh(icosphere_soup(1, 10.0)), 35);
  try {
    adapt(sphere, "sqrt3-interp", {1, 0, 6}, 2000);
    FAIL() << "expected the face budget to stop the refinement";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::BudgetExceeded);
    EXPECT_EQ(e.field(), "max_faces");
    EXPECT_NE(std::string(e.what()).find("2000"), std::string::npos) << e.what();
  }
  // At the budget exactly is fine: a run that needs 80 * 27 faces at most.
  const Outcome r = adapt(sphere, "sqrt3-interp", {1, 0, 3}, 80 * 27);
  EXPECT_EQ(r.level.mesh.num_faces(), 80u * 27u);
}

TEST(AdaptiveSqrt3, RefineRunsItWithBothCriteriaAndReportsIt) {
  RefineParams p;
  p.scheme = "sqrt3-interp";
  p.adaptive_angle = 3;  // neighbours differ by ~21 degrees, /sqrt3 per level
  p.max_level = 3;
  const Mesh sphere = to_mesh(icosphere_soup(1, 10.0));
  const RefineResult angle_only = refine(sphere, p);
  EXPECT_EQ(angle_only.report.levels, 3);
  EXPECT_EQ(angle_only.report.adaptive_angle, 3);
  EXPECT_GT(angle_only.report.faces_over_criterion, 0u);  // 3 degrees needs more than 3 levels
  EXPECT_EQ(angle_only.report.max_input_displacement, 0);
  p.adaptive_tol = 1e-6;  // either criterion refines: now everything is refined
  const RefineResult both = refine(sphere, p);
  EXPECT_EQ(both.mesh.num_faces(), 80u * 27u);
  EXPECT_GE(both.mesh.num_faces(), angle_only.mesh.num_faces());
  EXPECT_EQ(check_face_budget(80, p), 80u * 27u);  // the bound from max_level
}

TEST(AdaptiveSqrt3, ValidationNamesTheField) {
  auto field_of = [](const RefineParams& p) {
    try {
      p.validate();
    } catch (const Error& e) {
      return std::string(e.field());
    }
    return std::string("none");
  };
  RefineParams p;
  p.scheme = "sqrt3";
  p.adaptive_angle = 20;
  EXPECT_EQ(field_of(p), "none");  // every sqrt3 scheme has the adaptive mode
  p.adaptive_angle = 181;
  EXPECT_EQ(field_of(p), "adaptive_angle");
  p.adaptive_angle = -1;
  EXPECT_EQ(field_of(p), "adaptive_angle");
  p.adaptive_angle = std::nan("");
  EXPECT_EQ(field_of(p), "adaptive_angle");
  p.adaptive_angle = 20;
  p.scheme = "loop";  // approximating 1-to-4: no adaptive mode
  EXPECT_EQ(field_of(p), "adaptive_angle");
  p.scheme = "butterfly";
  EXPECT_EQ(field_of(p), "none");
}

TEST(AdaptiveSqrt3, CancelStopsIt) {
  std::atomic<bool> cancel{true};
  RefineParams p;
  p.scheme = "sqrt3-interp";
  p.adaptive_angle = 1;
  p.max_level = 6;
  try {
    refine(to_mesh(icosphere_soup(2, 10.0)), p, {}, &cancel);
    FAIL() << "expected Cancelled";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Cancelled);
  }
}

TEST(AdaptiveSqrt3, CancelStopsItBeforeTheNextTriangle) {
  // Raised when level 1 starts: no level-1 triangle is examined, so the run stops with
  // exactly the splits of a run capped at level 1 (not at the next 1024th split).
  const Level sphere = make_level(to_mesh(icosphere_soup(2, 10.0)), 35);
  const auto s = make_scheme("sqrt3-interp");
  AdaptiveSqrt3 capped(sphere, *adaptive_sqrt3_scheme(*s), {1, 0, 1});
  capped.run(1u << 26);
  const std::size_t level0_splits =
      capped.stats().refined_by_criterion + capped.stats().refined_by_closure;
  ASSERT_GT(level0_splits, 0u);

  std::atomic<bool> cancel{false};
  AdaptiveSqrt3 adaptive(sphere, *adaptive_sqrt3_scheme(*s), {1, 0, 6});
  try {
    adaptive.run(1u << 26, &cancel, [&](int l) {
      if (l == 1) cancel = true;
    });
    FAIL() << "expected Cancelled";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Cancelled);
  }
  EXPECT_EQ(adaptive.stats().refined_by_criterion + adaptive.stats().refined_by_closure,
            level0_splits);
}

TEST(AdaptiveSqrt3, CancelScopeStopsItWhileOnlyExamining) {
  // A flat input: every triangle is examined, none is split. The job's flag reaches the
  // run through the CancelScope alone (no flag passed).
  const Level cube = make_level(to_mesh(cube_soup(2.0)), 35);
  const auto s = make_scheme("sqrt3-interp");
  AdaptiveSqrt3 adaptive(cube, *adaptive_sqrt3_scheme(*s), {0, 1e-9, 6});
  std::atomic<bool> cancel{true};
  const CancelScope scope(&cancel);
  try {
    adaptive.run(1u << 26);
    FAIL() << "expected Cancelled";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Cancelled);
  }
}

// --- the dihedral criterion of the 1-to-4 adaptive mode (for the paper's comparison)

TEST(AdaptiveSplit4Angle, ButterflyRefinesByTheDihedralAngle) {
  RefineParams p;
  p.scheme = "butterfly";
  p.adaptive_angle = 10;
  p.max_level = 3;
  // The 35 degree angle this test was written for: it creases the coarse torus's 45 degree
  // edges, which the criterion then leaves alone. Auto (the default since issue 17) finds no
  // crease on a torus, and every face of this one is still over 10 degrees at level 2.
  p.features.crease_mode = CreaseMode::Angle;
  const Mesh torus = to_mesh(torus_soup(12, 8, 20.0, 6.0));
  const RefineResult r = refine(torus, p);
  EXPECT_EQ(r.mesh.check_invariants(), "");
  EXPECT_EQ(boundary_halfedges(r.mesh), 0u);
  EXPECT_GT(r.mesh.num_faces(), torus.num_faces());
  EXPECT_LT(r.mesh.num_faces(), 64 * torus.num_faces());
  // The report counts exactly the edges still over the angle at the cap.
  const Level final_level{r.mesh, detect_features(r.mesh, p.features)};
  EXPECT_EQ(
      r.report.edges_over_tolerance,
      count_edges_over_tolerance(final_level, *adaptive_scheme(*make_scheme("butterfly")), 0, 10));
  // A looser angle refines less.
  p.adaptive_angle = 20;
  EXPECT_LT(refine(torus, p).mesh.num_faces(), r.mesh.num_faces());
}

}  // namespace
}  // namespace stlrefine::test
