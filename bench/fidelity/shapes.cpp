// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "bench/fidelity/shapes.h"

#include <cmath>
#include <cstdint>
#include <numbers>

namespace stlrefine::fidelity {
namespace {

constexpr double kPi = std::numbers::pi;
using Tri = std::array<std::uint32_t, 3>;

//! Adds a ring of n vertices at radius r and height z; returns the first index.
std::uint32_t add_ring(IndexedSoup& soup, int n, double r, double z) {
  const auto first = static_cast<std::uint32_t>(soup.positions.size());
  for (int i = 0; i < n; ++i) {
    const double a = 2 * kPi * i / n;
    soup.positions.push_back({r * std::cos(a), r * std::sin(a), z});
  }
  return first;
}

//! Quads between two rings (lower ring `lo`, upper ring `hi`, both n vertices, the lower
//! one seen below the upper one from outside), split by the "union jack" (4-8) rule: cell
//! (i, j) takes the diagonal through its corner (i, j) when i + j is even, otherwise the
//! other one. Ring vertices with i + j even get all four diagonals of their cells
//! (valence 8 inside a strip), the others none (valence 4).
void union_jack_strip(IndexedSoup& soup, std::uint32_t lo, std::uint32_t hi, int n, int j) {
  for (int i = 0; i < n; ++i) {
    const std::uint32_t a = lo + i, b = lo + (i + 1) % n, c = hi + (i + 1) % n, d = hi + i;
    if ((i + j) % 2 == 0) {
      soup.triangles.push_back(Tri{a, b, c});
      soup.triangles.push_back(Tri{a, c, d});
    } else {
      soup.triangles.push_back(Tri{a, b, d});
      soup.triangles.push_back(Tri{b, c, d});
    }
  }
}

//! Rings at the given (radius, height) pairs, bottom to top, joined by union-jack strips.
std::vector<std::uint32_t> ring_stack(IndexedSoup& soup, int n, const std::vector<Vec2>& rings) {
  std::vector<std::uint32_t> first;
  for (const Vec2& rz : rings) first.push_back(add_ring(soup, n, rz.r, rz.z));
  for (std::size_t j = 0; j + 1 < first.size(); ++j)
    union_jack_strip(soup, first[j], first[j + 1], n, static_cast<int>(j));
  return first;
}

ProfilePiece segment(Vec2 a, Vec2 b, bool flat_cap = false) {
  ProfilePiece s;
  s.kind = ProfilePiece::Kind::Segment;
  s.a = a;
  s.b = b;
  s.flat_cap = flat_cap;
  return s;
}

ProfilePiece arc(Vec2 centre, double radius, double a0, double a1) {
  ProfilePiece s;
  s.kind = ProfilePiece::Kind::Arc;
  s.centre = centre;
  s.radius = radius;
  s.a0 = a0;
  s.a1 = a1;
  return s;
}

}  // namespace

Shape irregular_cylinder() {
  const int n = 16;
  const double r = 10, h = 20;
  IndexedSoup soup;
  const auto rings = ring_stack(soup, n, {{r, 0}, {r, 5}, {r, h}});
  const std::uint32_t bottom = rings[0], top = rings[2];
  // Bottom cap: a fan from rim vertex 0 (seen from below: ccw), as CAD exporters do.
  for (int k = 1; k + 1 < n; ++k)
    soup.triangles.push_back(Tri{bottom, bottom + k + 1, bottom + static_cast<std::uint32_t>(k)});
  // Top cap: a fan around a centre vertex.
  const auto centre = static_cast<std::uint32_t>(soup.positions.size());
  soup.positions.push_back({0, 0, h});
  for (int k = 0; k < n; ++k)
    soup.triangles.push_back(Tri{centre, top + k, top + static_cast<std::uint32_t>((k + 1) % n)});
  return {"cylinder",
          "capped cylinder r = 10, h = 20, 16 sides, ring at z = 5, union-jack side "
          "(middle-ring valence 4/8, upper row 15 x 3.9 mm triangles), bottom cap a fan from "
          "one rim vertex, top cap a centre fan",
          std::move(soup),
          TrueSurface({segment({0, 0}, {r, 0}, true), segment({r, 0}, {r, h}),
                       segment({r, h}, {0, h}, true)}),
          12.345,
          r};
}

Shape uv_sphere() {
  const int n = 16, bands = 8;
  const double r = 10;
  IndexedSoup soup;
  std::vector<Vec2> rings;
  for (int j = 1; j < bands; ++j) {
    const double polar = kPi * (bands - j) / bands;  // from near the south pole upwards
    rings.push_back({r * std::sin(polar), r * std::cos(polar)});
  }
  const auto first = ring_stack(soup, n, rings);
  const auto south = static_cast<std::uint32_t>(soup.positions.size());
  soup.positions.push_back({0, 0, -r});
  soup.positions.push_back({0, 0, r});
  const std::uint32_t north = south + 1, lo = first.front(), hi = first.back();
  for (int k = 0; k < n; ++k) {
    const auto k1 = static_cast<std::uint32_t>((k + 1) % n), k0 = static_cast<std::uint32_t>(k);
    soup.triangles.push_back(Tri{south, lo + k1, lo + k0});
    soup.triangles.push_back(Tri{north, hi + k0, hi + k1});
  }
  return {"sphere",
          "UV sphere r = 10, 16 x 8, union-jack diagonals (valence 4/8), poles of valence 16",
          std::move(soup),
          TrueSurface({arc({0, 0}, r, -kPi / 2, kPi / 2)}),
          std::nullopt,
          r};
}

Shape irregular_torus() {
  const int n_major = 24, n_minor = 12;
  const double big = 10, small = 4;
  IndexedSoup soup;
  // Rings around the z axis, one per minor angle; the strip between the last ring and the
  // first closes the tube. n_minor is even, so the union-jack parity also closes.
  std::vector<std::uint32_t> first;
  for (int j = 0; j < n_minor; ++j) {
    const double a = 2 * kPi * j / n_minor;
    first.push_back(add_ring(soup, n_major, big + small * std::cos(a), small * std::sin(a)));
  }
  // Minor angle grows from the outer equator upwards, so "lower" ring j, "upper" j + 1 is
  // the outward-facing order on the outer half; the same order is outward on the inner half
  // as the minor circle is traversed ccw.
  for (int j = 0; j < n_minor; ++j)
    union_jack_strip(soup, first[j], first[(j + 1) % n_minor], n_major, j);
  return {"torus",         "torus R = 10, r = 4, 24 x 12, union-jack diagonals (valence 4/8)",
          std::move(soup), TrueSurface({arc({big, 0}, small, -kPi, kPi)}),
          std::nullopt,    big};
}

Shape open_tube() {
  const int n = 16;
  const double r = 10, h = 20;
  IndexedSoup soup;
  ring_stack(soup, n, {{r, 0}, {r, 5}, {r, h}});
  return {"tube",
          "open tube r = 10, h = 20, 16 sides, ring at z = 5, union-jack (valence 4/8), both "
          "rims boundaries",
          std::move(soup),
          TrueSurface({segment({r, 0}, {r, h})}),
          12.345,
          r};
}

std::vector<Shape> all_shapes() {
  std::vector<Shape> shapes;
  shapes.push_back(irregular_cylinder());
  shapes.push_back(uv_sphere());
  shapes.push_back(irregular_torus());
  shapes.push_back(open_tube());
  return shapes;
}

}  // namespace stlrefine::fidelity
