// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "tests/support/convex_hull.h"

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include "tests/support/random.h"

namespace stlrefine::test {
namespace {

using Tri = std::array<std::uint32_t, 3>;

std::vector<Vec3> sphere_points(std::uint64_t seed, int n, Vec3 scale = {1, 1, 1}) {
  Rng rng(seed);
  std::vector<Vec3> p;
  for (int i = 0; i < n; ++i) {
    const Vec3 d = rng.unit_vector();
    p.push_back({d.x * scale.x, d.y * scale.y, d.z * scale.z});
  }
  return p;
}

// Closed and consistently wound: every directed edge once, its reverse once.
void expect_closed_oriented(const std::vector<Tri>& tris) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
  for (const Tri& t : tris)
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  for (const auto& [e, count] : directed) {
    EXPECT_EQ(count, 1) << e.first << "->" << e.second;
    EXPECT_EQ(directed.count({e.second, e.first}), 1u) << e.first << "->" << e.second;
  }
}

// The hull property: every point lies on or behind every face's plane, and strictly
// behind it unless it is one of the face's corners.
void expect_hull(const std::vector<Vec3>& p, const std::vector<Tri>& tris) {
  for (const Tri& t : tris) {
    const Vec3 n = normalized(triangle_normal(p[t[0]], p[t[1]], p[t[2]]));
    for (std::uint32_t i = 0; i < p.size(); ++i) {
      if (i == t[0] || i == t[1] || i == t[2]) continue;
      EXPECT_LT(dot(n, p[i] - p[t[0]]), 1e-9) << "point " << i;
    }
  }
}

TEST(ConvexHull, TetrahedronIsWoundOutward) {
  const std::vector<Vec3> p{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const auto tris = convex_hull(p);
  ASSERT_EQ(tris.size(), 4u);
  expect_closed_oriented(tris);
  const Vec3 centre{0.25, 0.25, 0.25};
  for (const Tri& t : tris)
    EXPECT_GT(dot(triangle_normal(p[t[0]], p[t[1]], p[t[2]]), p[t[0]] - centre), 0);
}

TEST(ConvexHull, RandomSpherePointsGiveAClosedHullOfAllOfThem) {
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    const auto p = sphere_points(seed, 300, {12, 9, 6.5});
    const auto tris = convex_hull(p);
    // A triangulated sphere with every point a vertex: F = 2V - 4.
    EXPECT_EQ(tris.size(), 2 * p.size() - 4);
    expect_closed_oriented(tris);
    expect_hull(p, tris);
    std::set<std::uint32_t> used;
    for (const Tri& t : tris) used.insert(t.begin(), t.end());
    EXPECT_EQ(used.size(), p.size());
    for (const Tri& t : tris)  // outward: the origin is inside
      EXPECT_GT(dot(triangle_normal(p[t[0]], p[t[1]], p[t[2]]), p[t[0]]), 0);
  }
}

TEST(ConvexHull, RejectsInputsThatAreNotInConvexPosition) {
  auto p = sphere_points(5, 50);
  p.push_back({0, 0, 0});  // inside
  EXPECT_THROW(convex_hull(p), std::runtime_error);
  // Cube corners: four coplanar points per face.
  std::vector<Vec3> cube;
  for (int i = 0; i < 8; ++i) cube.push_back({double(i & 1), double(i >> 1 & 1), double(i >> 2)});
  EXPECT_THROW(convex_hull(cube), std::runtime_error);
  EXPECT_THROW(convex_hull(std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}), std::runtime_error);
  EXPECT_THROW(convex_hull(std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}}),
               std::runtime_error);
}

}  // namespace
}  // namespace stlrefine::test
