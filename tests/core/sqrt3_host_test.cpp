// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
//
// The sqrt3 topology host (spec 3.1) with a linear stencil (centroids, points at 1/3 and
// 2/3 of sharp edges): counts, invariants, derived features, the two-step trisection, the
// alpha it carries to new vertices.
#include "core/schemes/sqrt3_host.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "core/error.h"
#include "tests/core/reference_cases.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {
namespace {

// Linear rules: with them two steps of sqrt3 turn a planar lattice into the lattice of
// one third the spacing. The alpha it asks for is each vertex's x coordinate, which the
// host must then carry exactly like the positions.
class LinearSqrt3Stencil final : public Sqrt3Stencil {
 public:
  bool interpolating() const override { return true; }
  // The tests below check the host's linear bookkeeping: the fold guard (which moves face
  // points where even the linear split folds, e.g. on the torus) would hide it.
  bool guards_folds() const override { return false; }
  BigVector<double> initial_alpha(const Level& input) const override {
    BigVector<double> alpha;
    for (const Vec3& p : input.mesh.positions()) alpha.push_back(p.x);
    return alpha;
  }
  void points(const Sqrt3Step& step, Sqrt3Points out) const override {
    const Mesh& m = step.mesh;
    std::copy(m.positions().begin(), m.positions().end(), out.vertices.begin());
    for (std::uint32_t f = 0; f < m.num_faces(); ++f)
      if (step.has_face_point(FaceId(f))) out.faces[f] = face_point(step, FaceId(f));
  }
  Vec3 face_point(const Sqrt3Step& step, FaceId f) const override {
    const Mesh& m = step.mesh;
    const auto [a, b, c] = m.face_vertices(f);
    return (m.position(a) + m.position(b) + m.position(c)) * (1.0 / 3.0);
  }
  Vec3 vertex_point(const Sqrt3Step& step, VertexId v) const override {
    return step.mesh.position(v);
  }
  std::array<Vec3, 2> curve_points(const Sqrt3Step& step, HalfedgeId h) const override {
    const Vec3 a = step.mesh.position(step.mesh.from(h)), b = step.mesh.position(step.mesh.to(h));
    return {(2.0 * a + b) * (1.0 / 3.0), (a + 2.0 * b) * (1.0 / 3.0)};
  }
};

std::vector<std::pair<std::string, Level>> sample_levels() {
  std::vector<std::pair<std::string, Level>> out;
  out.emplace_back("icosahedron", make_level(to_mesh(icosahedron_soup())));
  out.emplace_back("tetrahedron", make_level(to_mesh(tetrahedron_soup())));
  out.emplace_back("cube", make_level(to_mesh(cube_soup(1.0))));
  out.emplace_back("grid", make_level(to_mesh(grid_soup(4, 3))));
  out.emplace_back("fan", make_level(to_mesh(fan_soup(5))));
  out.emplace_back("cylinder", make_level(to_mesh(cylinder_soup(8, 1, 3))));
  out.emplace_back("torus", make_level(to_mesh(torus_soup(8, 6, 3, 1))));
  out.emplace_back("polyline", tagged_polyline_level(true));
  Level one;
  one.mesh = to_mesh(IndexedSoup{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 1, 2}}});
  one.features = detect_features(one.mesh, {});
  out.emplace_back("triangle", std::move(one));
  return out;
}

std::size_t boundary_edges(const Mesh& m) {
  std::size_t n = 0;
  for (std::uint32_t e = 0; e < m.num_edges(); ++e) n += m.is_boundary(EdgeId(e));
  return n;
}

// The host's derived features must equal a fresh classification from its sharp flags.
void expect_features_consistent(const Level& level) {
  const Mesh& m = level.mesh;
  BigVector<std::uint8_t> flags(level.features.sharp_edges().begin(),
                                level.features.sharp_edges().end());
  const Features fresh(m, std::move(flags));
  EXPECT_EQ(fresh.num_sharp_edges(), level.features.num_sharp_edges());
  for (std::uint32_t v = 0; v < m.num_vertices(); ++v) {
    const VertexId id(v);
    ASSERT_EQ(fresh.kind(id), level.features.kind(id)) << "vertex " << v;
    if (fresh.kind(id) != VertexKind::Crease) continue;
    auto a = fresh.curve_neighbours(id), b = level.features.curve_neighbours(id);
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    EXPECT_EQ(a, b) << "curve neighbours of vertex " << v;
  }
}

TEST(Sqrt3Host, CountsAndInvariantsOverFourSteps) {
  const LinearSqrt3Stencil stencil;
  for (auto& [name, input] : sample_levels()) {
    SCOPED_TRACE(name);
    Level level = std::move(input);
    const long euler = long(level.mesh.num_vertices()) - long(level.mesh.num_edges()) +
                       long(level.mesh.num_faces());
    // Valences at the last even level (the input counts as level 0).
    std::vector<int> valence_before;
    for (std::uint32_t v = 0; v < level.mesh.num_vertices(); ++v)
      valence_before.push_back(level.mesh.valence(VertexId(v)));
    for (int step = 1; step <= 4; ++step) {
      SCOPED_TRACE("step " + std::to_string(step));
      StepStats stats;
      const Mesh& c = level.mesh;
      const bool trisects = step % 2 == 0;
      const std::size_t bc = boundary_edges(c);
      Level fine = sqrt3_refine(level, stencil, stats);
      const Mesh& m = fine.mesh;
      ASSERT_EQ(m.check_invariants(), "");
      EXPECT_EQ(fine.step, step);
      EXPECT_EQ(m.num_faces(), 3 * c.num_faces());
      EXPECT_EQ(m.num_vertices(), c.num_vertices() + c.num_faces() + (trisects ? bc : 0));
      EXPECT_EQ(m.num_edges(), c.num_edges() + 3 * c.num_faces() + (trisects ? bc : 0));
      EXPECT_EQ(long(m.num_vertices()) - long(m.num_edges()) + long(m.num_faces()), euler);
      EXPECT_EQ(boundary_edges(m), trisects ? 3 * bc : bc);
      EXPECT_EQ(fine.features.num_sharp_edges(),
                (trisects ? 3 : 1) * level.features.num_sharp_edges());
      for (std::uint32_t v = 0; v < c.num_vertices(); ++v) {
        EXPECT_EQ(m.position(VertexId(v)), c.position(VertexId(v)));
        // Odd steps keep the valence of a vertex with no sharp edge. One with sharp edges
        // gains an edge per sector and loses it again in the even step after.
        if (!trisects && level.features.kind(VertexId(v)) == VertexKind::Smooth) {
          EXPECT_EQ(m.valence(VertexId(v)), c.valence(VertexId(v))) << "old vertex " << v;
        }
        if (trisects && v < valence_before.size()) {
          EXPECT_EQ(m.valence(VertexId(v)), valence_before[v]) << "old vertex " << v;
        }
      }
      if (trisects) {
        // Face points and trisection points are regular: valence 6 inside, 4 on a boundary.
        for (std::uint32_t v = c.num_vertices(); v < m.num_vertices(); ++v)
          EXPECT_EQ(m.valence(VertexId(v)), m.is_boundary(VertexId(v)) ? 4 : 6)
              << "new vertex " << v;
        valence_before.clear();
        for (std::uint32_t v = 0; v < m.num_vertices(); ++v)
          valence_before.push_back(m.valence(VertexId(v)));
      }
      expect_features_consistent(fine);
      // Every sharp fine edge lies on a sharp coarse edge: collinear with it.
      for (std::uint32_t e = 0; e < m.num_edges(); ++e) {
        if (!fine.features.is_sharp(EdgeId(e))) continue;
        const HalfedgeId h = m.halfedge(EdgeId(e));
        const Vec3 p = m.position(m.from(h)), q = m.position(m.to(h));
        bool on_coarse = false;
        for (std::uint32_t ce = 0; ce < c.num_edges() && !on_coarse; ++ce) {
          if (!level.features.is_sharp(EdgeId(ce))) continue;
          const HalfedgeId ch = c.halfedge(EdgeId(ce));
          const Vec3 a = c.position(c.from(ch)), b = c.position(c.to(ch));
          on_coarse = norm(cross(b - a, p - a)) < 1e-12 && norm(cross(b - a, q - a)) < 1e-12 &&
                      dot(p - a, p - b) <= 1e-12 && dot(q - a, q - b) <= 1e-12;
        }
        EXPECT_TRUE(on_coarse) << "sharp edge " << str(p) << " - " << str(q);
      }
      level = std::move(fine);
    }
  }
}

TEST(Sqrt3Host, NoSharpEdgeIsFlipped) {
  // Odd steps keep every sharp edge; even steps cut each into three.
  const LinearSqrt3Stencil stencil;
  Level level = make_level(to_mesh(cube_soup(2.0)));
  StepStats stats;
  const Level odd = sqrt3_refine(level, stencil, stats);
  for (std::uint32_t e = 0; e < level.mesh.num_edges(); ++e) {
    if (!level.features.is_sharp(EdgeId(e))) continue;
    const HalfedgeId h = level.mesh.halfedge(EdgeId(e));
    const EdgeId kept = find_edge(odd.mesh, level.mesh.from(h), level.mesh.to(h));
    ASSERT_TRUE(kept.valid());
    EXPECT_TRUE(odd.features.is_sharp(kept));
  }
  // ... and every non-sharp one is gone (flipped).
  for (std::uint32_t e = 0; e < level.mesh.num_edges(); ++e) {
    if (level.features.is_sharp(EdgeId(e))) continue;
    const HalfedgeId h = level.mesh.halfedge(EdgeId(e));
    EXPECT_FALSE(find_edge(odd.mesh, level.mesh.from(h), level.mesh.to(h)).valid());
  }
}

// After two steps every coarse edge is cut into three fine edges and every coarse
// triangle into nine (spec 3.1), with and without a boundary.
TEST(Sqrt3Host, TwoStepsTrisectEveryEdgeAndNineEveryTriangle) {
  const LinearSqrt3Stencil stencil;
  // Affine lattices: there the centroid rule puts level-2 points at the thirds of edges.
  for (const Level& coarse :
       {make_level(to_mesh(grid_soup(5, 4)), 35),
        make_level(to_mesh(grid_soup(4, 4, {1, 2, 3}, {1, 0.2, 0.1}, {0.3, 1, -0.2})), 35)}) {
    StepStats stats;
    const Level fine = sqrt3_refine(sqrt3_refine(coarse, stencil, stats), stencil, stats);
    const Mesh& c = coarse.mesh;
    const Mesh& m = fine.mesh;
    ASSERT_EQ(m.num_faces(), 9 * c.num_faces());
    auto vertex_near = [&](const Vec3& p) {
      for (std::uint32_t v = 0; v < m.num_vertices(); ++v)
        if (distance(m.position(VertexId(v)), p) < 1e-12) return VertexId(v);
      return VertexId();
    };
    for (std::uint32_t e = 0; e < c.num_edges(); ++e) {
      const HalfedgeId h = c.halfedge(EdgeId(e));
      const VertexId a = c.from(h), b = c.to(h);
      const VertexId m1 = vertex_near((2.0 * c.position(a) + c.position(b)) * (1.0 / 3.0));
      const VertexId m2 = vertex_near((c.position(a) + 2.0 * c.position(b)) * (1.0 / 3.0));
      ASSERT_TRUE(m1.valid() && m2.valid()) << "edge " << e;
      EXPECT_TRUE(find_edge(m, a, m1).valid()) << "edge " << e;
      EXPECT_TRUE(find_edge(m, m1, m2).valid()) << "edge " << e;
      EXPECT_TRUE(find_edge(m, m2, b).valid()) << "edge " << e;
    }
    // Each coarse triangle holds the centroids of exactly nine fine triangles.
    for (std::uint32_t f = 0; f < c.num_faces(); ++f) {
      const auto [a, b, d] = c.face_vertices(FaceId(f));
      const Vec3 pa = c.position(a), pb = c.position(b), pd = c.position(d);
      const Vec3 n = cross(pb - pa, pd - pa);
      int inside = 0;
      for (std::uint32_t g = 0; g < m.num_faces(); ++g) {
        const auto [x, y, z] = m.face_vertices(FaceId(g));
        const Vec3 q = (m.position(x) + m.position(y) + m.position(z)) * (1.0 / 3.0);
        inside += dot(cross(pb - pa, q - pa), n) > 0 && dot(cross(pd - pb, q - pb), n) > 0 &&
                  dot(cross(pa - pd, q - pd), n) > 0;
      }
      EXPECT_EQ(inside, 9) << "coarse face " << f;
    }
  }
}

TEST(Sqrt3Host, CarriesAlphaLikeThePositions) {
  // The stencil's alpha is x; linear rules move points exactly as the host moves alpha
  // (face point: mean of the corners; curve point at 1/3: (2 a_i + a_i+1)/3).
  const LinearSqrt3Stencil stencil;
  for (auto& [name, input] : sample_levels()) {
    SCOPED_TRACE(name);
    Level level = std::move(input);
    for (int step = 1; step <= 4; ++step) {
      StepStats stats;
      level = sqrt3_refine(level, stencil, stats);
      ASSERT_EQ(level.alpha.size(), level.mesh.num_vertices());
      for (std::uint32_t v = 0; v < level.mesh.num_vertices(); ++v)
        ASSERT_NEAR(level.alpha[v], level.mesh.position(VertexId(v)).x, 1e-12)
            << "step " << step << " vertex " << v;
    }
  }
}

TEST(Sqrt3Host, EvenStepRefusesAFaceWithTwoSharpEdges) {
  // A lone triangle has three boundary edges: fine for an odd step, impossible in an even
  // one (the host never makes such a face), so it must say so rather than guess.
  Level level;
  level.mesh = to_mesh(IndexedSoup{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 1, 2}}});
  level.features = detect_features(level.mesh, {});
  level.step = 1;
  StepStats stats;
  try {
    sqrt3_refine(level, LinearSqrt3Stencil(), stats);
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::Internal);
  }
}

TEST(Sqrt3Host, PredictsThreeTimesTheFacesPerStep) {
  const HostScheme<Sqrt3Stencil> scheme("test", std::make_unique<LinearSqrt3Stencil>());
  EXPECT_EQ(scheme.predict_faces(20, 0), 20u);
  EXPECT_EQ(scheme.predict_faces(20, 1), 60u);
  EXPECT_EQ(scheme.predict_faces(20, 4), 1620u);
  EXPECT_EQ(scheme.predict_faces(UINT64_MAX / 2, 1), UINT64_MAX);
}

// The linear stencil with the host's fold guard on.
class GuardedLinearSqrt3Stencil final : public Sqrt3Stencil {
 public:
  bool interpolating() const override { return true; }
  void points(const Sqrt3Step& step, Sqrt3Points out) const override { linear_.points(step, out); }
  Vec3 face_point(const Sqrt3Step& step, FaceId f) const override {
    return linear_.face_point(step, f);
  }
  Vec3 vertex_point(const Sqrt3Step& step, VertexId v) const override {
    return linear_.vertex_point(step, v);
  }
  std::array<Vec3, 2> curve_points(const Sqrt3Step& step, HalfedgeId h) const override {
    return linear_.curve_points(step, h);
  }

 private:
  LinearSqrt3Stencil linear_;
};

// Issue 17 item 2: beside a long obtuse face the flipped quad (a, q_g, b, q_f) is not convex
// even with centroids, so the flip reverses a child; no face point can fix that. The guard
// keeps such an edge: the fine level has it, with the two 1-to-3 children beside it, and the
// face count is still 3F. Flat patch, a = (0,0), b = (1,0), c = (3,0.1) (f = abc), d =
// (0.5,-1) (g = bad): q_f = (4/3, 1/30), q_g = (1/2, -1/3), and (b, q_f, q_g) is clockwise.
TEST(Sqrt3Host, KeepsAnEdgeWhoseFlipWouldFold) {
  const IndexedSoup soup{{{0, 0, 0}, {1, 0, 0}, {3, 0.1, 0}, {0.5, -1, 0}}, {{0, 1, 2}, {1, 0, 3}}};
  const Level coarse = make_level(to_mesh(soup));
  const VertexId a = find_vertex(coarse.mesh, {0, 0, 0}), b = find_vertex(coarse.mesh, {1, 0, 0});
  ASSERT_FALSE(coarse.features.is_sharp(find_edge(coarse.mesh, a, b)));
  auto reversed_faces = [](const Mesh& m) {
    std::size_t n = 0;
    for (std::uint32_t f = 0; f < m.num_faces(); ++f) n += m.face_normal(FaceId(f)).z <= 0;
    return n;
  };
  // Without the guard the edge is flipped and a child is reversed: the case is real.
  StepStats stats;
  const Level unguarded = sqrt3_refine(coarse, LinearSqrt3Stencil(), stats);
  EXPECT_FALSE(find_edge(unguarded.mesh, a, b).valid());
  EXPECT_GT(reversed_faces(unguarded.mesh), 0u);
  const GuardedLinearSqrt3Stencil guarded;
  Level fine = sqrt3_refine(coarse, guarded, stats);
  ASSERT_EQ(fine.mesh.check_invariants(), "");
  EXPECT_TRUE(find_edge(fine.mesh, a, b).valid());
  EXPECT_EQ(fine.mesh.num_faces(), 3 * coarse.mesh.num_faces());
  EXPECT_EQ(reversed_faces(fine.mesh), 0u);
  EXPECT_GE(stats.fold_fallbacks, 1u);  // the kept edge
  expect_features_consistent(fine);
  // The next (trisecting) step refines the level with the kept edge like any other.
  const Level next = sqrt3_refine(fine, guarded, stats);
  ASSERT_EQ(next.mesh.check_invariants(), "");
  EXPECT_EQ(next.mesh.num_faces(), 9 * coarse.mesh.num_faces());
  EXPECT_EQ(reversed_faces(next.mesh), 0u);
  expect_features_consistent(next);
}

}  // namespace
}  // namespace stlrefine::test
