// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#pragma once

// Shapes and checks shared by the slicer tests.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "slicer/slice.h"
#include "tests/support/shapes.h"

namespace stlrefine::test {

//! The same soup with every triangle's winding reversed (normals pointing inwards): merged
//! inside a larger shell it is a cavity.
inline IndexedSoup inverted(IndexedSoup soup) {
  for (auto& t : soup.triangles) std::swap(t[1], t[2]);
  return soup;
}

//! Flips triangles whose normal points towards `centre` (convex shapes only).
inline void orient_away_from(IndexedSoup& soup, Vec3 centre) {
  for (auto& t : soup.triangles) {
    const Vec3 &a = soup.positions[t[0]], &b = soup.positions[t[1]], &c = soup.positions[t[2]];
    if (dot(triangle_normal(a, b, c), (a + b + c) * (1.0 / 3.0) - centre) < 0)
      std::swap(t[1], t[2]);
  }
}

//! Prism along x (0..length) whose cross-section is the diamond |y| + |z| <= 1: its two side
//! edges (y = +-1, z = 0) are horizontal, its top ridge is the edge (y, z) = (0, 1).
inline IndexedSoup diamond_prism_soup(double length) {
  IndexedSoup soup;
  const Vec3 section[4] = {{0, 1, 0}, {0, 0, 1}, {0, -1, 0}, {0, 0, -1}};
  for (double x : {0.0, length})
    for (const Vec3& s : section) soup.positions.push_back({x, s.y, s.z});
  for (std::uint32_t i = 0; i < 4; ++i) {
    const std::uint32_t j = (i + 1) % 4;
    soup.triangles.push_back({i, j, j + 4});
    soup.triangles.push_back({i, j + 4, i + 4});
  }
  soup.triangles.push_back({0, 1, 2});  // end caps
  soup.triangles.push_back({0, 2, 3});
  soup.triangles.push_back({4, 5, 6});
  soup.triangles.push_back({4, 6, 7});
  orient_away_from(soup, {length / 2, 0, 0});
  return soup;
}

//! cube_soup(size) without the two triangles of its x = 0 side: an open box.
inline IndexedSoup open_box_soup(double size) {
  IndexedSoup soup = cube_soup(size);
  std::erase_if(soup.triangles, [&](const auto& t) {
    return soup.positions[t[0]].x == 0 && soup.positions[t[1]].x == 0 &&
           soup.positions[t[2]].x == 0;
  });
  return soup;
}

inline slicer::SliceParams uniform(double h) {
  slicer::SliceParams p;
  p.layer_height = h;
  return p;
}

inline slicer::SliceParams at(std::vector<double> heights) {
  slicer::SliceParams p;
  p.heights = std::move(heights);
  return p;
}

//! No two consecutive points of a closed loop are equal (wrapping around).
inline ::testing::AssertionResult no_zero_length_edges(const slicer::Loop& loop) {
  for (std::size_t i = 0; i < loop.points.size(); ++i) {
    const auto& a = loop.points[i];
    const auto& b = loop.points[(i + 1) % loop.points.size()];
    if (a == b)
      return ::testing::AssertionFailure()
             << "points " << i << " and next are both (" << a.x << ", " << a.y << ")";
  }
  return ::testing::AssertionSuccess();
}

//! Runs fn, which must throw stlrefine::Error; returns "code:field".
template <class Fn>
std::string error_of(Fn&& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return std::string(to_string(e.code())) + ":" + e.field();
  }
  return "no error";
}

}  // namespace stlrefine::test
