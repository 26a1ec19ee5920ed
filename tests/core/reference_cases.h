// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Meshes on which the production 1-to-4 stencils are compared, point by point, with the
// spec-only reference in tests/support/reference_split4.h, and the comparison itself.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "core/schemes/scheme.h"
#include "tests/core/test_util.h"
#include "tests/support/mesh_queries.h"
#include "tests/support/reference_split4.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {

struct RefCase {
  std::string name;
  std::function<Level()> make;
};

//! Deterministic pseudo-random numbers in [-1, 1] (no <random>: same on every platform).
inline double jitter(std::uint32_t i, std::uint32_t salt) {
  std::uint32_t x = i * 2654435761u + salt * 40503u + 12345u;
  x ^= x >> 13;
  x *= 0x5bd1e995u;
  x ^= x >> 15;
  return (x % 20001u) / 10000.0 - 1.0;
}

//! A flat n x n grid in a tilted plane that misses the origin, with in-plane jitter.
inline IndexedSoup jittered_plane_soup(int n) {
  const Vec3 u = normalized(Vec3{1, 0.2, 0.3});
  const Vec3 w = normalized(cross(u, Vec3{0.1, 1, 0.2}));  // plane normal
  const Vec3 v = cross(w, u);
  IndexedSoup soup = grid_soup(n, n, w * 5.0 + u * 2.0, u, v);
  for (std::uint32_t i = 0; i < soup.positions.size(); ++i)
    soup.positions[i] += u * (0.2 * jitter(i, 1)) + v * (0.2 * jitter(i, 2));
  return soup;
}
inline Vec3 jittered_plane_normal() {
  const Vec3 u = normalized(Vec3{1, 0.2, 0.3});
  return normalized(cross(u, Vec3{0.1, 1, 0.2}));
}

//! A grid with small random heights (all interior valences 6, boundary present).
inline IndexedSoup bumpy_grid_soup(int n, double amplitude) {
  IndexedSoup soup = grid_soup(n, n, {-1, -1, 0}, {2.0 / n, 0, 0}, {0, 2.0 / n, 0});
  for (std::uint32_t i = 0; i < soup.positions.size(); ++i)
    soup.positions[i].z = amplitude * jitter(i, 3);
  return soup;
}

//! Every position moved by up to `amount` per coordinate: irregular rings, so rules with
//! weights that cancel on symmetric rings (e.g. the cos(4 pi j/k) terms) show.
inline IndexedSoup jittered(IndexedSoup soup, double amount) {
  for (std::uint32_t i = 0; i < soup.positions.size(); ++i)
    soup.positions[i] += Vec3{jitter(i, 4), jitter(i, 5), jitter(i, 6)} * amount;
  return soup;
}

inline double cubic_field(double x, double y) {
  return 0.1 + 0.3 * x - 0.2 * y + 0.15 * x * x - 0.1 * x * y + 0.05 * y * y + 0.02 * x * x * x -
         0.03 * x * x * y + 0.04 * x * y * y - 0.01 * y * y * y;
}

//! 8x8 grid with a tagged sharp polyline from the left boundary to the top boundary with a
//! bend: (0,3)..(3,3) then (3,3)..(3,8). Its ends are corners (3 sharp edges), (3,3) is an
//! irregular crease vertex, the others regular. Heights are bumped so every rule matters.
inline Level tagged_polyline_level(bool with_dart_spur) {
  const int n = 8;
  IndexedSoup soup = bumpy_grid_soup(n, 0.05);
  const Mesh m = to_mesh(soup);
  auto V = [&](int i, int j) { return find_vertex(m, soup.positions[grid_index(n, i, j)]); };
  std::vector<std::pair<VertexId, VertexId>> sharp;
  for (int i = 0; i < 3; ++i) sharp.push_back({V(i, 3), V(i + 1, 3)});
  for (int j = 3; j < n; ++j) sharp.push_back({V(3, j), V(3, j + 1)});
  if (with_dart_spur) {
    // (5,5)-(6,5)-(7,5): darts at both ends; (6,1)-(6,2): a single sharp edge.
    sharp.push_back({V(5, 5), V(6, 5)});
    sharp.push_back({V(6, 5), V(7, 5)});
    sharp.push_back({V(6, 1), V(6, 2)});
  }
  return make_level_with_sharp(m, sharp);
}

inline std::vector<RefCase> reference_cases() {
  auto lv = [](std::function<IndexedSoup()> soup, double angle) {
    return [soup, angle] { return make_level(to_mesh(soup()), angle); };
  };
  return {
      {"IcosahedronSmooth", lv([] { return icosahedron_soup(); }, 180)},
      {"IcosahedronAllCorners", lv([] { return icosahedron_soup(); }, 35)},
      {"OctahedronSmooth", lv([] { return octahedron_soup(); }, 180)},
      {"TetrahedronSmooth", lv([] { return tetrahedron_soup(); }, 180)},
      {"Cube", lv([] { return cube_soup(1.0); }, 35)},
      {"CubeSmooth", lv([] { return cube_soup(1.0); }, 180)},
      {"Bipyramid5", lv([] { return bipyramid_soup(5, 1.3); }, 180)},
      {"Bipyramid7", lv([] { return bipyramid_soup(7, 0.9); }, 180)},
      {"Bipyramid9", lv([] { return bipyramid_soup(9, 0.7); }, 180)},
      {"OpenGrid", lv([] { return grid_soup(6, 5); }, 35)},
      {"JitteredPlane", lv([] { return jittered_plane_soup(6); }, 35)},
      {"BumpyGrid", lv([] { return bumpy_grid_soup(8, 0.1); }, 180)},
      {"CubicHeightField",
       lv([] { return height_field_soup(8, 8, -1, -1, 0.25, cubic_field); }, 180)},
      {"Cylinder24", lv([] { return cylinder_soup(24, 10, 20); }, 35)},
      {"Cylinder8Corners", lv([] { return cylinder_soup(8, 10, 30); }, 35)},
      {"Cylinder8Smooth", lv([] { return cylinder_soup(8, 10, 15); }, 180)},
      {"Icosphere", lv([] { return icosphere_soup(1, 2.0); }, 180)},
      {"JitteredIcosphere", lv([] { return jittered(icosphere_soup(1, 2.0), 0.1); }, 180)},
      {"JitteredBipyramid7", lv([] { return jittered(bipyramid_soup(7, 0.9), 0.1); }, 180)},
      {"JitteredBipyramid5", lv([] { return jittered(bipyramid_soup(5, 1.1), 0.1); }, 180)},
      {"IcosphereCreased", lv([] { return icosphere_soup(1, 2.0); }, 20)},
      {"Torus", lv([] { return torus_soup(10, 7, 3, 1); }, 180)},
      {"Fan3", lv([] { return fan_soup(3, 0.3); }, 180)},
      {"Fan4", lv([] { return fan_soup(4, 0.3); }, 180)},
      {"Fan5", lv([] { return fan_soup(5, 0.3); }, 180)},
      {"Fan6", lv([] { return fan_soup(6, 0.3); }, 180)},
      {"Fan7", lv([] { return fan_soup(7, 0.3); }, 180)},
      {"Fan9", lv([] { return fan_soup(9, 0.3); }, 180)},
      {"TaggedPolyline", [] { return tagged_polyline_level(false); }},
      {"TaggedDarts", [] { return tagged_polyline_level(true); }},
  };
}

//! Describes coarse edge e for failure messages.
inline std::string describe_edge(const Level& level, EdgeId e) {
  const Mesh& m = level.mesh;
  const HalfedgeId h = m.halfedge(e);
  std::ostringstream os;
  auto vdesc = [&](VertexId v) {
    os << "v" << v.idx << "[" << to_string(level.features.kind(v)) << ", valence " << m.valence(v)
       << (m.is_boundary(v) ? ", boundary" : "") << "] " << str(m.position(v));
  };
  os << "edge " << e.idx << (level.features.is_sharp(e) ? " (sharp)" : "") << " from ";
  vdesc(m.from(h));
  os << " to ";
  vdesc(m.to(h));
  return os.str();
}

//! Every fine position equals the reference within tol * scale. Edge points the spec leaves
//! open (ref.unspecified) and those flagged in `skip_edge` (e.g. ones a fold guard may
//! legitimately move) are not compared.
inline void expect_matches_reference(const Level& coarse, const Level& fine,
                                     const ReferenceStep& ref,
                                     const std::vector<bool>& skip_edge = {}) {
  const Mesh& c = coarse.mesh;
  ASSERT_EQ(fine.mesh.num_vertices(), ref.positions.size());
  const double tol = 1e-12 * std::max(1.0, max_abs_coord(c.positions()));
  int failures = 0;
  for (std::uint32_t i = 0; i < ref.positions.size() && failures < 12; ++i) {
    const Vec3 got = fine.mesh.position(VertexId(i));
    const Vec3& want = ref.positions[i];
    const double d =
        std::max({std::abs(got.x - want.x), std::abs(got.y - want.y), std::abs(got.z - want.z)});
    if (d <= tol) continue;
    if (i >= c.num_vertices()) {
      const std::size_t e = i - c.num_vertices();
      if (ref.unspecified[e] || (!skip_edge.empty() && skip_edge[e])) continue;
    }
    ++failures;
    if (i < c.num_vertices()) {
      ADD_FAILURE() << "old vertex " << i << " [" << to_string(coarse.features.kind(VertexId(i)))
                    << ", valence " << c.valence(VertexId(i)) << "] at "
                    << str(c.position(VertexId(i))) << "\n  got  " << str(got) << "\n  want "
                    << str(want);
    } else {
      const EdgeId e(static_cast<std::uint32_t>(i - c.num_vertices()));
      ADD_FAILURE() << describe_edge(coarse, e) << "\n  got  " << str(got) << "\n  want "
                    << str(want);
    }
  }
}

//! Edges of coarse faces that have a child turned by more than 90 degrees (reference
//! positions): a fold guard may move their points.
inline std::vector<bool> edges_of_folded_faces(const Mesh& coarse, const ReferenceStep& ref) {
  std::vector<bool> out(coarse.num_edges(), false);
  const auto faces = reference_split4_faces(coarse);
  for (std::uint32_t f = 0; f < coarse.num_faces(); ++f) {
    const Vec3 np = coarse.face_normal(FaceId(f));
    bool folded = false;
    for (int k = 0; k < 4; ++k) {
      const auto& t = faces[4 * f + k];
      const Vec3 nc =
          triangle_normal(ref.positions[t[0]], ref.positions[t[1]], ref.positions[t[2]]);
      folded = folded || dot(np, nc) < 0;
    }
    if (!folded) continue;
    for (int k = 0; k < 3; ++k) out[coarse.edge(Mesh::halfedge(FaceId(f), k)).idx] = true;
  }
  return out;
}

}  // namespace stlrefine::test
