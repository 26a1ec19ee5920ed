// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "tests/support/convex_hull.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace stlrefine::test {
namespace {

//! Grid coordinates are in [0, 2^40]: differences fit in 41 bits, the 2x2 minors in 83, each
//! of the determinant's three products in 124 bits and their sum in 126 (no overflow of a
//! 128-bit integer).
constexpr double kGridSteps = 0x1.0p40;
__extension__ typedef __int128 Int128;

struct IPoint {
  std::int64_t x, y, z;
  friend bool operator==(const IPoint&, const IPoint&) = default;
};

//! Sign of det[b - a, c - a, d - a]: > 0 when d lies on the side of plane (a, b, c) that
//! its normal (b - a) x (c - a) points to. Exact.
int orient(const IPoint& a, const IPoint& b, const IPoint& c, const IPoint& d) {
  const Int128 bx = b.x - a.x, by = b.y - a.y, bz = b.z - a.z;
  const Int128 cx = c.x - a.x, cy = c.y - a.y, cz = c.z - a.z;
  const Int128 dx = d.x - a.x, dy = d.y - a.y, dz = d.z - a.z;
  const Int128 det = bx * (cy * dz - cz * dy) - by * (cx * dz - cz * dx) + bz * (cx * dy - cy * dx);
  return (det > 0) - (det < 0);
}

bool collinear(const IPoint& a, const IPoint& b, const IPoint& c) {
  const Int128 bx = b.x - a.x, by = b.y - a.y, bz = b.z - a.z;
  const Int128 cx = c.x - a.x, cy = c.y - a.y, cz = c.z - a.z;
  return by * cz - bz * cy == 0 && bz * cx - bx * cz == 0 && bx * cy - by * cx == 0;
}

std::uint64_t edge_key(std::uint32_t from, std::uint32_t to) {
  return (std::uint64_t(from) << 32) | to;
}

[[noreturn]] void fail(const std::string& what) {
  throw std::runtime_error("convex_hull: " + what);
}

}  // namespace

std::vector<std::array<std::uint32_t, 3>> convex_hull(std::span<const Vec3> points) {
  using Tri = std::array<std::uint32_t, 3>;
  const std::size_t n = points.size();
  if (n < 4) fail("fewer than 4 points");

  // --- snap to the grid of the bounding box (decisions only)
  Vec3 lo = points[0], hi = points[0];
  for (const Vec3& p : points) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
  if (!(extent > 0)) fail("all points coincide");
  const double scale = kGridSteps / extent;
  std::vector<IPoint> q(n);
  for (std::size_t i = 0; i < n; ++i)
    q[i] = {std::llround((points[i].x - lo.x) * scale), std::llround((points[i].y - lo.y) * scale),
            std::llround((points[i].z - lo.z) * scale)};

  // --- a first tetrahedron: 0, the first point off it, the first off their line, the first
  // off their plane. Those found later are inserted like the others.
  const auto at = [](std::size_t i) { return static_cast<std::uint32_t>(i); };
  std::size_t i1 = 1;
  while (i1 < n && q[i1] == q[0]) ++i1;
  std::size_t i2 = i1 + 1;
  while (i2 < n && collinear(q[0], q[i1], q[i2])) ++i2;
  std::size_t i3 = i2 + 1;
  while (i3 < n && orient(q[0], q[i1], q[i2], q[i3]) == 0) ++i3;
  if (i3 >= n) fail("the points are coplanar");

  std::vector<Tri> faces;
  std::vector<bool> alive;
  std::unordered_map<std::uint64_t, std::uint32_t> face_of_edge;  // half-edge -> its face
  auto add_face = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const auto f = static_cast<std::uint32_t>(faces.size());
    faces.push_back({a, b, c});
    alive.push_back(true);
    face_of_edge[edge_key(a, b)] = f;
    face_of_edge[edge_key(b, c)] = f;
    face_of_edge[edge_key(c, a)] = f;
  };
  {
    std::uint32_t a = 0, b = at(i1), c = at(i2);
    const std::uint32_t d = at(i3);
    if (orient(q[a], q[b], q[c], q[d]) > 0) std::swap(b, c);  // d must lie below (a, b, c)
    add_face(a, b, c);
    add_face(a, d, b);
    add_face(b, d, c);
    add_face(c, d, a);
  }

  // --- insert the rest: remove the faces the point sees, cone the horizon to it
  std::vector<std::uint32_t> visible;
  std::vector<std::array<std::uint32_t, 2>> horizon;
  std::vector<bool> seen(faces.size());
  for (std::size_t i = 1; i < n; ++i) {
    if (i == i1 || i == i2 || i == i3) continue;
    const std::uint32_t p = at(i);
    visible.clear();
    seen.assign(faces.size(), false);
    for (std::uint32_t f = 0; f < faces.size(); ++f) {
      if (!alive[f]) continue;
      const Tri& t = faces[f];
      const int o = orient(q[t[0]], q[t[1]], q[t[2]], q[p]);
      if (o == 0) fail("point " + std::to_string(i) + " lies in the plane of a hull face");
      if (o > 0) {
        visible.push_back(f);
        seen[f] = true;
      }
    }
    if (visible.empty()) fail("point " + std::to_string(i) + " is not in convex position");
    horizon.clear();
    for (const std::uint32_t f : visible)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = faces[f][k], b = faces[f][(k + 1) % 3];
        if (!seen[face_of_edge.at(edge_key(b, a))]) horizon.push_back({a, b});
      }
    for (const std::uint32_t f : visible) {
      alive[f] = false;
      for (int k = 0; k < 3; ++k) face_of_edge.erase(edge_key(faces[f][k], faces[f][(k + 1) % 3]));
    }
    for (const auto& [a, b] : horizon) add_face(a, b, p);
  }

  std::vector<Tri> out;
  std::vector<bool> used(n, false);
  for (std::size_t f = 0; f < faces.size(); ++f) {
    if (!alive[f]) continue;
    out.push_back(faces[f]);
    for (const std::uint32_t v : faces[f]) used[v] = true;
  }
  for (std::size_t i = 0; i < n; ++i)
    if (!used[i]) fail("point " + std::to_string(i) + " is not a hull vertex");
  return out;
}

}  // namespace stlrefine::test
