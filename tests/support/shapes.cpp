// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "tests/support/shapes.h"

#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <numbers>
#include <string>
#include <utility>

#include "core/mesh/build_mesh.h"

namespace stlrefine::test {

namespace {

using Tri = std::array<std::uint32_t, 3>;

// Winds every triangle so that its normal points away from `centre` (convex shapes only).
void orient_outward(IndexedSoup& soup, Vec3 centre) {
  for (Tri& t : soup.triangles) {
    const Vec3& a = soup.positions[t[0]];
    const Vec3& b = soup.positions[t[1]];
    const Vec3& c = soup.positions[t[2]];
    const Vec3 centroid = (a + b + c) * (1.0 / 3.0);
    if (dot(triangle_normal(a, b, c), centroid - centre) < 0) std::swap(t[1], t[2]);
  }
}

std::uint32_t idx(std::size_t i) {
  return static_cast<std::uint32_t>(i);
}

}  // namespace

IndexedSoup tetrahedron_soup() {
  const double s = 1.0 / std::sqrt(3.0);
  IndexedSoup soup;
  soup.positions = {{s, s, s}, {s, -s, -s}, {-s, s, -s}, {-s, -s, s}};
  soup.triangles = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
  orient_outward(soup, {0, 0, 0});
  return soup;
}

IndexedSoup octahedron_soup() {
  IndexedSoup soup;
  // 0:+x 1:-x 2:+y 3:-y 4:+z 5:-z
  soup.positions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (std::uint32_t x : {0u, 1u})
    for (std::uint32_t y : {2u, 3u})
      for (std::uint32_t z : {4u, 5u}) soup.triangles.push_back({x, y, z});
  orient_outward(soup, {0, 0, 0});
  return soup;
}

IndexedSoup icosahedron_soup() {
  const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
  const double n = std::sqrt(1.0 + phi * phi);
  const double a = 1.0 / n, b = phi / n;
  IndexedSoup soup;
  for (double s1 : {-1.0, 1.0}) {
    for (double s2 : {-1.0, 1.0}) {
      soup.positions.push_back({0, s1 * a, s2 * b});
      soup.positions.push_back({s1 * a, s2 * b, 0});
      soup.positions.push_back({s2 * b, 0, s1 * a});
    }
  }
  // Neighbours are exactly at the edge length 2a; faces are mutually adjacent triples.
  const double edge = 2.0 * a;
  auto adjacent = [&](std::size_t i, std::size_t j) {
    return std::abs(distance(soup.positions[i], soup.positions[j]) - edge) < 1e-9;
  };
  for (std::size_t i = 0; i < 12; ++i)
    for (std::size_t j = i + 1; j < 12; ++j)
      for (std::size_t k = j + 1; k < 12; ++k)
        if (adjacent(i, j) && adjacent(j, k) && adjacent(i, k))
          soup.triangles.push_back({idx(i), idx(j), idx(k)});
  orient_outward(soup, {0, 0, 0});
  return soup;
}

IndexedSoup cube_soup(double size) {
  IndexedSoup soup;
  // Vertex index = x + 2y + 4z with x, y, z in {0, 1}.
  for (int i = 0; i < 8; ++i)
    soup.positions.push_back({(i & 1) ? size : 0.0, (i & 2) ? size : 0.0, (i & 4) ? size : 0.0});
  const std::array<std::array<std::uint32_t, 4>, 6> quads = {{
      {0, 1, 3, 2},  // z = 0
      {4, 5, 7, 6},  // z = 1
      {0, 1, 5, 4},  // y = 0
      {2, 3, 7, 6},  // y = 1
      {0, 2, 6, 4},  // x = 0
      {1, 3, 7, 5},  // x = 1
  }};
  for (const auto& q : quads) {
    soup.triangles.push_back({q[0], q[1], q[2]});
    soup.triangles.push_back({q[0], q[2], q[3]});
  }
  orient_outward(soup, {size / 2, size / 2, size / 2});
  return soup;
}

IndexedSoup bipyramid_soup(int n, double height) {
  IndexedSoup soup;
  for (int i = 0; i < n; ++i) {
    const double t = 2.0 * std::numbers::pi * i / n;
    soup.positions.push_back({std::cos(t), std::sin(t), 0.0});
  }
  soup.positions.push_back({0, 0, height});
  soup.positions.push_back({0, 0, -height});
  const auto top = idx(n), bottom = idx(n + 1);
  for (int i = 0; i < n; ++i) {
    const auto a = idx(i), b = idx((i + 1) % n);
    soup.triangles.push_back({a, b, top});
    soup.triangles.push_back({b, a, bottom});
  }
  orient_outward(soup, {0, 0, 0});
  return soup;
}

IndexedSoup grid_soup(int nx, int ny, Vec3 origin, Vec3 du, Vec3 dv) {
  IndexedSoup soup;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) soup.positions.push_back(origin + du * i + dv * j);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const auto v00 = grid_index(nx, i, j), v10 = grid_index(nx, i + 1, j);
      const auto v11 = grid_index(nx, i + 1, j + 1), v01 = grid_index(nx, i, j + 1);
      soup.triangles.push_back({v00, v10, v11});
      soup.triangles.push_back({v00, v11, v01});
    }
  }
  return soup;
}

IndexedSoup height_field_soup(int nx, int ny, double x0, double y0, double h,
                              const std::function<double(double, double)>& f) {
  IndexedSoup soup = grid_soup(nx, ny, {x0, y0, 0}, {h, 0, 0}, {0, h, 0});
  for (Vec3& p : soup.positions) p.z = f(p.x, p.y);
  return soup;
}

IndexedSoup fan_soup(int n, double apex_height) {
  IndexedSoup soup;
  soup.positions.push_back({0, 0, apex_height});
  for (int i = 0; i < n; ++i) {
    const double t = 2.0 * std::numbers::pi * i / n;
    soup.positions.push_back({std::cos(t), std::sin(t), 0.0});
  }
  for (int i = 0; i < n; ++i) soup.triangles.push_back({0, idx(1 + i), idx(1 + (i + 1) % n)});
  return soup;
}

IndexedSoup cylinder_soup(int n, double radius, double height) {
  IndexedSoup soup;
  for (double z : {0.0, height}) {
    for (int i = 0; i < n; ++i) {
      const double t = 2.0 * std::numbers::pi * i / n;
      soup.positions.push_back({radius * std::cos(t), radius * std::sin(t), z});
    }
  }
  soup.positions.push_back({0, 0, 0});
  soup.positions.push_back({0, 0, height});
  const auto cb = idx(2 * n), ct = idx(2 * n + 1);
  for (int i = 0; i < n; ++i) {
    const auto b0 = idx(i), b1 = idx((i + 1) % n);
    const auto t0 = idx(n + i), t1 = idx(n + (i + 1) % n);
    soup.triangles.push_back({b0, b1, t1});
    soup.triangles.push_back({b0, t1, t0});
    soup.triangles.push_back({cb, b1, b0});
    soup.triangles.push_back({ct, t0, t1});
  }
  return soup;
}

IndexedSoup icosphere_soup(int subdivisions, double radius) {
  IndexedSoup soup = icosahedron_soup();
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      const std::pair<std::uint32_t, std::uint32_t> key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const auto id = idx(soup.positions.size());
      soup.positions.push_back(normalized(soup.positions[a] + soup.positions[b]));
      mid.emplace(key, id);
      return id;
    };
    std::vector<Tri> out;
    for (const Tri& t : soup.triangles) {
      const auto m0 = midpoint(t[0], t[1]), m1 = midpoint(t[1], t[2]), m2 = midpoint(t[2], t[0]);
      out.push_back({t[0], m0, m2});
      out.push_back({t[1], m1, m0});
      out.push_back({t[2], m2, m1});
      out.push_back({m0, m1, m2});
    }
    soup.triangles = std::move(out);
  }
  for (Vec3& p : soup.positions) p = normalized(p) * radius;
  return soup;
}

IndexedSoup torus_soup(int n_major, int n_minor, double R, double r) {
  IndexedSoup soup;
  for (int i = 0; i < n_major; ++i) {
    const double u = 2.0 * std::numbers::pi * i / n_major;
    for (int j = 0; j < n_minor; ++j) {
      const double v = 2.0 * std::numbers::pi * j / n_minor;
      const double w = R + r * std::cos(v);
      soup.positions.push_back({w * std::cos(u), w * std::sin(u), r * std::sin(v)});
    }
  }
  auto at = [&](int i, int j) { return idx((i % n_major) * n_minor + (j % n_minor)); };
  for (int i = 0; i < n_major; ++i) {
    for (int j = 0; j < n_minor; ++j) {
      const auto a = at(i, j), b = at(i + 1, j), c = at(i + 1, j + 1), d = at(i, j + 1);
      soup.triangles.push_back({a, b, c});
      soup.triangles.push_back({a, c, d});
    }
  }
  return soup;
}

IndexedSoup moebius_soup(int n) {
  IndexedSoup soup;
  const double w = 0.3;
  for (int i = 0; i < n; ++i) {
    const double u = 2.0 * std::numbers::pi * i / n;
    for (double s : {w, -w}) {
      const double rr = 1.0 + s * std::cos(u / 2);
      soup.positions.push_back({rr * std::cos(u), rr * std::sin(u), s * std::sin(u / 2)});
    }
  }
  // top_i = 2i, bottom_i = 2i + 1; after a full turn top and bottom swap (half twist).
  auto top = [&](int i) { return i == n ? idx(1) : idx(2 * i); };
  auto bottom = [&](int i) { return i == n ? idx(0) : idx(2 * i + 1); };
  for (int i = 0; i < n; ++i) {
    soup.triangles.push_back({bottom(i), bottom(i + 1), top(i + 1)});
    soup.triangles.push_back({bottom(i), top(i + 1), top(i)});
  }
  return soup;
}

IndexedSoup merged(const IndexedSoup& a, const IndexedSoup& b) {
  IndexedSoup out = a;
  std::vector<std::uint32_t> remap;
  for (const Vec3& p : b.positions) {
    std::uint32_t id = idx(out.positions.size());
    for (std::size_t i = 0; i < a.positions.size(); ++i)
      if (a.positions[i] == p) id = idx(i);
    if (id == out.positions.size()) out.positions.push_back(p);
    remap.push_back(id);
  }
  for (const Tri& t : b.triangles) out.triangles.push_back({remap[t[0]], remap[t[1]], remap[t[2]]});
  return out;
}

IndexedSoup translated(IndexedSoup soup, Vec3 t) {
  for (Vec3& p : soup.positions) p += t;
  return soup;
}

Mesh to_mesh(const IndexedSoup& soup) {
  return build_mesh(soup).mesh;
}

IndexedSoup read_binary_stl_soup(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char header[80];
  std::uint32_t count = 0;
  in.read(header, sizeof header);
  in.read(reinterpret_cast<char*>(&count), sizeof count);
  IndexedSoup soup;
  std::map<std::array<float, 3>, std::uint32_t> index;
  for (std::uint32_t f = 0; f < count && in; ++f) {
    std::array<float, 12> v{};  // normal, three corners
    std::uint16_t attribute = 0;
    in.read(reinterpret_cast<char*>(v.data()), sizeof v);
    in.read(reinterpret_cast<char*>(&attribute), sizeof attribute);
    if (!in) break;
    std::array<std::uint32_t, 3> tri{};
    for (int k = 0; k < 3; ++k) {
      const std::array<float, 3> p{v[3 + 3 * k], v[4 + 3 * k], v[5 + 3 * k]};
      const auto [it, added] = index.emplace(p, static_cast<std::uint32_t>(index.size()));
      if (added) soup.positions.push_back({p[0], p[1], p[2]});
      tri[k] = it->second;
    }
    soup.triangles.push_back(tri);
  }
  return soup;
}

}  // namespace stlrefine::test
