// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "core/io/stl.h"
#include "tests/io/io_test_util.h"

namespace stlrefine::test {
namespace {

TriangleSoup soup_of(std::vector<float> coords) {
  TriangleSoup soup;
  soup.coords = std::move(coords);
  return soup;
}

using Tri = std::array<std::uint32_t, 3>;

TEST(Weld, NumbersVerticesInOrderOfFirstAppearance) {
  // Two triangles sharing the edge (1,0,0)-(0,1,0).
  const IndexedSoup w = weld(soup_of({0, 0, 0, 1, 0, 0, 0, 1, 0,  //
                                      1, 1, 0, 0, 1, 0, 1, 0, 0}));
  ASSERT_EQ(w.positions.size(), 4u);
  EXPECT_EQ(w.positions[0], Vec3(0, 0, 0));
  EXPECT_EQ(w.positions[1], Vec3(1, 0, 0));
  EXPECT_EQ(w.positions[2], Vec3(0, 1, 0));
  EXPECT_EQ(w.positions[3], Vec3(1, 1, 0));
  EXPECT_EQ(w.triangles, (std::vector<Tri>{{0, 1, 2}, {3, 2, 1}}));
}

TEST(Weld, TreatsNegativeZeroAsZero) {
  const IndexedSoup w = weld(soup_of({0.0f, 0.0f, 0.0f, 1, 0, 0, 0, 1, 0,  //
                                      -0.0f, 0.0f, -0.0f, 0, 1, 0, 0, 0, 1}));
  ASSERT_EQ(w.positions.size(), 4u);
  EXPECT_EQ(w.triangles[1][0], 0u);
  // The shared vertex is +0.0 whichever sign came first.
  const IndexedSoup first_negative = weld(soup_of({-0.0f, -0.0f, -0.0f, 1, 0, 0, 0, 1, 0}));
  EXPECT_FALSE(std::signbit(first_negative.positions[0].x));
  EXPECT_FALSE(std::signbit(first_negative.positions[0].z));
}

TEST(Weld, ExactWeldingKeepsNeighbouringFloatsApart) {
  const float a = 0.1f;
  const float b = std::nextafter(a, 1.0f);
  const IndexedSoup w = weld(soup_of({a, 0, 0, 1, 0, 0, 0, 1, 0,  //
                                      b, 0, 0, 1, 0, 0, 0, 1, 0}));
  EXPECT_EQ(w.positions.size(), 4u);
}

TEST(Weld, ConvertsFloatsExactly) {
  const IndexedSoup w = weld(soup_of({0.1f, -3.3f, 1e-7f, 1, 0, 0, 0, 1, 0}));
  EXPECT_EQ(w.positions[0].x, static_cast<double>(0.1f));
  EXPECT_EQ(w.positions[0].y, static_cast<double>(-3.3f));
  EXPECT_EQ(w.positions[0].z, static_cast<double>(1e-7f));
}

TEST(Weld, KeepsDegenerateTriangles) {
  const IndexedSoup w = weld(soup_of({0, 0, 0, 0, 0, 0, 1, 0, 0}));
  ASSERT_EQ(w.triangles.size(), 1u);
  EXPECT_EQ(w.triangles[0], (Tri{0, 0, 1}));
}

TEST(Weld, GrowsForSoupsWithoutSharedCorners) {
  // 20000 disjoint triangles: three times more vertices than the table's first guess.
  std::vector<float> coords;
  for (int i = 0; i < 20000; ++i) {
    const std::array<float, 9> t = unit_triangle(static_cast<float>(2 * i));
    coords.insert(coords.end(), t.begin(), t.end());
  }
  const IndexedSoup w = weld(soup_of(coords));
  ASSERT_EQ(w.positions.size(), 60000u);
  EXPECT_EQ(w.triangles[19999], (Tri{59997, 59998, 59999}));
  EXPECT_EQ(w.positions[59997], Vec3(39998, 0, 0));
}

TEST(Weld, WeldsGearwheelToClosedMesh) {
  const IndexedSoup w = weld(read_stl_file(data_file("gearwheel.stl")));
  EXPECT_EQ(w.triangles.size(), 2444u);
  EXPECT_EQ(w.positions.size(), 1222u);  // genus 1: V = F / 2
}

TEST(Weld, ToleranceMergesNearPointsButNotFarOnes) {
  // Corner 0 of the second triangle is 4e-4 from (0,0,0), across the grid cell boundary at 0;
  // the third triangle's corner is 2e-3 away.
  const IndexedSoup w = weld(soup_of({0,      0,     0, 1, 0, 0, 0,       1, 0,  //
                                      -4e-4f, 1e-4f, 0, 0, 0, 1, 1.0002f, 0, 0,  //
                                      2e-3f,  0,     0, 0, 0, 1, 0,       1, 0}),
                             1e-3);
  EXPECT_EQ(w.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 3, 1}, {4, 3, 2}}));
  ASSERT_EQ(w.positions.size(), 5u);
  // A merged corner takes the first position exactly; new vertices keep their own.
  EXPECT_EQ(w.positions[0], Vec3(0, 0, 0));
  EXPECT_EQ(w.positions[4].x, static_cast<double>(2e-3f));
}

TEST(Weld, ToleranceJoinsTheNearestVertex) {
  // (0.9,0,0) is within 1 of both (0,0,0) and (1.5,0,0); it joins the nearer one.
  const IndexedSoup w = weld(soup_of({0, 0, 0, 1.5f, 0, 0, 0, 5, 0,  //
                                      0.9f, 0, 0, 0, 5, 0, 0, 0, 5}),
                             1.0);
  EXPECT_EQ(w.triangles[1], (Tri{1, 2, 3}));
}

//! The documented rule, by brute force: each corner in order joins the nearest earlier
//! vertex within tolerance (ties to the lower index), else becomes a new vertex.
IndexedSoup brute_force_weld(const TriangleSoup& soup, double tolerance) {
  IndexedSoup out;
  out.triangles.resize(soup.triangle_count());
  for (std::size_t i = 0; i < soup.coords.size() / 3; ++i) {
    const Vec3 p(soup.coords[3 * i] + 0.0, soup.coords[3 * i + 1] + 0.0,
                 soup.coords[3 * i + 2] + 0.0);
    std::uint32_t best = std::numeric_limits<std::uint32_t>::max();
    double best_d = std::numeric_limits<double>::infinity();
    for (std::uint32_t v = 0; v < out.positions.size(); ++v) {
      const Vec3 d = out.positions[v] - p;
      const double d2 = dot(d, d);
      if (d2 <= tolerance * tolerance && d2 < best_d) {
        best = v;
        best_d = d2;
      }
    }
    if (best == std::numeric_limits<std::uint32_t>::max()) {
      best = static_cast<std::uint32_t>(out.positions.size());
      out.positions.push_back(p);
    }
    out.triangles[i / 3][i % 3] = best;
  }
  return out;
}

TEST(Weld, ToleranceMatchesBruteForce) {
  // Clusters of jittered points around a few centres, at several scales, so that merges,
  // near misses and cell boundaries all occur.
  std::mt19937 rng(7);
  for (const double scale : {1e-3, 1.0, 1e4}) {
    SCOPED_TRACE(scale);
    const double tolerance = 1e-3 * scale;
    std::uniform_real_distribution<double> centre(-5 * scale, 5 * scale);
    std::uniform_real_distribution<double> jitter(-1.5 * tolerance, 1.5 * tolerance);
    std::vector<Vec3> centres(40);
    for (Vec3& c : centres) c = Vec3(centre(rng), centre(rng), centre(rng));
    TriangleSoup soup;
    for (int i = 0; i < 3 * 600; ++i) {
      const Vec3& c = centres[rng() % centres.size()];
      for (const double x : {c.x, c.y, c.z})
        soup.coords.push_back(static_cast<float>(x + jitter(rng)));
    }
    const IndexedSoup grid = weld(soup, tolerance);
    const IndexedSoup brute = brute_force_weld(soup, tolerance);
    EXPECT_EQ(grid.triangles, brute.triangles);
    EXPECT_EQ(grid.positions, brute.positions);
    EXPECT_GT(grid.positions.size(), centres.size());  // some near misses...
    EXPECT_LT(grid.positions.size(), 1000u);           // ...and many merges
  }
}

TEST(Weld, ToleranceIsDeterministic) {
  const TriangleSoup soup = read_stl_file(data_file("gearwheel.stl"));
  const IndexedSoup a = weld(soup, 0.05);
  const IndexedSoup b = weld(soup, 0.05);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_LE(a.positions.size(), 1222u);
  // A tolerance far below float spacing is exact welding.
  const IndexedSoup tiny = weld(soup, 1e-30);
  EXPECT_EQ(tiny.positions, weld(soup).positions);
  EXPECT_EQ(tiny.triangles, weld(soup).triangles);
}

TEST(Weld, RejectsBadTolerance) {
  const TriangleSoup soup = soup_of({0, 0, 0, 1, 0, 0, 0, 1, 0});
  for (const double bad : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    try {
      weld(soup, bad);
      ADD_FAILURE() << "tolerance " << bad << " accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::InvalidParameter);
      EXPECT_EQ(e.field(), "tolerance");
    }
  }
}

}  // namespace
}  // namespace stlrefine::test
